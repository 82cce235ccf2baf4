"""A pipeline that is right or wrong by the sub-pixel phase of a box edge (phase-check tests).

It answers what the reference pipeline answers, plus one obstacle too many when the left edge
of the first box it found ends on a fully covered pixel in the camera image: on the row
through the box's centre, the box's darkest pixels meet bare floor with no blended pixel
between them. The competition's renderer covers an edge pixel with 0, 1 or 2 of its 2
samples, so as the box moves across one pixel the answer is right at about half the positions
and wrong at the others.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np

from arenabench.pipeline import detect as reference_detect

#: Smallest coverage (fraction of the way from the floor's grey to the box's) of a blended
#: edge pixel; the competition renderer's half-covered pixels read about 0.35.
PARTIAL = 0.15


def edge_fully_covered(image_bgr: np.ndarray, det) -> bool:
    """Whether the first box's left edge, on its centre row, ends on a fully covered pixel
    (the next pixel to the left shows bare floor, not a blend)."""
    if not det.obstacles or det.homography is None:
        return False
    contour = np.asarray(det.obstacles[0].contour, dtype=np.float64).reshape(-1, 1, 2)
    h_inv = np.linalg.inv(np.asarray(det.homography, dtype=np.float64))
    pts = cv2.perspectiveTransform(contour, h_inv).reshape(-1, 2)
    cx, cy = (round(float(v)) for v in pts.mean(axis=0))
    row = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)[cy].astype(np.float64)
    box = row[cx]
    x = cx
    while x > 4 and row[x - 1] <= box + 3:  # x: the leftmost box-dark pixel
        x -= 1
    floor = row[x - 4]
    return bool((floor - row[x - 1]) / max(floor - box, 1.0) < PARTIAL)


def detect(image_bgr: np.ndarray) -> dict:
    """The reference answer, with one obstacle too many when the edge pixel is full."""
    det = reference_detect(image_bgr)
    if not det.ok:
        return {"status": "markers_not_found", "marker_ids": list(det.marker_ids or [])}
    extra = 1 if edge_fully_covered(image_bgr, det) else 0
    return {"count": det.count + extra, "area": det.area, "marker_ids": list(det.marker_ids)}


def reference_answer(image_bgr: np.ndarray) -> dict:
    """The reference pipeline's answer."""
    det = reference_detect(image_bgr)
    if not det.ok:
        return {"status": "markers_not_found", "marker_ids": list(det.marker_ids or [])}
    return {"count": det.count, "area": det.area, "marker_ids": list(det.marker_ids)}


def always_wrong(image_bgr: np.ndarray) -> dict:
    """The reference answer with one obstacle too many, always."""
    det = reference_detect(image_bgr)
    return {"count": det.count + 1, "area": det.area, "marker_ids": list(det.marker_ids)}


def garbage(image_bgr: np.ndarray) -> dict:
    """An answer that is no answer (``bad_output``), always."""
    return {"count": "many", "area": "large"}


def no_markers(image_bgr: np.ndarray) -> dict:
    """``markers_not_found``, always."""
    return {"status": "markers_not_found", "marker_ids": []}


if __name__ == "__main__":  # pragma: no cover
    sys.exit("import it: edge_phase:detect")


def aspect_filter(image_bgr: np.ndarray) -> dict:
    """The reference answer, counting only boxes with 0.3 < w/h < 3 (a public solution's
    filter): wrong exactly where a box is longer than three widths."""
    det = reference_detect(image_bgr)
    if not det.ok:
        return {"status": "markers_not_found", "marker_ids": list(det.marker_ids or [])}
    kept = []
    for ob in det.obstacles:
        (_, _), (w, h), _ = cv2.minAreaRect(np.asarray(ob.contour, dtype=np.float32))
        if h > 0 and 0.3 < w / h < 3:
            kept.append(ob.area)
    return {"count": len(kept), "area": sum(kept), "marker_ids": list(det.marker_ids)}
