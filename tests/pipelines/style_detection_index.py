"""Competition style (a): warp corners taken by *detection index*.

The team's script takes marker k of the detector's output (``corners[k]``) and a fixed corner
of it, in the order the detector happened to report the markers on the published example
(``cv2.aruco.ArucoDetector``: ids 90, 95, 85, 80): corner 2 of the first, 3 of the second, 1 of
the third and 0 of the fourth go to (1000, 1000), (0, 1000), (1000, 0) and (0, 0). That is right
exactly when a test image lists its markers in that order. Then: grey, a 2 px border cropped,
Otsu threshold (inverted), external contours over 500 px, ``cv2.contourArea``.

Seen in public e-Yantra 2024-25 Task 1C ``map.py`` solutions (code search for
``task1c_image`` / ``obstacles.txt``): corners picked as ``corners[0][0][2]``,
``corners[1][0][3]``, ... or ``marker_four[0], marker_three[2], ...`` in detection order, and
Otsu with a 2 px crop. Adjusted for the real example: those scripts counted every contour
(``RETR_TREE``); the example's warp leaves specks of a few px at the corners, so this keeps
contours over 500 px (the published method's minimum) to give 2 obstacles.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
from competition_style import HEIGHT, WIDTH, answer, detect_markers, main, not_found

#: (marker index in detection order, its corner) -> destination, as in the team's script.
PICKS = ((0, 2, (WIDTH, HEIGHT)), (1, 3, (0, HEIGHT)), (2, 1, (WIDTH, 0)), (3, 0, (0, 0)))
CROP_PX = 2
MIN_AREA = 500


def detect(image_bgr: np.ndarray) -> dict:
    """Count obstacles and their total area (frame px) on a BGR image."""
    corners, ids = detect_markers(image_bgr)
    if len(corners) < 4:
        return not_found(ids)
    src = np.float32([corners[k][0][c] for k, c, _ in PICKS])
    dst = np.float32([d for _, _, d in PICKS])
    warped = cv2.warpPerspective(image_bgr, cv2.getPerspectiveTransform(src, dst),
                                 (WIDTH, HEIGHT))
    cropped = warped[CROP_PX:HEIGHT - CROP_PX, CROP_PX:WIDTH - CROP_PX]
    gray = cv2.cvtColor(cropped, cv2.COLOR_BGR2GRAY)
    _, binary = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    areas = [cv2.contourArea(c) for c in contours]
    kept = [a for a in areas if a > MIN_AREA]
    return answer(len(kept), sum(kept), ids)


if __name__ == "__main__":
    sys.exit(main(detect))
