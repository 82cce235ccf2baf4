"""How the image's renderer drew box edges: coverage samples per pixel and where they were
averaged, read from the blends along the boxes' outlines.

A pixel an edge crosses takes a blend of its two sides: with ``n`` coverage samples the blend's
share of the lighter side is a multiple of ``1/n`` (0 or 1 is a hard step), measured in linear
light when the samples were averaged in an sRGB framebuffer, in sRGB values when in a plain
one. For each pixel within :data:`BAND_PX` of a fitted box outline whose 3 x 3 neighbourhood
spans two surfaces (a darkest and a lightest grey at least :data:`MIN_CONTRAST` apart), its
share is computed both ways; the blended ones (strictly between the two sides) vote:

- samples: 1 when almost no edge pixel is blended; else 4 when quarter blends (shares near 1/4
  or 3/4 in the space that fits best) are common, 2 when they are not;
- resolve: the space in which more blended pixels sit on a multiple of ``1/n``.

Too few blended pixels (no boxes, or boxes without contrast) leave both open.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices
from arenabench.generator.model.scene import CameraSpec, Obstacle
from arenabench.generator.rendering.edges import srgb_to_linear

#: Pixels within this distance (px) of a box outline are read.
BAND_PX = 2.0
#: Two sides of an edge differ by at least this many grey levels.
MIN_CONTRAST = 40
#: A blended pixel lies this many grey levels inside both sides.
BLEND_MARGIN = 6
#: A share within this distance of a multiple of 1/n sits on it.
ON_TOLERANCE = 0.07
#: Below this share of blended pixels among the edge pixels, edges are hard (one sample).
HARD_SHARE = 0.03
#: Quarter blends above this share of the blended pixels mean four samples.
QUARTER_SHARE = 0.2
#: Fewer blended pixels than this leave samples and resolve open.
MIN_BLENDED = 40


@dataclass(frozen=True)
class EdgeEvidence:
    """The edge model read from the image.

    Attributes
    ----------
    samples : int or None
        1, 2 or 4; ``None`` when open.
    resolve : str or None
        ``"linear"`` or ``"srgb"``; ``None`` when open (or meaningless: hard edges).
    edge_pixels : int
        Pixels read (near an outline, spanning two surfaces).
    blended : int
        Of those, the blended ones.
    shares : dict
        Per hypothesis (``"2/linear"``, ...), the share of blended pixels on a multiple of
        ``1/n``; and ``quarter/<space>``: the share near 1/4 or 3/4.
    reason : str
        Why a value is open ("" when both are pinned).
    """

    samples: int | None
    resolve: str | None
    edge_pixels: int
    blended: int
    shares: dict[str, float] = field(default_factory=dict)
    reason: str = ""


def outline_band(obstacles: tuple[Obstacle, ...] | list[Obstacle], camera: CameraSpec,
                 shape: tuple[int, int], width_px: float = BAND_PX) -> np.ndarray:
    """Pixels within ``width_px`` of the boxes' image outlines (convex hulls)."""
    K, pose = cam.intrinsics(camera), cam.world_from_camera(camera)
    outline = np.zeros(shape, np.uint8)
    for ob in obstacles:
        hull = cv2.convexHull(cam.project(box_vertices(ob), K, pose).astype(np.float32))
        cv2.polylines(outline, [np.round(hull * 16).astype(np.int32)], True, 1, 1,
                      cv2.LINE_8, 4)
    return cv2.distanceTransform(1 - outline, cv2.DIST_L2, 5) <= width_px


def _on(share: np.ndarray, n: int) -> np.ndarray:
    return np.abs(share * n - np.round(share * n)) <= ON_TOLERANCE * n


def read_edges(gray: np.ndarray, band: np.ndarray) -> EdgeEvidence:
    """Read the edge model from a grey image's pixels in ``band`` (see the module docstring).

    Parameters
    ----------
    gray : numpy.ndarray
        (H, W) uint8 image.
    band : numpy.ndarray
        (H, W) bool: the pixels near the boxes' outlines.
    """
    g = gray.astype(np.int32)
    lo = cv2.erode(gray, np.ones((3, 3), np.uint8)).astype(np.int32)
    hi = cv2.dilate(gray, np.ones((3, 3), np.uint8)).astype(np.int32)
    edge = band & (hi - lo >= MIN_CONTRAST)
    blended = edge & (g > lo + BLEND_MARGIN) & (g < hi - BLEND_MARGIN)
    n_edge, n_blend = int(edge.sum()), int(blended.sum())
    if n_edge == 0:
        return EdgeEvidence(None, None, 0, 0, reason="no box edge in the image")
    p, a, b = g[blended], lo[blended], hi[blended]
    share = {"srgb": (p - a) / np.maximum(b - a, 1),
             "linear": (srgb_to_linear(p) - srgb_to_linear(a))
             / np.maximum(srgb_to_linear(b) - srgb_to_linear(a), 1e-9)}
    shares: dict[str, float] = {}
    for space, s in share.items():
        for n in (2, 4):
            shares[f"{n}/{space}"] = round(float(_on(s, n).mean()), 4) if n_blend else 0.0
        quarter = (np.abs(s - 0.25) <= ON_TOLERANCE) | (np.abs(s - 0.75) <= ON_TOLERANCE)
        shares[f"quarter/{space}"] = round(float(quarter.mean()), 4) if n_blend else 0.0
    if n_blend < HARD_SHARE * n_edge:
        return EdgeEvidence(1, None, n_edge, n_blend, shares,
                            reason="hard edges: the samples' averaging space is not seen")
    if n_blend < MIN_BLENDED:
        return EdgeEvidence(None, None, n_edge, n_blend, shares,
                            reason=f"only {n_blend} blended edge pixels")
    space = max(("linear", "srgb"), key=lambda s: (shares[f"4/{s}"], s == "linear"))
    samples = 4 if shares[f"quarter/{space}"] >= QUARTER_SHARE else 2
    space = max(("linear", "srgb"), key=lambda s: (shares[f"{samples}/{s}"], s == "linear"))
    return EdgeEvidence(samples, space, n_edge, n_blend, shares)
