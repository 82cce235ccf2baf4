"""Edge pixels as the competition's renderer draws them: two coverage samples per pixel,
averaged in linear light.

Measured on the published example (``docs/rendering.md``, "Edges"): every blended pixel along
the box outlines is the *half* blend of its two neighbouring surfaces in linear light (grey 188
between a dark side face of 71 and the floor of 248, 198 between the top face of 120 and the
floor), never a quarter blend, and the other edge pixels are hard steps. That is a two-sample
resolve in an sRGB framebuffer. This module holds that model: where the samples sit
(:data:`EDGE_SAMPLES`), the region that gets them (:func:`obstacle_region`) and the resolve
(:func:`resolve_two_samples`). The renderer draws the samples; nothing here touches OpenGL.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from . import camera as cam
from .layout import box_vertices
from .scene import Scene

__all__ = ["EDGE_MODEL", "EDGE_SAMPLES", "REGION_PAD_PX", "SAME_SURFACE_MAX_DIFF", "linear_to_srgb",
           "obstacle_region", "resolve_two_samples", "srgb_to_linear"]

#: Offsets (x, y) in px, from the pixel centre, of the two coverage samples (the standard
#: two-sample pattern: on the diagonal, a quarter pixel either side of the centre).
EDGE_SAMPLES: tuple[tuple[float, float], tuple[float, float]] = ((-0.25, -0.25), (0.25, 0.25))

#: Two samples whose colours differ by at most this many grey levels in every channel saw the
#: same surface: the pixel keeps its centre sample (textures are filtered once per pixel, as
#: in a multisample resolve, where only coverage is sampled per sample).
SAME_SURFACE_MAX_DIFF = 8

#: How edges are drawn, as recorded in a dataset's ``dataset.json`` (``render.edges``).
EDGE_MODEL = (f"two samples per pixel at {EDGE_SAMPLES[0]} and {EDGE_SAMPLES[1]} px from its "
              "centre on the obstacles' region, averaged in linear light")

#: Margin in px around the obstacles' projected bounding box that gets two samples.
REGION_PAD_PX = 2

_SRGB = np.arange(256) / 255.0
_SRGB_TO_LINEAR = np.where(_SRGB <= 0.04045, _SRGB / 12.92, ((_SRGB + 0.055) / 1.055) ** 2.4)


def srgb_to_linear(values: np.ndarray) -> np.ndarray:
    """Linear-light intensities (float64, 0..1) of 8-bit sRGB ``values`` (IEC 61966-2-1)."""
    return _SRGB_TO_LINEAR[np.asarray(values, dtype=np.uint8)]


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """8-bit sRGB values (rounded to nearest) of linear-light intensities in 0..1."""
    y = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    s = np.where(y <= 0.0031308, y * 12.92, 1.055 * np.power(y, 1.0 / 2.4) - 0.055)
    return np.clip(np.rint(s * 255.0), 0, 255).astype(np.uint8)


def obstacle_region(scene: Scene) -> tuple[int, int, int, int] | None:
    """Pixel box ``(x0, y0, x1, y1)`` (end-exclusive) holding every obstacle's image.

    Parameters
    ----------
    scene : Scene
        The scene; its camera must be a pinhole (no distortion), as the renderer draws it.

    Returns
    -------
    tuple of int or None
        The bounding box of the obstacles' projected vertices, grown by
        :data:`REGION_PAD_PX` and clipped to the image; the whole image when an obstacle is
        not wholly in front of the camera; ``None`` when there is no obstacle in view.
    """
    w, h = scene.camera.width, scene.camera.height
    if not scene.obstacles:
        return None
    K, pose = cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera)
    try:
        pts = np.concatenate([cam.project(box_vertices(ob), K, pose) for ob in scene.obstacles])
    except ValueError:  # a vertex behind the camera: its image is unbounded
        return (0, 0, w, h)
    x0 = max(math.floor(pts[:, 0].min()) - REGION_PAD_PX, 0)
    y0 = max(math.floor(pts[:, 1].min()) - REGION_PAD_PX, 0)
    x1 = min(math.ceil(pts[:, 0].max()) + REGION_PAD_PX + 1, w)
    y1 = min(math.ceil(pts[:, 1].max()) + REGION_PAD_PX + 1, h)
    if x1 <= x0 or y1 <= y0:
        return None
    return (int(x0), int(y0), int(x1), int(y1))


def resolve_two_samples(centre: np.ndarray, first: np.ndarray, second: np.ndarray) -> int:
    """Resolve two coverage samples into ``centre``, in place; returns the pixels blended.

    Where the samples saw the same surface (they differ by at most
    :data:`SAME_SURFACE_MAX_DIFF` in every channel) the pixel keeps its centre sample;
    elsewhere it becomes their mean in linear light, encoded back to sRGB.

    Parameters
    ----------
    centre : numpy.ndarray
        (H, W, 3) uint8 single-sample render of the region, changed in place.
    first, second : numpy.ndarray
        (H, W, 3) uint8 renders of the same region at the two :data:`EDGE_SAMPLES` offsets.

    Returns
    -------
    int
        How many pixels were blended.
    """
    if not centre.shape == first.shape == second.shape or centre.dtype != np.uint8:
        raise ValueError(f"samples must be equal-shaped uint8 images, got {centre.shape}, "
                         f"{first.shape}, {second.shape}")
    diff = cv2.absdiff(first, second)
    edge = ((diff[..., 0] > SAME_SURFACE_MAX_DIFF) | (diff[..., 1] > SAME_SURFACE_MAX_DIFF)
            | (diff[..., 2] > SAME_SURFACE_MAX_DIFF))
    ys, xs = np.nonzero(edge)
    if len(ys):
        mean = (_SRGB_TO_LINEAR[first[ys, xs]] + _SRGB_TO_LINEAR[second[ys, xs]]) * 0.5
        centre[ys, xs] = linear_to_srgb(mean)
    return len(ys)
