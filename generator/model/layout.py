"""Where things lie on the arena: marker squares and corners, reference corners, world -> frame.

Shared by the renderer and the ground truth so both use one definition. Marker-local corner
order is cv2.aruco's: the generated marker image's top-left, top-right, bottom-right,
bottom-left. An upright marker has its image top towards north; ``rotation_deg`` turns the
printed marker counter-clockwise seen from above.
"""

from __future__ import annotations

import math

import numpy as np

from arenabench.frame import CORNER_ORDER, FrameSpec
from arenabench.generator.assets.texture_store import IMAGE_TEXTURE
from arenabench.generator.model.scene import ArenaSpec, FloorPatch, MarkerSpec, Obstacle

#: Height (m) of the marker sheets above the floor: keeps them off the floor's depth values.
MARKER_Z = 0.0005
#: A marker is in view when its corners lie this many px inside the image border (the GT's
#: ``in_view`` and the sampler's check that a camera sees all four markers).
IN_VIEW_MARGIN_PX = 2.0

#: Signs (sx, sy) of each arena corner.
_CORNER_SIGNS = {"nw": (-1, 1), "ne": (1, 1), "se": (1, -1), "sw": (-1, -1)}


def marker_square(arena: ArenaSpec, markers: MarkerSpec, corner: str) -> tuple[float, ...]:
    """(x_min, x_max, y_min, y_max) of the marker (quiet zone excluded) in an arena corner.

    The marker's outer corner coincides with the border square's corner.
    """
    if corner not in _CORNER_SIGNS:
        raise ValueError(f"corner must be one of {CORNER_ORDER}, got {corner!r}")
    sx, sy = _CORNER_SIGNS[corner]
    h, m = arena.side_m / 2.0, markers.side_m
    xs = sorted((sx * h, sx * (h - m)))
    ys = sorted((sy * h, sy * (h - m)))
    return xs[0], xs[1], ys[0], ys[1]


def marker_corners_world(
    arena: ArenaSpec, markers: MarkerSpec, corner: str, *, pad_m: float = 0.0
) -> np.ndarray:
    """World (x, y) of a marker's corners 0..3 in cv2.aruco order, shape (4, 2).

    Parameters
    ----------
    arena, markers : scene parts
    corner : {"nw", "ne", "se", "sw"}
        Which arena corner.
    pad_m : float, keyword-only
        Grow the square by this much on every side (the quiet zone's outline).
    """
    x0, x1, y0, y1 = marker_square(arena, markers, corner)
    x0, y0, x1, y1 = x0 - pad_m, y0 - pad_m, x1 + pad_m, y1 + pad_m
    upright = np.array([[x0, y1], [x1, y1], [x1, y0], [x0, y0]])
    centre = upright.mean(axis=0)
    a = math.radians(markers.rotation_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    out = (upright - centre) @ rot.T + centre
    return np.round(out, 12)


def reference_corners_world(
    arena: ArenaSpec, markers: MarkerSpec, corners: str = "inner"
) -> np.ndarray:
    """World (x, y) of the frame's reference corners in NW, NE, SE, SW order, shape (4, 2)."""
    if corners not in ("inner", "outer"):
        raise ValueError(f"corners must be 'inner' or 'outer', got {corners!r}")
    h = arena.side_m / 2.0
    d = h - markers.side_m if corners == "inner" else h
    return np.array([[sx * d, sy * d] for sx, sy in (_CORNER_SIGNS[c] for c in CORNER_ORDER)])


def world_to_frame(
    arena: ArenaSpec, markers: MarkerSpec, frame: FrameSpec | None = None
) -> np.ndarray:
    """3x3 affine map from floor (x, y, 1) in metres to frame px.

    ``u = S (x - x_nw) / (x_ne - x_nw)``, ``v = S (y_nw - y) / (y_nw - y_sw)``.
    """
    frame = frame or FrameSpec()
    ref = reference_corners_world(arena, markers, frame.corners)
    (x_nw, y_nw), (x_ne, _), _, (_, y_sw) = ref
    s = float(frame.size)
    sx, sy = s / (x_ne - x_nw), s / (y_nw - y_sw)
    return np.array([[sx, 0.0, -sx * x_nw], [0.0, -sy, sy * y_nw], [0.0, 0.0, 1.0]])


def floor_extent(arena: ArenaSpec) -> float:
    """Half side (m) of the floor square (border square plus margin)."""
    return arena.side_m / 2.0 + arena.margin_m


def floor_corners(arena: ArenaSpec) -> np.ndarray:
    """World (x, y) of the textured floor's corners, in the texture's TL, TR, BR, BL order
    (its first row north): the floor square, or the rectangle an image texture covers
    (``arena.texture_size_m``, centred on the arena)."""
    if arena.texture == IMAGE_TEXTURE:
        hx, hy = (s / 2.0 for s in arena.texture_size_m)
    else:
        hx = hy = floor_extent(arena)
    return np.array([[-hx, hy], [hx, hy], [hx, -hy], [-hx, -hy]])


def box_footprint(obstacle: Obstacle | FloorPatch) -> np.ndarray:
    """World (x, y) of a box's (or flat patch's) footprint corners, CCW from above, (4, 2)."""
    a = math.radians(obstacle.yaw_deg)
    ux = np.array([math.cos(a), math.sin(a)]) * obstacle.length_m / 2.0
    uy = np.array([-math.sin(a), math.cos(a)]) * obstacle.width_m / 2.0
    c = np.asarray(obstacle.center_m, dtype=np.float64)
    return np.array([c - ux - uy, c + ux - uy, c + ux + uy, c - ux + uy])


def box_vertices(obstacle: Obstacle) -> np.ndarray:
    """World (x, y, z) of a box's 8 vertices: the footprint at z = 0, then the top, (8, 3)."""
    fp = box_footprint(obstacle)
    low = np.column_stack([fp, np.zeros(4)])
    high = np.column_stack([fp, np.full(4, obstacle.height_m)])
    return np.vstack([low, high])


def facing_side_faces(obstacle: Obstacle, eye: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The side faces of a box that face the point ``eye`` (a camera's position), as
    ``(quad, normal)``: the face's 4 world vertices (bottom edge, then top) and its outward
    horizontal unit normal."""
    v = box_vertices(obstacle)
    out = []
    for i in range(4):
        j = (i + 1) % 4
        quad = v[[i, j, j + 4, i + 4]]
        edge = v[j, :2] - v[i, :2]
        normal = np.array([edge[1], -edge[0], 0.0]) / np.linalg.norm(edge)
        if normal @ (eye - quad.mean(axis=0)) > 0:
            out.append((quad, normal))
    return out
