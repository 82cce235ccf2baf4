"""Edge pixels as the competition's renderer draws them: two coverage samples per pixel,
averaged in linear light; and the other edge models a twin may need.

Measured on the published example (``docs/rendering.md``, "Edges"): every blended pixel along
the box outlines is the *half* blend of its two neighbouring surfaces in linear light (grey 188
between a dark side face of 71 and the floor of 248, 198 between the top face of 120 and the
floor), never a quarter blend, and the other edge pixels are hard steps. That is a two-sample
resolve in an sRGB framebuffer. This module holds that model and its neighbours (a scene's
``render`` section, :class:`~arenabench.generator.model.scene.RenderSpec`, picks one): where the
samples sit (:data:`EDGE_PATTERNS`), the region that gets them (:func:`obstacle_region`) and
the resolve (:func:`resolve_samples`). The renderer draws the samples; nothing here touches
OpenGL.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices
from arenabench.generator.model.scene import RenderSpec, Scene

__all__ = ["EDGE_PATTERNS", "EDGE_RESOLVES", "EDGE_SAMPLES", "REGION_PAD_PX",
           "SAME_SURFACE_MAX_DIFF", "edge_model", "linear_to_srgb", "obstacle_region",
           "resolve_samples", "srgb_to_linear"]

#: Offsets (x, y) in px from the pixel centre (x to the right, y down the rows) of the coverage
#: samples of each edge model, by samples per pixel. They are the standard multisample
#: positions of GL, Vulkan and Direct3D (Vulkan's "standard sample locations",
#: ``VkPhysicalDeviceLimits::standardSampleLocations``; Direct3D's
#: ``D3D11_STANDARD_MULTISAMPLE_PATTERN``; Mesa's ``intel_sample_positions.c`` lists the same):
#: 1 sample at the centre (hard edges); 2 on the diagonal, a quarter pixel either side of the
#: centre (corner-origin (0.25, 0.25) and (0.75, 0.75)); 4 on the rotated grid, corner-origin
#: (0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875), i.e. (-2, -6), (6, -2),
#: (-6, 2), (2, 6) sixteenths of a pixel from the centre.
#: ``tests/generator/rendering/test_edges.py`` checks that
#: the keys are the choices of ``render.edge_samples``.
EDGE_PATTERNS: dict[int, tuple[tuple[float, float], ...]] = {
    1: ((0.0, 0.0),),
    2: ((-0.25, -0.25), (0.25, 0.25)),
    4: ((-0.125, -0.375), (0.375, -0.125), (-0.375, 0.125), (0.125, 0.375)),
}

#: The competition renderer's pattern: two samples (the default ``render.edge_samples``).
EDGE_SAMPLES = EDGE_PATTERNS[RenderSpec().edge_samples]

#: How the samples of an edge pixel are averaged (``render.edge_resolve``): in linear light,
#: as an sRGB framebuffer resolves, or in sRGB values, as a plain (UNORM) one does.
EDGE_RESOLVES = {"linear": "averaged in linear light", "srgb": "averaged in sRGB values"}

#: Two samples whose colours differ by at most this many grey levels in every channel saw the
#: same surface: the pixel keeps its centre sample (textures are filtered once per pixel, as
#: in a multisample resolve, where only coverage is sampled per sample).
SAME_SURFACE_MAX_DIFF = 8

_WORDS = {1: "one", 2: "two", 4: "four"}


def edge_model(spec: RenderSpec) -> str:
    """How edges are drawn under ``spec``, as a dataset's ``dataset.json`` records it
    (``render.edges``)."""
    if spec.edge_samples == 1:
        return "one sample per pixel (hard edges)"
    at = [str(p) for p in EDGE_PATTERNS[spec.edge_samples]]
    where = ", ".join(at[:-1]) + f" and {at[-1]}"
    return (f"{_WORDS[spec.edge_samples]} samples per pixel at {where} px from its centre on "
            f"the obstacles' region, {EDGE_RESOLVES[spec.edge_resolve]}")


#: Margin in px around the obstacles' projected bounding box that gets the edge samples.
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


def resolve_samples(centre: np.ndarray, samples: tuple[np.ndarray, ...] | list[np.ndarray],
                    *, resolve: str = "linear") -> int:
    """Resolve coverage samples into ``centre``, in place; returns the pixels blended.

    Where the samples saw the same surface (every two of them differ by at most
    :data:`SAME_SURFACE_MAX_DIFF` in every channel) the pixel keeps its centre sample;
    elsewhere it becomes their mean: in linear light, encoded back to sRGB (``"linear"``), or
    of the sRGB values (``"srgb"``), rounded to nearest (ties to even, as
    :func:`linear_to_srgb`).

    Parameters
    ----------
    centre : numpy.ndarray
        (H, W, 3) uint8 single-sample render of the region, changed in place.
    samples : sequence of numpy.ndarray
        (H, W, 3) uint8 renders of the same region at the offsets of one of
        :data:`EDGE_PATTERNS`, at least one.
    resolve : {"linear", "srgb"}, keyword-only
        Where the mean is taken (:data:`EDGE_RESOLVES`).

    Returns
    -------
    int
        How many pixels were blended.
    """
    if resolve not in EDGE_RESOLVES:
        raise ValueError(f"resolve must be one of {', '.join(EDGE_RESOLVES)}, got {resolve!r}")
    if not samples or centre.dtype != np.uint8 or any(
            s.shape != centre.shape or s.dtype != np.uint8 for s in samples):
        raise ValueError(f"samples must be one or more uint8 images shaped like the centre "
                         f"{centre.shape}, got {[s.shape for s in samples]}")
    lo, hi = samples[0].copy(), samples[0].copy()
    for s in samples[1:]:
        np.minimum(lo, s, out=lo)
        np.maximum(hi, s, out=hi)
    diff = cv2.subtract(hi, lo)  # the largest difference between two samples, per channel
    edge = ((diff[..., 0] > SAME_SURFACE_MAX_DIFF) | (diff[..., 1] > SAME_SURFACE_MAX_DIFF)
            | (diff[..., 2] > SAME_SURFACE_MAX_DIFF))
    ys, xs = np.nonzero(edge)
    if len(ys):
        lut = _SRGB_TO_LINEAR if resolve == "linear" else np.arange(256, dtype=np.float64)
        total = lut[samples[0][ys, xs]]
        for s in samples[1:]:
            total = total + lut[s[ys, xs]]
        mean = total * (1.0 / len(samples))  # exact for 1, 2 and 4 samples
        centre[ys, xs] = (linear_to_srgb(mean) if resolve == "linear"
                          else np.clip(np.rint(mean), 0, 255).astype(np.uint8))
    return len(ys)
