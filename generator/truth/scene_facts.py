"""Derived facts of a scene: per-image numbers that explain failures (docs/ground-truth.md
section "Derived facts"), computed analytically from the scene like the rest of the GT.

They are written into the GT's ``params`` under the prefix :data:`PREFIX` (so report
breakdowns rank them beside the sampled parameters) and never change an image.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from shapely.geometry import MultiPoint, Polygon

from arenabench.frame import FrameSpec
from arenabench.generator.model.layout import box_footprint, world_to_frame
from arenabench.generator.model.scene import Scene
from arenabench.generator.truth.groundtruth import visible_silhouette_world

#: Prefix of the derived facts' keys in the GT's ``params``.
PREFIX = "derived."
#: Two boxes whose visible silhouettes come closer than this (frame px) touch: the pixels
#: between them are mixed at best, so a contour-based pipeline sees one blob.
TOUCH_GAP_PX = 1.0

#: Key -> one line saying what it is (units included); the keys a GT's ``params`` gets.
FACTS: dict[str, str] = {
    "derived.max_aspect_ratio": "largest length / width (>= 1) of a box counted in the frame; "
                                "0 without boxes",
    "derived.max_visible_aspect_ratio": "largest long side / short side of the smallest "
                                        "rectangle around a counted box's visible "
                                        "silhouette in the frame (what a pipeline measures); "
                                        "0 without boxes",
    "derived.min_edge_distance_px": "smallest distance (frame px) from a counted box's visible "
                                    "silhouette to the frame's edge; negative when it crosses "
                                    "the edge; the frame's half side without boxes",
    "derived.touching_boxes": "boxes whose visible silhouette comes within "
                              f"{TOUCH_GAP_PX:g} frame px of another's",
    "derived.min_box_gap_px": "smallest gap (frame px) between the visible silhouettes of two "
                              "counted boxes; 0 when two touch or overlap; the frame's side "
                              "with fewer than two boxes",
}


def _apply(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.column_stack([pts, np.ones(len(pts))]) @ h.T
    return p[:, :2] / p[:, 2:3]


def derived_facts(scene: Scene, *, frame: FrameSpec | None = None) -> dict[str, Any]:
    """The derived facts of ``scene`` (keys of :data:`FACTS`).

    Only boxes counted in the ground truth (footprint overlapping the frame) take part.

    Parameters
    ----------
    scene : Scene
        The scene.
    frame : FrameSpec, keyword-only
        Rectified frame (default 1000 px, inner corners).

    Returns
    -------
    dict
        ``derived.max_aspect_ratio`` (float, of the boxes' length and width),
        ``derived.max_visible_aspect_ratio`` (float), ``derived.min_edge_distance_px`` (float, frame
        px, of the visible silhouettes), ``derived.touching_boxes`` (int),
        ``derived.min_box_gap_px`` (float, frame px).
    """
    frame = frame or FrameSpec()
    size = float(frame.size)
    w2f = world_to_frame(scene.arena, scene.markers, frame)
    frame_poly = Polygon([(0, 0), (size, 0), (size, size), (0, size)])
    ratios: list[float] = []
    seen: list[float] = []
    silhouettes: list[Polygon] = []
    edge = size / 2.0
    for i, ob in enumerate(scene.obstacles):
        if Polygon(_apply(w2f, box_footprint(ob))).intersection(frame_poly).area <= 0:
            continue
        ratios.append(max(ob.length_m, ob.width_m) / min(ob.length_m, ob.width_m))
        pts = _apply(w2f, visible_silhouette_world(scene, i))
        silhouettes.append(MultiPoint(pts).convex_hull)
        (_, _), (w, h), _ = cv2.minAreaRect(pts.astype(np.float32))
        seen.append(max(w, h) / max(min(w, h), 1e-9))
        # a convex silhouette is nearest to each side at a vertex
        edge = min(edge, float(np.min(np.concatenate([pts.ravel(), size - pts.ravel()]))))
    gap = size
    touching: set[int] = set()
    for a in range(len(silhouettes)):
        for b in range(a + 1, len(silhouettes)):
            d = float(silhouettes[a].distance(silhouettes[b]))
            gap = min(gap, d)
            if d < TOUCH_GAP_PX:
                touching.update((a, b))
    return {
        "derived.max_aspect_ratio": max(ratios, default=0.0),
        "derived.max_visible_aspect_ratio": max(seen, default=0.0),
        "derived.min_edge_distance_px": edge,
        "derived.touching_boxes": len(touching),
        "derived.min_box_gap_px": gap,
    }
