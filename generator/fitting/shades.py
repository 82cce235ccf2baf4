"""Light and materials from the image: the floor, background and box greys, the shades of the
faces the image shows, and a light that reproduces them.

The floor's shade and its albedo enter a textured floor's render only as their product, so the
twin states the floor's light in its texture (floor factor 1: the box tops, which share the
floor's normal, show their albedo). A box face seen by the camera in enough pixels
(:data:`MIN_FACE_PX`, its outline eroded so that no edge pixel counts) gives its shade; faces
are named by the compass direction their normal points to. The light is the ambient term and
one directional light of :func:`arenabench.generator.fitting.scene_fit.fit_lighting` (the weakest
light that
gives the faces seen: a face not seen keeps about the ambient shade); a face direction no box
shows is left open (the fill lights ``lighting.east_fill`` / ``lighting.west_fill`` state a
lighter one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from arenabench.frame import CORNER_ORDER
from arenabench.generator.fitting.scene_fit import BoxObservation, fit_boxes, fit_lighting
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import (
    box_vertices,
    facing_side_faces,
    floor_extent,
    marker_corners_world,
)
from arenabench.generator.model.scene import (
    ArenaSpec,
    CameraSpec,
    LightingSpec,
    MarkerSpec,
    Obstacle,
)
from arenabench.generator.model.shading import shade_factors

#: A box face counts as seen when this many of its pixels lie 2 px or more inside its outline.
MIN_FACE_PX = 30
#: Compass names of the side faces' normals.
COMPASS = ("east", "north", "west", "south")
#: The smallest dark blob (px) taken as a box.
MIN_BOX_PX = 400
#: Dark lines this wide (px) or thinner are taken for printed lines, not boxes, and cut off
#: before the blobs are sized (a box's blob is at least :data:`MIN_BOX_PX` and tens of pixels
#: across).
THIN_LINE_PX = 4
#: Background pixels needed to read the background grey.
MIN_BACKGROUND_PX = 500
#: Levels from the floor's grey past which a pixel outside the arena can be background: a
#: plain floor's margin reaches past the markers' square by an amount the image has not yet
#: told, so pixels of the floor's own grey there are floor (arena_geometry's floor edge needs
#: the two this far apart too).
BACKGROUND_APART = 8


@dataclass(frozen=True)
class FaceShade:
    """A side face of a box as the image shows it.

    Attributes
    ----------
    box : int
        Index of the box.
    direction : str
        Where its normal points (one of :data:`COMPASS`).
    normal : tuple of float
        Its world normal.
    gray : float
        Its median grey.
    pixels : int
        How many of its pixels were read.
    """

    box: int
    direction: str
    normal: tuple[float, float, float]
    gray: float
    pixels: int


@dataclass(frozen=True)
class Shades:
    """The image's greys, and the light and materials that give them.

    Attributes
    ----------
    floor_rgb : tuple of int
        The floor's grey (R, G, B: the mode inside the markers' square, boxes left out).
    background_rgb : tuple of int or None
        The grey around the floor; ``None`` when the image shows too little of it.
    background_px : int
        Pixels the background grey was read from.
    boxes : tuple of BoxObservation
        The boxes fitted (footprint, yaw, height) with their top grey.
    box_rgb : tuple of tuple of int
        Each box's top face (R, G, B), its albedo under floor factor 1.
    faces : tuple of FaceShade
        Every side face seen.
    lighting : LightingSpec
        Ambient and one directional light giving the faces seen.
    face_residual : float
        RMS difference (grey levels) between the faces seen and the light's shades of them.
    box_mask : numpy.ndarray
        (H, W) bool: the boxes' blobs (what the image shows of them).
    """

    floor_rgb: tuple[int, int, int]
    background_rgb: tuple[int, int, int] | None
    background_px: int
    boxes: tuple[BoxObservation, ...]
    box_rgb: tuple[tuple[int, int, int], ...]
    faces: tuple[FaceShade, ...]
    lighting: LightingSpec
    face_residual: float
    box_mask: np.ndarray

    @property
    def directions_seen(self) -> tuple[str, ...]:
        """Compass directions of the side faces seen, in :data:`COMPASS` order."""
        seen = {f.direction for f in self.faces}
        return tuple(d for d in COMPASS if d in seen)

def compass(normal: np.ndarray) -> str:
    """The compass name of a horizontal normal (east = +x, north = +y)."""
    angle = math.degrees(math.atan2(normal[1], normal[0])) % 360.0
    return COMPASS[int(((angle + 45.0) % 360.0) // 90.0)]


def _mode(values: np.ndarray) -> int:
    v = np.clip(np.rint(values), 0, 255).astype(np.int64)
    return int(np.argmax(np.bincount(v.ravel(), minlength=256)))


def floor_level(values: np.ndarray) -> int:
    """The floor's grey among ``values``: the commonest grey within 20 levels of their median
    (a textured floor spreads over several levels, so a uniform box top can outnumber any
    one of them; the boxes cover less than half the floor)."""
    v = np.clip(np.rint(values), 0, 255).astype(np.int64).ravel()
    median = int(np.median(v))
    near = v[np.abs(v - median) <= 20]
    hist = np.bincount(near, minlength=256).astype(np.float64)
    smooth = np.convolve(hist, np.ones(5) / 5.0, mode="same")  # a textured floor's spread
    # a plain floor's one grey ties over five levels: among the tied levels, the commonest (a
    # peaked kernel instead would move a lit concrete floor's level onto its clipped 255s)
    tied = np.flatnonzero(smooth >= smooth.max() * (1.0 - 1e-12))
    return int(tied[np.argmax(hist[tied])])


def _polygon_mask(shape: tuple[int, int], px: np.ndarray) -> np.ndarray:
    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [np.round(px * 16).astype(np.int32)], 1, shift=4)
    return m.astype(bool)


def background_pixels(gray: np.ndarray, camera: CameraSpec, arena: ArenaSpec,
                      floor_gray: float) -> np.ndarray:
    """Pixels of the background: outside the arena's floor square (as far as ``arena`` places
    it), at least :data:`BACKGROUND_APART` levels from the floor's grey, in regions that reach
    the image's border (the background lies beyond the floor's edge; a logo or a line printed
    on a margin the arena does not yet know of does not reach the border).

    Without a texture the margin is not known when the greys are read, so the floor past the
    markers' square is "outside" too, and would outvote the background.
    """
    outside = ~floor_square_mask(camera, gray.shape, floor_extent(arena) + 0.02)
    apart = outside & (np.abs(gray - floor_gray) > BACKGROUND_APART)
    n, labels = cv2.connectedComponents(apart.astype(np.uint8), connectivity=8)
    edge = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    keep = np.zeros(n, bool)
    keep[np.unique(edge)] = True
    keep[0] = False
    return keep[labels]


def floor_square_mask(camera: CameraSpec, shape: tuple[int, int], half: float) -> np.ndarray:
    """Pixels of the floor square of half-side ``half`` (m) around the origin."""
    h = cam.floor_homography(cam.intrinsics(camera), cam.world_from_camera(camera))
    sq = np.array([[-half, -half], [half, -half], [half, half], [-half, half]], np.float64)
    return _polygon_mask(shape, cv2.perspectiveTransform(sq.reshape(-1, 1, 2), h).reshape(-1, 2))


def marker_mask(camera: CameraSpec, arena: ArenaSpec, markers: MarkerSpec,
                shape: tuple[int, int], pad_m: float) -> np.ndarray:
    """Pixels of the four marker squares grown by ``pad_m``."""
    K, pose = cam.intrinsics(camera), cam.world_from_camera(camera)
    out = np.zeros(shape, bool)
    for c in CORNER_ORDER:
        quad = marker_corners_world(arena, markers, c, pad_m=pad_m)
        out |= _polygon_mask(shape, cam.project(np.column_stack([quad, np.zeros(4)]), K, pose))
    return out


def side_faces(gray: np.ndarray, index: int, ob: Obstacle, camera: CameraSpec,
               blob: np.ndarray) -> list[FaceShade]:
    """The side faces of box ``ob`` that the camera sees in :data:`MIN_FACE_PX` or more
    pixels 2 px inside their outline (and inside the box's blob)."""
    K, pose = cam.intrinsics(camera), cam.world_from_camera(camera)
    out = []
    for quad, normal in facing_side_faces(ob, pose[:3, 3]):
        m = _polygon_mask(gray.shape, cam.project(quad, K, pose)).astype(np.uint8)
        m = cv2.erode(m, np.ones((5, 5), np.uint8)).astype(bool) & blob
        if m.sum() >= MIN_FACE_PX:
            out.append(FaceShade(index, compass(normal), tuple(round(float(c), 6) for c in normal),
                                 float(np.median(gray[m])), int(m.sum())))
    return out


def read_shades(bgr: np.ndarray, camera: CameraSpec, arena: ArenaSpec,
                markers: MarkerSpec) -> Shades:
    """Read the greys and fit the boxes, the faces and the light.

    Parameters
    ----------
    bgr : numpy.ndarray
        (H, W, 3) uint8 image.
    camera, arena, markers : scene parts
        The fitted camera and the arena's geometry.

    Returns
    -------
    Shades
    """
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)
    shape = gray.shape
    inner = floor_square_mask(camera, shape, arena.side_m / 2 - markers.side_m * 0.5)
    inner &= ~marker_mask(camera, arena, markers, shape, markers.quiet_zone_m + 0.02)
    floor_gray = floor_level(gray[inner])
    boxes = fit_boxes(_box_candidates(gray, camera, arena, markers, floor_gray), camera, arena,
                      markers, floor_gray=floor_gray, min_box_px=MIN_BOX_PX)
    box_mask = np.zeros(shape, bool)
    K, pose = cam.intrinsics(camera), cam.world_from_camera(camera)
    for b in boxes:
        hull = cv2.convexHull(cam.project(box_vertices(b.obstacle), K, pose).astype(np.float32))
        box_mask |= _polygon_mask(shape, hull.reshape(-1, 2))
    grown = cv2.dilate(box_mask.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    floor_px = inner & ~grown
    floor_rgb = tuple(floor_level(bgr[..., 2 - c][floor_px]) for c in range(3))
    outside = background_pixels(gray, camera, arena, floor_gray)
    background_rgb = None
    if outside.sum() >= MIN_BACKGROUND_PX:
        background_rgb = tuple(_mode(bgr[..., 2 - c][outside]) for c in range(3))
    faces: list[FaceShade] = []
    box_rgb = []
    dark = gray < floor_gray - 40  # fit_boxes' blobs: pixels visibly darker than the floor
    for i, b in enumerate(boxes):
        hull = cv2.convexHull(cam.project(box_vertices(b.obstacle), K, pose).astype(np.float32))
        blob = _polygon_mask(shape, hull.reshape(-1, 2)) & dark
        faces += side_faces(gray, i, b.obstacle, camera, blob)
        top = _top_mask(b.obstacle, camera, shape) & blob
        box_rgb.append(tuple(int(np.median(bgr[..., 2 - c][top])) for c in range(3))
                       if top.sum() >= MIN_FACE_PX else (round(b.top_gray),) * 3)
    observed = [replace(b, side_faces=tuple((f.normal, f.gray) for f in faces if f.box == i),
                        top_gray=float(np.mean(box_rgb[i])))
                for i, b in enumerate(boxes)]
    lighting = fit_lighting(observed)
    return Shades(floor_rgb=floor_rgb, background_rgb=background_rgb,
                  background_px=int(outside.sum()), boxes=tuple(observed),
                  box_rgb=tuple(box_rgb), faces=tuple(faces), lighting=lighting,
                  face_residual=_face_residual(faces, observed, lighting), box_mask=box_mask)


#: A dark blob is not a box when its minimum-area rectangle is this many times longer than
#: wide (a printed line), or when it fills less than this share of that rectangle (a ring of
#: border lines, letters).
MAX_BLOB_ASPECT = 12.0
MIN_BLOB_FILL = 0.5


def _box_candidates(gray: np.ndarray, camera: CameraSpec, arena: ArenaSpec,
                    markers: MarkerSpec, floor_gray: float) -> np.ndarray:
    """``gray`` with what cannot be a box painted over in the floor's grey: everything outside
    the markers' square (the background, lanes and logos in the margin) and dark blobs shaped
    like printed lines or letters (:data:`MAX_BLOB_ASPECT`, :data:`MIN_BLOB_FILL`)."""
    out = gray.copy()
    out[~floor_square_mask(camera, gray.shape, arena.side_m / 2.0)] = floor_gray
    dark = ((out < floor_gray - 40)
            & ~marker_mask(camera, arena, markers, gray.shape, markers.quiet_zone_m + 0.02))
    # thin printed lines cut off first: a line that touches a box would make one blob with
    # it, too long for a box, and the box would be painted over with the line
    square = np.ones((THIN_LINE_PX + 1,) * 2, np.uint8)
    thick = cv2.morphologyEx(dark.astype(np.uint8), cv2.MORPH_OPEN, square)
    out[dark & ~cv2.dilate(thick, np.ones((3, 3), np.uint8)).astype(bool)] = floor_gray
    n, labels, stats, _ = cv2.connectedComponentsWithStats(thick, connectivity=8)
    for i in range(1, n):
        if stats[i, cv2.CC_STAT_AREA] < MIN_BOX_PX:
            continue
        pts = np.column_stack(np.nonzero(labels == i)[::-1]).astype(np.float32)
        (_, _), (w, h), _ = cv2.minAreaRect(pts)
        long, short = max(w, h), max(min(w, h), 1.0)
        if long / short > MAX_BLOB_ASPECT or stats[i, cv2.CC_STAT_AREA] < MIN_BLOB_FILL * w * h:
            blob = cv2.dilate((labels == i).astype(np.uint8), np.ones((3, 3), np.uint8))
            out[blob.astype(bool) & dark] = floor_gray
    return out


def _top_mask(ob: Obstacle, camera: CameraSpec, shape: tuple[int, int]) -> np.ndarray:
    K, pose = cam.intrinsics(camera), cam.world_from_camera(camera)
    top = cam.project(box_vertices(ob)[4:], K, pose)
    m = _polygon_mask(shape, top).astype(np.uint8)
    return cv2.erode(m, np.ones((5, 5), np.uint8)).astype(bool)


def _face_residual(faces: list[FaceShade], boxes: list[BoxObservation],
                   lighting: LightingSpec) -> float:
    if not faces:
        return 0.0
    diffs = []
    for f in faces:
        factor = float(shade_factors(np.array([f.normal]), lighting)[0])
        diffs.append(min(boxes[f.box].top_gray * factor, 255.0) - f.gray)
    return float(np.sqrt(np.mean(np.square(diffs))))

