"""Competition style (d): Canny edges, external contours, a small minimum area.

Corners by id (``corners[ids == 80][-1][0]``, 85 -> 1, 90 -> 2, 95 -> 3), warp to 1000 x 1000,
grey, 5 x 5 Gaussian blur, ``Canny(blur, 50, 100)``, external contours of the edge map, every one
over 100 px counted with ``cv2.contourArea`` (the outline of a closed edge loop encloses the box).

Seen in public e-Yantra 2024-25 Task 1C ``map.py`` solutions, e.g. Loki-Silvres/Warehouse-Drone
``src/swift_pico/scripts/map.py`` (``ArucoDetector`` with DICT_4X4_1000, ``Canny(blur, 50,
100)``, ``RETR_EXTERNAL``, ``area > 100``). No adjustment: it reads 72578.0 (+0.6 %) on the real
example.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
from competition_style import (
    WIDTH,
    answer,
    detect_markers,
    main,
    not_found,
    warp_by_id,
)

CANNY = (50, 100)
MIN_AREA = 100


def detect(image_bgr: np.ndarray) -> dict:
    """Count obstacles and their total area (frame px) on a BGR image."""
    corners, ids = detect_markers(image_bgr)
    warped = warp_by_id(image_bgr, corners, ids, size=WIDTH)
    if warped is None:
        return not_found(ids)
    gray = cv2.cvtColor(warped, cv2.COLOR_BGR2GRAY)
    blur = cv2.GaussianBlur(gray, (5, 5), 0)
    edges = cv2.Canny(blur, *CANNY)
    contours, _ = cv2.findContours(edges, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    kept = [a for a in (cv2.contourArea(c) for c in contours) if a > MIN_AREA]
    return answer(len(kept), sum(kept), ids)


if __name__ == "__main__":
    sys.exit(main(detect))
