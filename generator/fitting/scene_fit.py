"""Fit a scene description to a real overhead image of the arena.

Steps: (1) detect the four corner markers; (2) fit the camera to them with the twin's camera
fit (:func:`arenabench.generator.fitting.camera_fit.fit_camera`: a homography, then the
markers' pixels; the field of view held where it is known, round angles kept where they fit
as well), or take a known camera (``FitOptions.camera``);
(3) segment the boxes and fit each one's footprint and height so that its projected
silhouette matches the image; (4) read the floor, background and box grey levels and set the
lighting so that the baked shades give the observed top and side faces; (5) optionally refine
a few scalars (floor margin, border width) by maximising SSIM against the image (procedural
arenas only); (6) nudge the camera so that cv2.aruco finds the render's marker corners on the
same pixels as the image's (same outline lengths, same detection order; fitted cameras only).
Between (5) and (6), ``FitOptions.snap`` may replace each box by a candidate (e.g. on the
competition world's grid) when that brings the render closer to the image.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from arenabench.aruco import aruco_dictionary
from arenabench.frame import CORNER_ORDER
from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.fitting import camera_fit as cf
from arenabench.generator.fitting.markers import MarkerFinding
from arenabench.generator.fitting.similarity import mean_abs_diff, ssim
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import (
    box_vertices,
    facing_side_faces,
    marker_corners_world,
)
from arenabench.generator.model.scene import (
    ArenaSpec,
    CameraSpec,
    DirectionalLight,
    LightingSpec,
    MarkerSpec,
    Obstacle,
    Scene,
)
from arenabench.generator.parameters.params import PARAMETERS


@dataclass(frozen=True)
class FitOptions:
    """Options of :func:`fit_scene`.

    Parameters
    ----------
    arena, markers : ArenaSpec, MarkerSpec
        Known arena geometry. By default the competition's own arena texture
        (:mod:`arenabench.generator.assets.competition_arena`), whose printed markers fix the scale.
    fit_marker_side : bool
        Also fit the marker side (for an arena whose marker size is not known exactly).
    match_detector_rounds : int
        Rounds per step size of :func:`match_detector` (0 = skip it).
    fov_deg : float or None
        Known vertical field of view (default: that of the camera that rendered the
        competition's example,
        :data:`~arenabench.generator.assets.competition_arena.CAMERA_FOV_DEG`), held; None
        fits it too. Under a near-nadir camera the markers barely constrain it (the field of
        view trades against the altitude), so a known value is the better evidence.
    refine_rounds : int
        Rounds of coordinate-wise SSIM refinement of a few scalars (0 = none).
    camera : CameraSpec or None
        A known camera (e.g. the competition's,
        :func:`arenabench.generator.fitting.competition_world.competition_camera`): taken as it is,
        so ``fov_deg``, ``fit_marker_side`` and ``match_detector_rounds`` do not apply. Its
        image size must be the image's.
    snap : callable or None
        Maps a fitted box to a candidate (e.g. the competition world's grid,
        :func:`arenabench.generator.fitting.competition_world.snap_obstacle`); each candidate
        replaces
        its box when the render gets closer to the image (SSIM).
    min_box_px : int
        Smallest dark blob (px) taken as a box.
    """

    arena: ArenaSpec = field(default_factory=lambda: ArenaSpec(
        side_m=comp.ARENA_SIDE_M, margin_m=comp.ARENA_MARGIN_M, texture=comp.TEXTURE_NAME,
        border_width_m=0.0))
    markers: MarkerSpec = field(default_factory=lambda: MarkerSpec(side_m=comp.MARKER_SIDE_M))
    fit_marker_side: bool = False
    fov_deg: float | None = comp.CAMERA_FOV_DEG
    match_detector_rounds: int = 3
    refine_rounds: int = 1
    camera: CameraSpec | None = None
    snap: Callable[[Obstacle], Obstacle] | None = None
    min_box_px: int = 400

    def __post_init__(self) -> None:
        fov = PARAMETERS["camera.fov_deg"].bounds
        if self.refine_rounds < 0:
            raise ValueError(f"refine_rounds must be >= 0, got {self.refine_rounds!r}")
        if self.fov_deg is not None and not fov.lo <= float(self.fov_deg) <= fov.hi:
            raise ValueError(f"fov_deg must be in [{fov.lo:g}, {fov.hi:g}] or None, "
                             f"got {self.fov_deg!r}")
        if self.match_detector_rounds < 0:
            raise ValueError(f"match_detector_rounds must be >= 0, got "
                             f"{self.match_detector_rounds!r}")
        if self.min_box_px < 1:
            raise ValueError(f"min_box_px must be >= 1, got {self.min_box_px!r}")


@dataclass(frozen=True)
class FitResult:
    """A fitted scene and how well it matches the image.

    Attributes
    ----------
    scene : Scene
        The fitted scene.
    fov_deg : float
        Chosen vertical field of view.
    reprojection_px : float
        RMS reprojection error of the 16 marker corners under the fitted camera.
    ssim, mad : float
        Grayscale SSIM and mean absolute difference (grey levels) of its render vs the image.
    """

    scene: Scene
    fov_deg: float
    reprojection_px: float
    ssim: float
    mad: float


def detect_marker_corners(bgr: np.ndarray, markers: MarkerSpec, *,
                          refine: bool = True) -> dict[str, np.ndarray]:
    """Image corners (4, 2) of each arena corner's marker, cv2.aruco order, keyed nw..sw.

    ``refine`` turns on cv2.aruco's sub-pixel corner refinement; without it the corners are
    what ``cv2.aruco.ArucoDetector`` with default parameters (as competition scripts use it)
    reports.

    Raises
    ------
    ValueError
        When one of ``markers.ids`` is not found.
    """
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY) if bgr.ndim == 3 else bgr
    dictionary = aruco_dictionary(markers.dictionary, field="markers.dictionary")
    params = cv2.aruco.DetectorParameters()
    if refine:
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary, params).detectMarkers(gray)
    found = {} if ids is None else {
        int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), corners, strict=True)
    }
    out = {}
    for name, mid in zip(CORNER_ORDER, markers.ids, strict=True):
        if mid not in found:
            raise ValueError(f"image: marker id {mid} ({name}) not found")
        out[name] = found[mid].astype(np.float64)
    return out


#: Steps of :func:`match_detector`'s search, per orbit-camera parameter.
_MATCH_STEPS = {"target_x": 0.0005, "target_y": 0.0005, "altitude_m": 0.002, "tilt_deg": 0.02,
                "yaw_deg": 0.02, "roll_deg": 0.02, "fov_deg": 0.02}


def _moved_camera(camera: CameraSpec, name: str, d: float) -> CameraSpec:
    if name in ("target_x", "target_y"):
        t = list(camera.target_m)
        t[name == "target_y"] = round(t[name == "target_y"] + d, 6)
        return replace(camera, target_m=tuple(t))
    return replace(camera, **{name: round(getattr(camera, name) + d, 6)})


def match_detector(
    scene: Scene, image_bgr: np.ndarray, renderer, *, rounds: int = 3, fit_fov: bool = True,
) -> tuple[Scene, int]:
    """Nudge the camera until the detector finds the render's markers where it finds the image's.

    ``cv2.aruco.ArucoDetector`` with default parameters (what competition scripts use) reports
    whole-pixel corners from the thresholded outline, and it sorts markers by outline length;
    a camera fitted to sub-pixel corners can leave a few corners one pixel off and swap two
    markers of nearly equal size. A coordinate search over the orbit camera's parameters in
    sub-pixel steps (the field of view too when ``fit_fov``) minimises the number of
    differing corner pixels, ties broken by the mean absolute difference around the markers.

    Returns
    -------
    (Scene, total corner difference in px, summed over the 16 corners' x and y)
    """
    want = detect_marker_corners(image_bgr, scene.markers, refine=False)
    gray = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)
    window = np.zeros(gray.shape, bool)
    for quad in want.values():
        x0, y0 = np.floor(quad.min(axis=0)).astype(int) - 4
        x1, y1 = np.ceil(quad.max(axis=0)).astype(int) + 5
        window[max(y0, 0):y1, max(x0, 0):x1] = True

    def cost(candidate: Scene) -> float:
        bgr = render_bgr(candidate, renderer)
        try:
            got = detect_marker_corners(bgr, candidate.markers, refine=False)
        except ValueError:
            return math.inf
        pixels = sum(float(np.abs(want[k] - got[k]).sum()) for k in want)
        patch = np.abs(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)[window] - gray[window]).mean()
        return pixels + float(patch) / 100.0

    best = cost(scene)
    for scale in (4.0, 1.0, 0.25):
        for _ in range(rounds):
            improved = False
            for name, step in _MATCH_STEPS.items():
                if name == "fov_deg" and not fit_fov:
                    continue
                for d in (-step * scale, step * scale):
                    cand = replace(scene, camera=_moved_camera(scene.camera, name, d))
                    c = cost(cand)
                    if c < best:
                        best, scene, improved = c, cand, True
            if not improved or best < 1.0:
                break
    return scene, int(best)


def _plane_to_image(K: np.ndarray, pose: np.ndarray, z: float) -> np.ndarray:
    """Homography from (x, y, 1) on the plane at height ``z`` to image px."""
    r_cw = pose[:3, :3].T
    t_cw = -r_cw @ pose[:3, 3]
    return K @ np.column_stack([r_cw[:, 0], r_cw[:, 1], r_cw[:, 2] * z + t_cw])


def _box_silhouette(ob: Obstacle, K: np.ndarray, pose: np.ndarray, shape) -> np.ndarray:
    """Pixels at least half covered by the box's projection (4 x 4 supersampling)."""
    px = cam.project(box_vertices(ob), K, pose)
    ss = 4
    hull = cv2.convexHull(np.round((px * ss + (ss - 1) / 2.0) * 16).astype(np.int32))
    mask = np.zeros((shape[0] * ss, shape[1] * ss), np.uint8)
    cv2.fillPoly(mask, [hull], 1, lineType=cv2.LINE_8, shift=4)
    cover = mask.reshape(shape[0], ss, shape[1], ss).sum(axis=(1, 3))
    return cover >= (ss * ss) / 2


def _crop(mask: np.ndarray, K: np.ndarray, pad: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """The mask's bounding box grown by ``pad`` px, and K for that crop."""
    ys, xs = np.nonzero(mask)
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, mask.shape[0])
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, mask.shape[1])
    shift = np.eye(3)
    shift[0, 2], shift[1, 2] = -x0, -y0
    return mask[y0:y1, x0:x1], shift @ K


def _refine_box(ob: Obstacle, target: np.ndarray, K, pose) -> tuple[float, Obstacle]:
    """Coordinate search of centre, size and height maximising the silhouette IoU."""
    crop, k_crop = _crop(target, K)

    def iou(o: Obstacle) -> float:
        sil = _box_silhouette(o, k_crop, pose, crop.shape)
        return float((sil & crop).sum() / max((sil | crop).sum(), 1))

    def moved(o: Obstacle, name: str, d: float) -> Obstacle:
        if name in ("cx", "cy"):
            c = list(o.center_m)
            c[0 if name == "cx" else 1] += d
            return replace(o, center_m=tuple(c))
        return replace(o, **{name: max(getattr(o, name) + d, 1e-3)})

    best = iou(ob)
    for step in (0.01, 0.005, 0.0025):
        improved = True
        while improved:
            improved = False
            for name in ("cx", "cy", "length_m", "width_m", "height_m"):
                for d in (-step, step):
                    cand = moved(ob, name, d)
                    v = iou(cand)
                    if v > best + 1e-9:
                        best, ob, improved = v, cand, True
    return best, ob


def _side_faces(gray, ob: Obstacle, K, pose, side_mask) -> tuple:
    """(world normal, median grey) of each visible side face covering >= 30 side px."""
    out = []
    for quad, normal in facing_side_faces(ob, pose[:3, 3]):
        px = cam.project(quad, K, pose)
        m = np.zeros(gray.shape, np.uint8)
        cv2.fillPoly(m, [np.round(px).astype(np.int32)], 1)
        # 5 x 5: a face seen nearly edge-on (a sliver a few px wide) is all edge pixels
        m = cv2.erode(m, np.ones((5, 5), np.uint8)).astype(bool) & side_mask
        if m.sum() >= 30:
            out.append((tuple(float(c) for c in normal), float(np.median(gray[m]))))
    return tuple(out)


@dataclass(frozen=True)
class BoxObservation:
    """A box seen in the image: its fitted obstacle and observed top/side grey levels."""

    obstacle: Obstacle
    top_gray: float
    side_faces: tuple[tuple[tuple[float, float, float], float], ...]
    iou: float


#: A pixel belongs to a box when it is this much darker than the floor (lit side faces can be
#: only a little darker than the floor, so the margin stays small).
DARK_MARGIN = 40


def _dark_blobs(gray: np.ndarray, exclude: np.ndarray, min_px: int, floor: float) -> list:
    dark = ((gray < floor - DARK_MARGIN) & ~exclude).astype(np.uint8)
    dark = cv2.morphologyEx(dark, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(dark, connectivity=8)
    return [labels == i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= min_px]


def fit_boxes(
    gray: np.ndarray, camera: CameraSpec, arena: ArenaSpec, markers: MarkerSpec, *,
    floor_gray: float, min_box_px: int = 400,
) -> list[BoxObservation]:
    """Segment the boxes and fit each one's footprint, yaw and height.

    The top face (the blob's commonest grey level) is back-projected to the plane at each
    candidate height; its minimum-area rectangle gives the footprint, and the height whose
    projected box silhouette best overlaps the blob (IoU) wins.
    """
    K = cam.intrinsics(camera)
    pose = cam.world_from_camera(camera)
    exclude = np.zeros(gray.shape, bool)
    for c in CORNER_ORDER:
        quad = marker_corners_world(arena, markers, c, pad_m=markers.quiet_zone_m + 0.05)
        px = cam.project(np.column_stack([quad, np.zeros(4)]), K, pose)
        m = np.zeros(gray.shape, np.uint8)
        cv2.fillPoly(m, [np.round(px).astype(np.int32)], 1)
        exclude |= m.astype(bool)
    out = []
    g8 = np.clip(np.rint(gray), 0, 255).astype(np.uint8)
    for blob in _dark_blobs(gray, exclude, min_box_px, floor_gray):
        hist = np.bincount(g8[blob], minlength=256)
        mode = int(np.argmax(hist))
        top = blob & (np.abs(gray - mode) <= 6)
        top = cv2.morphologyEx(top.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        ys, xs = np.nonzero(top)
        if len(xs) < 3:  # no top face of one grey (a palette image's dithering): the blob
            ys, xs = np.nonzero(blob)
        pts = np.column_stack([xs, ys]).astype(np.float64)
        hull = cv2.convexHull(pts.astype(np.float32))
        if hull is None or len(hull) < 3:
            continue  # a line of pixels, not a box
        hull = hull.reshape(-1, 2).astype(np.float64)
        crop, k_crop = _crop(blob, K)
        best = None
        for h in np.arange(0.05, 2.0, 0.01):
            hinv = np.linalg.inv(_plane_to_image(K, pose, float(h)))
            w = cv2.perspectiveTransform(hull.reshape(-1, 1, 2), hinv).reshape(-1, 2)
            (cx, cy), (lw, ww), ang = cv2.minAreaRect(w.astype(np.float32))
            if lw < ww:
                lw, ww, ang = ww, lw, ang + 90.0
            ang = (ang + 90.0) % 180.0 - 90.0
            ob = Obstacle(center_m=(cx, cy), yaw_deg=ang, length_m=max(lw, 1e-3),
                          width_m=max(ww, 1e-3), height_m=float(h), color_rgb=(mode,) * 3)
            sil = _box_silhouette(ob, k_crop, pose, crop.shape)
            iou = float((sil & crop).sum() / max((sil | crop).sum(), 1))
            if best is None or iou > best[0]:
                best = (iou, ob)
        iou, ob = best
        # Refine against the blob: every pixel visibly darker than the floor counts, as in
        # detection pipelines, so a render's hard edges give the same thresholded area.
        iou, ob = _refine_box(ob, blob, K, pose)
        ob = replace(ob, center_m=tuple(round(v, 4) for v in ob.center_m),
                     yaw_deg=round(ob.yaw_deg, 3), length_m=round(ob.length_m, 4),
                     width_m=round(ob.width_m, 4), height_m=round(ob.height_m, 3))
        sides = _side_faces(gray, ob, K, pose, blob & ~top.astype(bool))
        top_px = gray[top.astype(bool)]  # none left by the opening: the blob's commonest grey
        out.append(BoxObservation(ob, float(np.median(top_px)) if top_px.size else float(mode),
                                  sides, iou))
    return out


#: Weight of the light intensity in :func:`fit_lighting`'s least squares (a tie-breaker).
LIGHT_PENALTY = 1e-4


def fit_lighting(boxes: list[BoxObservation]) -> LightingSpec:
    """Ambient + one directional light whose baked shades give the observed face ratios.

    The top face's factor is 1 (so albedos equal the observed top greys and the floor grey);
    each visible side face's factor should be its grey over its box's top grey. Grid search
    over the light's azimuth and elevation, ambient solved in closed form.
    """
    obs = [(np.array(n), g / max(b.top_gray, 1.0)) for b in boxes for n, g in b.side_faces]
    if not obs:
        return LightingSpec(ambient=1.0, directional=())
    normals = np.array([n for n, _ in obs])
    ratios = np.array([r for _, r in obs])
    best = None
    for el in np.radians(np.arange(5.0, 90.0, 1.0)):
        for az in np.radians(np.arange(0.0, 360.0, 2.0)):
            to_light = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                                 math.sin(el)])
            lam = np.clip(normals @ to_light, 0.0, None)
            # factor = amb + I lam with amb + I sin(el) = 1  ->  factor = 1 + I (lam - sin(el))
            x = lam - math.sin(el)
            inten = (x @ (ratios - 1.0)) / max(x @ x, 1e-12)
            inten = float(np.clip(inten, 0.0, 1.0 / math.sin(el)))
            # the small penalty picks, among lights that fit the observed faces equally well,
            # the weakest one: faces the image does not show (e.g. east and west when only
            # south and north faces are seen) then keep the ambient shade instead of an
            # arbitrary bright one
            res = float(np.sum((1.0 + inten * x - ratios) ** 2)) + LIGHT_PENALTY * inten ** 2
            if best is None or res < best[0]:
                best = (res, to_light, inten, el)
    _, to_light, inten, el = best
    ambient = 1.0 - inten * math.sin(el)
    light = DirectionalLight(direction=tuple(round(float(-c), 5) for c in to_light),
                             intensity=round(inten, 5))
    return LightingSpec(ambient=round(ambient, 5), directional=(light,))


def _floor_mask(scene: Scene, shape: tuple[int, int], half: float) -> np.ndarray:
    K = cam.intrinsics(scene.camera)
    pose = cam.world_from_camera(scene.camera)
    h = _plane_to_image(K, pose, 0.0)
    sq = np.array([[-half, -half], [half, -half], [half, half], [-half, half]], np.float64)
    px = cv2.perspectiveTransform(sq.reshape(-1, 1, 2), h).reshape(-1, 2)
    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [np.round(px * 16).astype(np.int32)], 1, shift=4)
    return m.astype(bool)


def _mode(values: np.ndarray) -> int:
    v = np.clip(np.rint(values), 0, 255).astype(np.int64)
    return int(np.argmax(np.bincount(v, minlength=256)))


def render_bgr(scene: Scene, renderer) -> np.ndarray:
    """Render ``scene`` with ``renderer`` and return it in OpenCV's BGR order."""
    return cv2.cvtColor(renderer.render(scene).rgb, cv2.COLOR_RGB2BGR)


def fit_score(scene: Scene, image_bgr: np.ndarray, renderer) -> tuple[float, float]:
    """(SSIM, mean absolute difference) of ``scene``'s render vs the image, in grayscale."""
    bgr = render_bgr(scene, renderer)
    return ssim(bgr, image_bgr), mean_abs_diff(bgr, image_bgr)


def fit_scene(image_bgr: np.ndarray, *, options: FitOptions | None = None,
              renderer=None) -> FitResult:
    """Fit a scene to an overhead image of the arena.

    Parameters
    ----------
    image_bgr : numpy.ndarray
        (H, W, 3) uint8 BGR image.
    options : FitOptions, keyword-only
        Arena geometry and search options.
    renderer : Renderer, keyword-only
        Reused renderer (one is created when omitted).

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        When the image is not an (H, W, 3) uint8 array or a marker is missing.
    """
    options = options or FitOptions()
    img = np.asarray(image_bgr)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError(f"image_bgr must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
    height, width = img.shape[:2]
    gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float64)
    known = options.camera
    if known is not None and (known.width, known.height) != (width, height):
        raise ValueError(f"image is {width} x {height} px, the known camera "
                         f"{known.width} x {known.height}")
    markers, camera = options.markers, known
    corners = detect_marker_corners(img, markers)
    if camera is None:  # the one camera fit (the twin's): homography, then the marker pixels
        finding = MarkerFinding(
            dictionary=markers.dictionary, family=(markers.dictionary,), ids=markers.ids,
            corners=corners, detector_corners=detect_marker_corners(img, markers, refine=False),
            rotation_deg=markers.rotation_deg, bit_errors=0, tried=(markers.dictionary,))
        fit = cf.fit_camera(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), finding,
                            arena=options.arena, markers=markers,
                            fit_marker_side=options.fit_marker_side, fov_deg=options.fov_deg)
        markers, camera = replace(markers, side_m=fit.marker_side_m), fit.camera
    fov = camera.fov_deg
    world = cf.world_corners(options.arena, markers)
    proj = cam.project(world, cam.intrinsics(camera), cam.world_from_camera(camera))
    image = np.vstack([corners[c] for c in CORNER_ORDER])
    err = float(np.sqrt(np.mean(np.sum((proj - image) ** 2, axis=1))))
    arena = options.arena
    probe = Scene(arena=arena, markers=markers, obstacles=(), camera=camera)
    inner = _floor_mask(probe, gray.shape, arena.side_m / 2 - markers.side_m - 0.1)
    floor_gray = _mode(gray[inner])
    boxes = fit_boxes(gray, camera, arena, markers, floor_gray=floor_gray,
                      min_box_px=options.min_box_px)
    lighting = fit_lighting(boxes)
    obstacles = tuple(
        replace(b.obstacle, color_rgb=(round(b.top_gray),) * 3) for b in boxes
    )
    outside = ~_floor_mask(probe, gray.shape, arena.side_m / 2 + arena.margin_m + 0.3)
    background = _mode(gray[outside]) if outside.any() else floor_gray
    scene = Scene(
        arena=replace(arena, floor_rgb=(floor_gray,) * 3), markers=markers,
        obstacles=obstacles, camera=camera, lighting=lighting,
        background_rgb=(background,) * 3,
    )
    own = renderer is None
    if own:
        from arenabench.generator.rendering.render import Renderer

        renderer = Renderer()
    try:
        best = fit_score(scene, img, renderer)
        # the competition texture fixes the margin and the border line: nothing to refine
        rounds = 0 if arena.texture == comp.TEXTURE_NAME else options.refine_rounds
        for _ in range(rounds):
            for field_name, steps in (("margin_m", (-0.1, -0.05, -0.025, 0.025, 0.05, 0.1)),
                                      ("border_width_m", (-0.005, 0.005))):
                base = getattr(scene.arena, field_name)
                for step in steps:
                    value = round(base + step, 4)
                    if value <= 0:
                        continue
                    cand = replace(scene, arena=replace(scene.arena, **{field_name: value}))
                    s = fit_score(cand, img, renderer)
                    if s[0] > best[0]:
                        best, scene = s, cand
        for i, box in enumerate(scene.obstacles if options.snap else ()):
            boxes = list(scene.obstacles)
            boxes[i] = options.snap(box)
            cand = replace(scene, obstacles=tuple(boxes))
            s = fit_score(cand, img, renderer)
            if s[0] > best[0]:
                best, scene = s, cand
        if options.match_detector_rounds and options.camera is None:
            scene, _ = match_detector(scene, img, renderer, rounds=options.match_detector_rounds,
                                      fit_fov=options.fov_deg is None)
            best = fit_score(scene, img, renderer)
    finally:
        if own:
            renderer.close()
    return FitResult(scene=scene, fov_deg=round(fov, 4), reprojection_px=err,
                     ssim=best[0], mad=best[1])
