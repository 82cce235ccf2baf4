"""Competition style (h): the ArUco calls most public solutions made, ``cv2.aruco.detectMarkers``.

OpenCV 4.7 moved marker detection into ``cv2.aruco.ArucoDetector`` and kept the old free
function ``cv2.aruco.detectMarkers(image, dictionary, parameters=...)`` beside it; OpenCV 5
removed it. Most public e-Yantra 2024-25 Task 1C ``map.py`` solutions (written for the
competition's OpenCV 4.10) call the free function, so such a script runs under the
competition's OpenCV and crashes under OpenCV 5 (``AttributeError: module 'cv2.aruco' has no
attribute 'detectMarkers'``). Apart from the marker call this is ``style_blur127``.
"""

from __future__ import annotations

import sys

import cv2
import numpy as np
import style_blur127
from competition_style import main


def detect_markers(image_bgr: np.ndarray) -> tuple[tuple[np.ndarray, ...], list[int]]:
    """ArUco markers found with the free function of OpenCV 4.x (DICT_4X4_250, on grey)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_250)
    gray = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
    corners, ids, _ = cv2.aruco.detectMarkers(gray, dictionary,
                                              parameters=cv2.aruco.DetectorParameters())
    return tuple(corners), ([] if ids is None else [int(i) for i in ids.flatten()])


def detect(image_bgr: np.ndarray) -> dict:
    """``style_blur127.detect`` with the markers found by :func:`detect_markers`."""
    style_blur127.detect_markers = detect_markers
    return style_blur127.detect(image_bgr)


if __name__ == "__main__":
    sys.exit(main(detect))
