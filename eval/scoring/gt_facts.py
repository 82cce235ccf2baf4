"""Facts of an image read from its ground-truth record when it is scored: per-image numbers
that separate common failure modes (docs/ground-truth.md, "Derived facts"), ranked as causes
beside the scene parameters and the generator's ``derived.*`` facts.

They are computed by the harness from the GT's obstacles and markers (never from pixels), so
every dataset has them, whatever generator version wrote it, and adding one changes no image,
no GT file and no ``GENERATOR_VERSION``. Keys start with :data:`PREFIX`; a fact that an image
does not define (no counted box, no homography) is left out for that image.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from arenabench.gtrecord import GroundTruth

#: Prefix of the facts' keys in an image's ``params`` (reports, ``results.csv``).
PREFIX = "gt."

#: Key -> one line saying what it is (units included).
FACTS: dict[str, str] = {
    "gt.min_box_visible_px": "smallest visible area (frame px, inside the frame) of a counted "
                             "box: what a size filter meets first; left out without boxes",
    "gt.min_marker_gap_px": "smallest distance (frame px) from a counted box's visible "
                            "silhouette to a marker square; 0 when they touch; left out "
                            "without boxes, markers or homography",
}


def _finite(values: list[float]) -> bool:
    return bool(values) and all(math.isfinite(v) for v in values)


def _marker_quads(gt: GroundTruth) -> list[np.ndarray]:
    """The markers' squares in frame px (image corners through the GT homography; distorted
    corners undistorted first with the GT's camera)."""
    import cv2

    if gt.homography is None or not gt.markers:
        return []
    h = np.asarray(gt.homography, dtype=np.float64)
    if h.shape != (3, 3) or not np.isfinite(h).all():
        return []
    cam = gt.camera
    quads = []
    for m in gt.markers:
        if not m.corners_px or len(m.corners_px) != 4:
            continue
        pts = np.asarray(m.corners_px, dtype=np.float64).reshape(-1, 1, 2)
        if not np.isfinite(pts).all():
            continue
        if cam is not None and cam.K is not None and cam.dist is not None and any(cam.dist):
            k = np.asarray(cam.K, dtype=np.float64)
            pts = cv2.undistortPoints(pts, k, np.asarray(cam.dist, dtype=np.float64), P=k)
        quads.append(cv2.perspectiveTransform(pts, h).reshape(-1, 2))
    return quads


def gt_facts(gt: GroundTruth) -> dict[str, float]:
    """The facts of :data:`FACTS` that ``gt`` defines.

    Parameters
    ----------
    gt : GroundTruth
        One image's ground truth.

    Returns
    -------
    dict
        ``{key: value}``; a fact the record cannot give (no counted box, missing fields,
        non-finite numbers) is left out.
    """
    from shapely.geometry import Polygon

    out: dict[str, float] = {}
    counted = [o for o in gt.obstacles or ()
               if o.footprint_area_px is not None and o.footprint_area_px > 0]
    areas = [float(o.visible_area_px) for o in counted if o.visible_area_px is not None]
    if len(areas) == len(counted) and _finite(areas):
        out["gt.min_box_visible_px"] = min(areas)
    shapes: list[Any] = []
    for o in counted:
        pts = np.asarray(o.visible_frame_px or (), dtype=np.float64)
        if pts.ndim == 2 and pts.shape[0] >= 3 and pts.shape[1] == 2 and np.isfinite(pts).all():
            shapes.append(Polygon(pts).buffer(0))
    quads = [Polygon(q).buffer(0) for q in _marker_quads(gt)] if shapes else []
    if shapes and len(shapes) == len(counted) and quads:
        out["gt.min_marker_gap_px"] = min(float(s.distance(q)) for s in shapes for q in quads)
    return out
