"""Competition style (f): Otsu, every contour counts.

Corners by id (corner 0 of 80, 1 of 85, 2 of 90, 3 of 95 -> the four frame corners), warp to
1000 x 1000, a 2 px crop on each side, grey, Otsu threshold inverted (boxes white),
``RETR_TREE`` and *no minimum area*: every contour found is an obstacle, and the area is the sum
of their ``cv2.contourArea``.

Seen in public e-Yantra 2024-25 Task 1C ``map.py`` solutions: ``threshold(gray, 0,
255, THRESH_BINARY_INV + THRESH_OTSU)``, ``findContours(..., RETR_TREE, ...)`` and
``len(contours)``, after a warp of the markers' inner corners and a 2 px crop. It is right on
the published example (2 obstacles) only because the warped image's corner pixels there are
light: a marker pixel that comes out darker than Otsu's threshold in a corner of the warp is a
speck, i.e. one more "obstacle". Kept as written: it is the style that notices the marker
pixels of a render (docs/rendering.md).
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
from competition_style import WIDTH, answer, detect_markers, main, not_found, warp_by_id

CROP = 2


def detect(image_bgr: np.ndarray) -> dict:
    """Count obstacles and their total area (frame px) on a BGR image."""
    corners, ids = detect_markers(image_bgr)
    warped = warp_by_id(image_bgr, corners, ids, size=WIDTH)
    if warped is None:
        return not_found(ids)
    gray = cv2.cvtColor(warped[CROP:-CROP, CROP:-CROP], cv2.COLOR_BGR2GRAY)
    _, binary = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    contours, _ = cv2.findContours(binary, cv2.RETR_TREE, cv2.CHAIN_APPROX_SIMPLE)
    return answer(len(contours), sum(cv2.contourArea(c) for c in contours), ids)


if __name__ == "__main__":
    sys.exit(main(detect))
