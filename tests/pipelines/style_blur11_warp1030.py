"""Competition style (g): Gaussian blur 11, threshold 127, a 1030 x 1030 warp, every contour.

Corners by id (corner 0 of 80, 1 of 85, 2 of 90, 3 of 95 -> the four frame corners), warp to
**1030 x 1030**, grey, ``GaussianBlur(gray, (11, 11), 0)``, ``threshold(..., 127,
THRESH_BINARY_INV)`` (boxes white), ``RETR_TREE`` and no minimum area: every contour is an
obstacle; the area is the sum of their ``cv2.contourArea`` scaled to the 1000 px frame
((1000 / 1030)^2).

Seen in public e-Yantra 2024-25 Task 1C ``map.py`` solutions: an 11 x 11 blur and
``threshold(blur, 127, 255, THRESH_BINARY_INV)`` after a warp to 1030 px. As with
``style_otsu_every_contour``, a dark speck where a marker's pixels reach into the warp's
corner counts as an obstacle, so it notices the marker pixels of a render.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
from competition_style import answer, detect_markers, main, not_found, warp_by_id

SIZE = 1030
BLUR = (11, 11)
THRESHOLD = 127


def detect(image_bgr: np.ndarray) -> dict:
    """Count obstacles and their total area (frame px) on a BGR image."""
    corners, ids = detect_markers(image_bgr)
    warped = warp_by_id(image_bgr, corners, ids, size=SIZE)
    if warped is None:
        return not_found(ids)
    gray = cv2.cvtColor(warped, cv2.COLOR_BGR2GRAY)
    blur = cv2.GaussianBlur(gray, BLUR, 0)
    _, binary = cv2.threshold(blur, THRESHOLD, 255, cv2.THRESH_BINARY_INV)
    contours, _ = cv2.findContours(binary, cv2.RETR_TREE, cv2.CHAIN_APPROX_SIMPLE)
    return answer(len(contours), sum(cv2.contourArea(c) for c in contours), ids)


if __name__ == "__main__":
    sys.exit(main(detect))
