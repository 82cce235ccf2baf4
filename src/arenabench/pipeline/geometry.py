"""Reference corners, homographies and the resize transform.

Two ways to pick the four reference corners that go to the frame corners (NW, NE, SE, SW):

- **by index** (``seed``, as published): sort the markers by id and take marker-local corner
  ``k`` of the ``k``-th marker. On the competition arena (markers printed upside down) these
  are the inner corners; with upright markers they are the outer ones, and with other id
  layouts the quadrilateral can come out twisted.
- **by geometry** (``reference``): order the marker centres clockwise around their mean (as
  seen in the image), start at marker 80 when the ids are the competition's (so the frame
  keeps the arena's orientation whatever the image rotation), else at the marker nearest the
  image's top-left; then take, per marker, the corner nearest to (``inner``) or farthest from
  (``outer``) the mean of the four centres. Neither image rotation nor the print orientation
  of the markers changes the result.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from arenabench.frame import COMPETITION_MARKER_IDS, FrameSpec


def resize_matrix(in_size: tuple[int, int], out_size: tuple[int, int]) -> np.ndarray:
    """3 x 3 map from input px to resized px, matching ``cv2.resize`` (pixel centres).

    Parameters
    ----------
    in_size, out_size : (width, height)
    """
    sx = out_size[0] / in_size[0]
    sy = out_size[1] / in_size[1]
    return np.array(
        [[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]], dtype=np.float64
    )


def apply_homography(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map (N, 2) points through the 3 x 3 homography ``h``."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    homog = np.hstack([pts, np.ones((len(pts), 1))]) @ np.asarray(h, dtype=np.float64).T
    return homog[:, :2] / homog[:, 2:3]


def corners_by_index(corners: Sequence[np.ndarray]) -> np.ndarray:
    """Published choice: corner ``k`` of the ``k``-th marker (markers already sorted by id)."""
    return np.array([np.asarray(corners[k])[k] for k in range(4)], dtype=np.float64)


def corners_by_geometry(
    ids: Sequence[int], corners: Sequence[np.ndarray], convention: str
) -> tuple[np.ndarray, list[int]]:
    """Reference corners chosen by geometry.

    Parameters
    ----------
    ids : sequence of int
        The four marker ids.
    corners : sequence of (4, 2) arrays
        Their corners in image px.
    convention : {"inner", "outer"}
        Corner nearest to or farthest from the centre of the four markers.

    Returns
    -------
    (4, 2) float64 array, list of int
        The reference corners in NW, NE, SE, SW order and the marker id at each.
    """
    quads = [np.asarray(c, dtype=np.float64).reshape(4, 2) for c in corners]
    centres = np.array([q.mean(axis=0) for q in quads])
    mean = centres.mean(axis=0)
    angles = np.arctan2(centres[:, 1] - mean[1], centres[:, 0] - mean[0])
    order = list(np.argsort(angles))  # clockwise on screen (y points down)
    comp = COMPETITION_MARKER_IDS["nw"]
    if sorted(int(i) for i in ids) == sorted(COMPETITION_MARKER_IDS.values()):
        start = order.index(list(ids).index(comp))
    else:
        start = int(np.argmin([centres[k].sum() for k in order]))
    order = order[start:] + order[:start]
    picked = []
    for k in order:
        dist = np.linalg.norm(quads[k] - mean, axis=1)
        picked.append(quads[k][int(np.argmin(dist) if convention == "inner" else np.argmax(dist))])
    return np.array(picked), [int(ids[k]) for k in order]


def quad_is_sound(quad: np.ndarray, *, min_area: float = 16.0) -> bool:
    """True when the quadrilateral is convex, not self-intersecting and not degenerate."""
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    cross = []
    for k in range(4):
        a, b, c = q[k], q[(k + 1) % 4], q[(k + 2) % 4]
        cross.append((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]))
    cross_arr = np.array(cross)
    convex = bool(np.all(cross_arr > 0) or np.all(cross_arr < 0))
    area = 0.5 * abs(
        float(np.dot(q[:, 0], np.roll(q[:, 1], -1)) - np.dot(q[:, 1], np.roll(q[:, 0], -1)))
    )
    return convex and area >= min_area


def frame_homography(src: np.ndarray, frame: FrameSpec) -> np.ndarray:
    """Homography taking the reference corners ``src`` (NW, NE, SE, SW) to the frame corners."""
    return cv2.getPerspectiveTransform(
        np.asarray(src, dtype=np.float32), frame.corners_px().astype(np.float32)
    ).astype(np.float64)
