"""A competition-style pipeline with a minimum box area set too high, which saves its warp.

The method of ``style_blur127.py`` (corners by id, warp to 1000 x 1000, 3 x 3 blur, threshold
127, ``RETR_TREE``), but contours under :data:`MIN_AREA` frame px are dropped: a threshold
tuned on a few images with big boxes, so the smaller boxes of some scenes go uncounted
(``wrong_count``, a box short). What separates its failures from its passes is the smallest
box's visible area (``gt.min_box_visible_px``), not the look of the scene.

Run as a command it also writes the warped arena to ``transformed_image.png`` in its working
directory, as many public solutions do.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
from competition_style import WIDTH, answer, detect_markers, main, not_found, warp_by_id
from style_blur127 import BLUR, MAX_AREA, THRESHOLD

#: Smallest contour area counted (frame px): about the median box of the ``eyrc`` preset.
MIN_AREA = 26000
#: Where the warp is saved (in the working directory) when run as a command.
WARP_FILE = "transformed_image.png"


def detect(image_bgr: np.ndarray, *, save: bool = False) -> dict:
    """Count obstacles of at least :data:`MIN_AREA` px and their total area (frame px)."""
    corners, ids = detect_markers(image_bgr)
    warped = warp_by_id(image_bgr, corners, ids, size=WIDTH)
    if warped is None:
        return not_found(ids)
    if save:
        cv2.imwrite(WARP_FILE, warped)
    gray = cv2.cvtColor(warped, cv2.COLOR_BGR2GRAY)
    _, binary = cv2.threshold(cv2.GaussianBlur(gray, BLUR, 0), THRESHOLD, 255,
                              cv2.THRESH_BINARY)
    contours, _ = cv2.findContours(binary, cv2.RETR_TREE, cv2.CHAIN_APPROX_SIMPLE)
    kept = [a for a in (cv2.contourArea(c) for c in contours) if MIN_AREA < a < MAX_AREA]
    return answer(len(kept), sum(kept), ids)


if __name__ == "__main__":
    sys.exit(main(lambda image: detect(image, save=True)))
