"""The regions the twin's render is compared with the real image in: markers, box edges, box
faces, floor; and the figures of each (mean absolute grey difference).

- **markers**: each marker's bounding square (as ``cv2.aruco``'s default detector finds it on
  the real image) grown by :data:`MARKER_GROW_PX`, the squares the acceptance figures use;
- **box edges**: pixels within 2 px of the fitted boxes' image outlines;
- **faces**: the boxes' images, their edges left out;
- **floor**: the floor square's pixels outside the other regions.

Beside the differences, where the default ``cv2.aruco`` detector puts the markers' corners on
the render against the image (whole pixels: what scripts that warp from them see).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from arenabench.generator.fitting.edge_evidence import outline_band
from arenabench.generator.fitting.markers import MarkerFinding, detector_corner_offsets
from arenabench.generator.fitting.shades import floor_square_mask
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices, floor_extent
from arenabench.generator.model.scene import Scene

#: Pixels around each marker's bounding square in the "markers" region.
MARKER_GROW_PX = 8
#: The regions, in the order reports show them.
REGIONS = ("markers", "box edges", "faces", "floor")


@dataclass(frozen=True)
class RegionFigures:
    """Mean absolute grey difference per region (and per marker), and over the image.

    Attributes
    ----------
    mad : dict
        Region -> mean absolute grey difference (``None`` for an empty region).
    pixels : dict
        Region -> its pixels.
    per_marker : dict
        Marker id -> the difference in its square.
    whole : float
        Over the whole image.
    detector_px : dict
        Marker id -> how far the default ``cv2.aruco`` detector's corners on the render are
        from its corners on the image (px; ``None``: not found on the render), by
        :func:`~arenabench.generator.fitting.markers.detector_corner_offsets`.
    """

    mad: dict[str, float | None]
    pixels: dict[str, int]
    per_marker: dict[int, float]
    whole: float
    detector_px: dict[int, float | None]


def marker_squares(finding: MarkerFinding, shape: tuple[int, int],
                   grow: int = MARKER_GROW_PX) -> dict[int, np.ndarray]:
    """Each marker's bounding square (of its default-detector corners) grown by ``grow`` px,
    as a mask, by id."""
    out = {}
    for corner, quad in finding.detector_corners.items():
        marker_id = finding.ids[("nw", "ne", "se", "sw").index(corner)]
        x0, y0 = np.floor(quad.min(axis=0)).astype(int) - grow
        x1, y1 = np.ceil(quad.max(axis=0)).astype(int) + grow
        m = np.zeros(shape, bool)
        m[max(y0, 0):y1 + 1, max(x0, 0):x1 + 1] = True
        out[marker_id] = m
    return out


def region_masks(scene: Scene, finding: MarkerFinding, shape: tuple[int, int]
                 ) -> dict[str, np.ndarray]:
    """The masks of :data:`REGIONS` for ``scene`` (the fitted scene) on an image of ``shape``."""
    squares = marker_squares(finding, shape)
    markers = np.zeros(shape, bool)
    for m in squares.values():
        markers |= m
    edges = outline_band(scene.obstacles, scene.camera, shape)
    boxes = np.zeros(shape, bool)
    K, pose = cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera)
    for ob in scene.obstacles:
        hull = cv2.convexHull(cam.project(box_vertices(ob), K, pose).astype(np.float32))
        m = np.zeros(shape, np.uint8)
        cv2.fillPoly(m, [np.round(hull.reshape(-1, 2) * 16).astype(np.int32)], 1, shift=4)
        boxes |= m.astype(bool)
    floor = floor_square_mask(scene.camera, shape, floor_extent(scene.arena))
    return {"markers": markers, "box edges": edges & ~markers,
            "faces": boxes & ~edges & ~markers, "floor": floor & ~boxes & ~edges & ~markers}


def region_figures(render_gray: np.ndarray, real_gray: np.ndarray,
                   masks: dict[str, np.ndarray], finding: MarkerFinding) -> RegionFigures:
    """The figures of ``render_gray`` against ``real_gray`` (both (H, W) uint8)."""
    diff = np.abs(render_gray.astype(np.float64) - real_gray.astype(np.float64))
    mad = {name: (round(float(diff[m].mean()), 4) if m.any() else None)
           for name, m in masks.items()}
    per = {i: round(float(diff[m].mean()), 4)
           for i, m in sorted(marker_squares(finding, real_gray.shape).items())}
    return RegionFigures(mad, {k: int(m.sum()) for k, m in masks.items()}, per,
                         round(float(diff.mean()), 4),
                         detector_corner_offsets(render_gray, finding))


def difference_image(render_gray: np.ndarray, real_gray: np.ndarray, *,
                     gain: float = 8.0) -> np.ndarray:
    """A BGR picture of render minus real: grey 128 where equal, red where the render is
    lighter, blue where darker, ``gain`` times the difference."""
    d = (render_gray.astype(np.float64) - real_gray.astype(np.float64)) * gain
    out = np.full((*real_gray.shape, 3), 128.0)
    out[..., 2] += np.clip(d, 0, None)          # lighter: towards red
    out[..., 1] -= np.abs(d) * 0.5
    out[..., 0] += np.clip(-d, 0, None)         # darker: towards blue
    out[..., 2] -= np.clip(-d, 0, None) * 0.5
    out[..., 0] -= np.clip(d, 0, None) * 0.5
    return np.clip(out, 0, 255).astype(np.uint8)
