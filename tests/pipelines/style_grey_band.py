"""Competition style (c): a grey band, ``cv2.inRange`` 88 .. 192 on all three channels.

Markers sorted by position (centres: top two by x, bottom two by x), corner 0 of the top-left,
1 of the top-right, 3 of the bottom-left and 2 of the bottom-right marker (on the competition
arena, markers printed rotated 180 deg, the inner corners), warp to 1000 x 1000 (destination
corners at 999), ``inRange(warped, (88, 88, 88), (192, 192, 192))``, external contours over
1000 px, ``cv2.contourArea``.

Seen in a public e-Yantra 2024-25 Task 1C ``map.py`` (code search for ``obstacles.txt``):
``lower_bound = [88.7] * 3``, ``upper_bound = [192] * 3``, ``min_area = 1000`` and a
``sort_corners_by_position`` helper. No adjustment: it reads 72161.5 on the real example.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
from competition_style import HEIGHT, WIDTH, answer, detect_markers, main, not_found

LOWER = np.array([88, 88, 88], dtype=np.uint8)
UPPER = np.array([192, 192, 192], dtype=np.uint8)
MIN_AREA = 1000


def sort_by_position(corners) -> list[np.ndarray]:
    """Marker corner arrays (4, 2) as top-left, top-right, bottom-left, bottom-right by centre."""
    centres = [c[0].mean(axis=0) for c in corners]
    by_y = np.argsort([c[1] for c in centres])
    top = sorted(by_y[:2], key=lambda i: centres[i][0])
    bottom = sorted(by_y[2:], key=lambda i: centres[i][0])
    return [corners[i][0] for i in (*top, *bottom)]


def detect(image_bgr: np.ndarray) -> dict:
    """Count obstacles and their total area (frame px) on a BGR image."""
    corners, ids = detect_markers(image_bgr)
    if len(corners) != 4:
        return not_found(ids)
    tl, tr, bl, br = sort_by_position(corners)
    src = np.float32([tl[0], tr[1], bl[3], br[2]])
    dst = np.float32([[0, 0], [WIDTH - 1, 0], [0, HEIGHT - 1], [WIDTH - 1, HEIGHT - 1]])
    warped = cv2.warpPerspective(image_bgr, cv2.getPerspectiveTransform(src, dst),
                                 (WIDTH, HEIGHT))
    mask = cv2.inRange(warped, LOWER, UPPER)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_TC89_KCOS)
    kept = [a for a in (cv2.contourArea(c) for c in contours) if a > MIN_AREA]
    return answer(len(kept), sum(kept), ids)


if __name__ == "__main__":
    sys.exit(main(detect))
