"""Lens distortion: OpenCV's model (k1, k2, p1, p2, k3) for images and for points.

The renderer draws a pinhole image on a canvas large enough to cover every distorted pixel's
source (:func:`lens_canvas`) and :func:`distort_image` resamples it; the ground truth distorts
its image-space points with the same model (:func:`distort_points`, i.e. ``cv2.projectPoints``
with the distortion coefficients; polygon edges first :func:`densify`-ed so that they bend).
The image -> frame homography stays defined on the undistorted image.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from arenabench.generator.parameters.params import lands_in

#: Preset parameter names of the lens distortion coefficients, in OpenCV's order.
LENS_PARAMS: tuple[str, ...] = tuple(
    name for _, name in sorted((int(f.split(".")[1]), name)
                               for f, name in lands_in("camera").items() if f.startswith("dist."))
)

#: Largest canvas (relative to the image side) rendered to cover a distorted image's sources.
MAX_CANVAS_SCALE = 3.0
#: Step (px) of the grid on which the inverse distortion map is solved (bilinear in between).
MAP_GRID_PX = 8


def has_distortion(dist: Any) -> bool:
    """Whether the coefficients ``(k1, k2, p1, p2, k3)`` describe any distortion."""
    return dist is not None and any(float(c) != 0.0 for c in dist)


def distort_points(points_px: np.ndarray, K: np.ndarray, dist: Any) -> np.ndarray:
    """Map undistorted (pinhole) image points to distorted image points (OpenCV's model).

    Parameters
    ----------
    points_px : numpy.ndarray
        (N, 2) pinhole image px.
    K : numpy.ndarray
        3x3 intrinsics.
    dist : sequence of float
        ``(k1, k2, p1, p2, k3)``.

    Returns
    -------
    numpy.ndarray
        (N, 2) distorted px (a copy of the input when ``dist`` is all zero).
    """
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    if not has_distortion(dist) or len(pts) == 0:
        return pts.copy()
    K = np.asarray(K, dtype=np.float64)
    xn = (pts[:, 0] - K[0, 2] - K[0, 1] * (pts[:, 1] - K[1, 2]) / K[1, 1]) / K[0, 0]
    yn = (pts[:, 1] - K[1, 2]) / K[1, 1]
    rays = np.column_stack([xn, yn, np.ones(len(pts))])
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K,
                               np.asarray(dist, dtype=np.float64))
    return out.reshape(-1, 2)


def undistort_points(points_px: np.ndarray, K: np.ndarray, dist: Any) -> np.ndarray:
    """Inverse of :func:`distort_points` (iterative, to about 1e-9 px), shape (N, 2)."""
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 1, 2)
    if not has_distortion(dist) or len(pts) == 0:
        return pts.reshape(-1, 2).copy()
    K = np.asarray(K, dtype=np.float64)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    out = cv2.undistortPoints(pts, K, np.asarray(dist, dtype=np.float64), None, K,
                              criteria=criteria)
    return out.reshape(-1, 2)


def densify(polygon_px: np.ndarray, *, step_px: float = 4.0) -> np.ndarray:
    """Insert points along a closed polygon's edges every ``step_px`` (vertices kept), (M, 2)."""
    poly = np.asarray(polygon_px, dtype=np.float64).reshape(-1, 2)
    if len(poly) < 2:
        return poly.copy()
    out = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        n = max(1, math.ceil(np.linalg.norm(b - a) / step_px))
        t = np.arange(n)[:, None] / n
        out.append(a + (b - a) * t)
    return np.concatenate(out)


@dataclass(frozen=True)
class LensCanvas:
    """How to render and resample a distorted image.

    Attributes
    ----------
    K : numpy.ndarray
        Intrinsics of the (larger) pinhole canvas to render.
    width, height : int
        Canvas size in px.
    map_x, map_y : numpy.ndarray
        (H, W) float32: for each distorted output pixel, where to sample the canvas.
    """

    K: np.ndarray
    width: int
    height: int
    map_x: np.ndarray
    map_y: np.ndarray


def lens_canvas(K: np.ndarray, dist: Any, width: int, height: int) -> LensCanvas:
    """The pinhole canvas covering every source of a distorted ``width`` x ``height`` image.

    The inverse map (distorted px -> pinhole px) is solved exactly on a grid every
    :data:`MAP_GRID_PX` px and interpolated bilinearly in between (a smooth map: well under
    0.01 px off). The canvas grows to hold the sources, up to :data:`MAX_CANVAS_SCALE` times the
    image side; samples beyond it repeat the canvas border.
    """
    key = (tuple(np.asarray(K, dtype=np.float64).ravel().tolist()),
           tuple(float(c) for c in dist), int(width), int(height))
    return _lens_canvas(key)


@functools.lru_cache(maxsize=4)
def _lens_canvas(key: tuple) -> LensCanvas:
    k_flat, dist, width, height = key
    K = np.array(k_flat, dtype=np.float64).reshape(3, 3)
    s = MAP_GRID_PX
    gx = np.arange(0, width - 1 + s, s, dtype=np.float64)
    gy = np.arange(0, height - 1 + s, s, dtype=np.float64)
    grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    src = undistort_points(grid, K, dist)
    if np.abs(distort_points(src, K, dist) - grid).max() > 0.01:
        raise ValueError(
            f"camera.k1..k3, camera.p1, camera.p2: lens distortion {list(dist)} folds over "
            "inside the image (no one-to-one map); use smaller coefficients"
        )
    src = src.reshape(len(gy), len(gx), 2).astype(np.float32)
    xs = (np.arange(width, dtype=np.float32) / s)[None, :].repeat(height, 0)
    ys = (np.arange(height, dtype=np.float32) / s)[:, None].repeat(width, 1)
    map_x = cv2.remap(src[:, :, 0], xs, ys, cv2.INTER_LINEAR)
    map_y = cv2.remap(src[:, :, 1], xs, ys, cv2.INTER_LINEAR)
    lo_x = max(math.floor(float(map_x.min())) - 2, -int((MAX_CANVAS_SCALE - 1) / 2 * width))
    lo_y = max(math.floor(float(map_y.min())) - 2, -int((MAX_CANVAS_SCALE - 1) / 2 * height))
    hi_x = min(math.ceil(float(map_x.max())) + 2,
               width - 1 + int((MAX_CANVAS_SCALE - 1) / 2 * width))
    hi_y = min(math.ceil(float(map_y.max())) + 2,
               height - 1 + int((MAX_CANVAS_SCALE - 1) / 2 * height))
    ox, oy = min(lo_x, 0), min(lo_y, 0)
    cw = max(hi_x, width - 1) - ox + 1
    ch = max(hi_y, height - 1) - oy + 1
    k_canvas = K.copy()
    k_canvas[0, 2] -= ox
    k_canvas[1, 2] -= oy
    map_x -= np.float32(ox)
    map_y -= np.float32(oy)
    for a in (k_canvas, map_x, map_y):
        a.setflags(write=False)
    return LensCanvas(K=k_canvas, width=int(cw), height=int(ch), map_x=map_x, map_y=map_y)


def distort_image(canvas_img: np.ndarray, canvas: LensCanvas, *,
                  interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """Resample a pinhole canvas render into the distorted image (``cv2.remap``)."""
    return cv2.remap(canvas_img, canvas.map_x, canvas.map_y, interpolation,
                     borderMode=cv2.BORDER_REPLICATE)
