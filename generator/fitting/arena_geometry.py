"""The arena's geometry and scale: from a given arena texture (its printed markers located in
it), or, without one, from the image (the markers' square, and the floor's edge against the
background for the scale).

A single image of a flat arena fixes shapes and angles but not size: every length scales with
the camera's distance. The scale comes from ``--arena-size`` (the floor's size: the area the
arena texture covers or, without a texture, the floor out to its edge against the background);
without it the twin takes the generator's default arena (the markers' outer square
:data:`DEFAULT_SIDE_M` a side) and says the scale is open.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from arenabench.frame import CORNER_ORDER
from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.fitting.markers import MarkerFinding, MarkersNotFoundError, find_markers
from arenabench.generator.model import camera as cam
from arenabench.generator.model.scene import CameraSpec

#: Side (m) of the markers' outer square when nothing gives the scale (the generator's
#: default arena).
DEFAULT_SIDE_M = 8.0
#: The packaged competition texture's SHA-256: a given texture with these bytes is it.
COMPETITION_SHA256 = hashlib.sha256(comp.TEXTURE_PATH.read_bytes()).hexdigest() \
    if comp.TEXTURE_PATH.exists() else ""
#: A texture's marker square must be square and centred to this share of its side.
SQUARE_TOLERANCE = 0.01


class ArenaError(ValueError):
    """The given texture or size does not fit the image (one line says why)."""


@dataclass(frozen=True)
class ArenaGeometry:
    """Where the markers lie on the floor, in metres.

    Attributes
    ----------
    side_m : float
        Side of the markers' outer square (``arena.side_m``).
    marker_side_m : float or None
        The marker side; ``None`` when it is to be fitted (no texture).
    margin_m : float or None
        Floor beyond the markers' square on each side (``None``: not known yet).
    scale_source : str
        ``"texture"``, ``"floor edge"`` or ``"default"`` (open).
    texture : str
        ``"competition"`` (the packaged texture), ``"file"`` (a given image) or ``""``.
    texture_path : Path or None
        The given texture.
    """

    side_m: float
    marker_side_m: float | None
    margin_m: float | None
    scale_source: str
    texture: str = ""
    texture_path: Path | None = None


def _outer_corners(finding: MarkerFinding) -> np.ndarray:
    """Each marker's corner farthest from the four markers' centre (NW, NE, SE, SW)."""
    centre = np.mean([q.mean(axis=0) for q in finding.corners.values()], axis=0)
    return np.array([finding.corners[c][np.argmax(np.linalg.norm(finding.corners[c] - centre,
                                                                 axis=1))]
                     for c in CORNER_ORDER])


def texture_geometry(path: Path, size_m: tuple[float, float], image: MarkerFinding
                     ) -> ArenaGeometry:
    """The arena's geometry from a texture covering ``size_m`` (W, H metres) whose markers are
    the image's.

    Raises
    ------
    ArenaError
        The texture cannot be read, shows no markers or other ones, is not square, or its
        markers' square is not centred in it (the generator centres the arena).
    """
    data = path.read_bytes()
    if hashlib.sha256(data).hexdigest() == COMPETITION_SHA256 and abs(
            size_m[0] - comp.TEXTURE_SIDE_M) < 1e-9 and abs(size_m[1] - comp.TEXTURE_SIDE_M) < 1e-9:
        return ArenaGeometry(comp.ARENA_SIDE_M, comp.MARKER_SIDE_M, comp.ARENA_MARGIN_M,
                             "texture", comp.TEXTURE_NAME, path)
    bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ArenaError(f"--texture {path}: not an image file")
    h, w = bgr.shape[:2]
    if abs(size_m[0] / w - size_m[1] / h) > SQUARE_TOLERANCE * size_m[0] / w:
        raise ArenaError(f"--arena-size {size_m[0]:g},{size_m[1]:g}: the texture is {w} x {h} px, "
                         "texels would not be square")
    if abs(size_m[0] - size_m[1]) > SQUARE_TOLERANCE * size_m[0]:
        raise ArenaError(f"--arena-size {size_m[0]:g},{size_m[1]:g}: the generator's arenas "
                         "are square")
    try:
        found = find_markers(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    except MarkersNotFoundError as exc:
        raise ArenaError(f"--texture {path}: {str(exc).removeprefix('image: ')}") from None
    if (found.ids != image.ids or found.rotation_deg != image.rotation_deg
            or (found.dictionary not in image.family and image.dictionary not in found.family)):
        raise ArenaError(
            f"--texture {path}: its markers ({found.dictionary} {list(found.ids)}, printed "
            f"{found.rotation_deg:g} deg) are not the image's ({image.dictionary} "
            f"{list(image.ids)}, {image.rotation_deg:g} deg)")
    outer = _outer_corners(found)
    sides = np.linalg.norm(outer - np.roll(outer, -1, axis=0), axis=1)
    side_tex = float(sides.mean())
    centre = outer.mean(axis=0) - np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    if np.ptp(sides) > SQUARE_TOLERANCE * side_tex or np.hypot(*centre) > SQUARE_TOLERANCE * w:
        raise ArenaError(f"--texture {path}: its markers do not sit on a square centred in it "
                         "(the generator centres the arena on the markers' square)")
    metres = size_m[0] / w
    marker_tex = float(np.mean([np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1).mean()
                                for q in found.corners.values()]))
    side = round(side_tex * metres, 6)
    return ArenaGeometry(side, round(marker_tex * metres, 6),
                         round((size_m[0] - side) / 2.0, 6), "texture", "file", path)


def floor_edge_half(gray: np.ndarray, camera: CameraSpec, half_side: float, *,
                    floor: float, background: float) -> float | None:
    """Half side of the floor square (in the units of ``half_side``, the markers' outer
    square's half side) where the floor meets the background, measured along the image rows
    and columns through the arena's centre; ``None`` when no edge is found on at least two
    sides (the floor fills the view, or floor and background are too alike)."""
    if abs(floor - background) < 8:
        return None
    h = cam.floor_homography(cam.intrinsics(camera), cam.world_from_camera(camera))
    found = []
    threshold = (floor + background) / 2.0
    for direction in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        ts = np.linspace(half_side * 1.001, half_side * 3.0, 4000)
        for offset in np.linspace(-0.6, 0.6, 7) * half_side:
            pts = np.array([[t * direction[0] + offset * direction[1],
                             t * direction[1] + offset * direction[0]] for t in ts])
            px = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), h).reshape(-1, 2)
            inside = ((px[:, 0] >= 0) & (px[:, 0] <= gray.shape[1] - 1)
                      & (px[:, 1] >= 0) & (px[:, 1] <= gray.shape[0] - 1))
            if not inside.all():
                ts_in, px_in = ts[inside], px[inside]
            else:
                ts_in, px_in = ts, px
            if len(ts_in) < 10:
                continue
            vals = cv2.remap(gray.astype(np.float32), px_in[:, 0].astype(np.float32).reshape(1, -1),
                             px_in[:, 1].astype(np.float32).reshape(1, -1),
                             cv2.INTER_LINEAR).ravel()
            side_is_floor = (vals - threshold) * np.sign(floor - background) > 0
            # the first run of background long enough to not be a printed line
            run = np.convolve(~side_is_floor, np.ones(25), mode="valid") >= 25
            if run.any():
                k = int(np.argmax(run))
                if k > 0:
                    found.append(float(ts_in[k]))
    if len(found) < 4:
        return None
    return float(np.median(found))
