"""The competition-style script of ``arenabench bench`` item 9 (a team's ``map.py``):
``python map_script.py --image PATH`` detects the four ArUco markers, warps the arena to
1000 x 1000, thresholds, counts the obstacles and writes ``obstacles.txt``. Numpy and OpenCV
only, as competition scripts are; exit status 3 when the markers are not all found.
"""

import argparse

import cv2
import numpy as np

ARENA_IDS = (80, 85, 90, 95)


def main() -> int:
    """Read ``--image``, write ``obstacles.txt``; 3 when the markers are not all found."""
    parser = argparse.ArgumentParser(description="Task 1C: count obstacles and their area.")
    parser.add_argument("--image", required=True)
    image = cv2.imread(parser.parse_args().image)
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_250), cv2.aruco.DetectorParameters()
    )
    corners, ids, _ = detector.detectMarkers(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
    found = [] if ids is None else [int(i) for i in ids.flatten()]
    by_id = {i: c[0] for c, i in zip(corners, found, strict=True)}
    count, area = 0, 0.0
    if all(i in by_id for i in ARENA_IDS):
        src = np.float32([by_id[i][k] for k, i in enumerate(ARENA_IDS)])
        dst = np.float32([[0, 0], [1000, 0], [1000, 1000], [0, 1000]])
        warped = cv2.warpPerspective(image, cv2.getPerspectiveTransform(src, dst), (1000, 1000))
        grey = cv2.GaussianBlur(cv2.cvtColor(warped, cv2.COLOR_BGR2GRAY), (5, 5), 0)
        _, mask = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        areas = [cv2.contourArea(c) for c in contours if cv2.contourArea(c) > 500]
        count, area = len(areas), float(sum(areas))
    with open("obstacles.txt", "w", encoding="utf-8") as fh:
        fh.write(f"Aruco ID: {found}\nObstacles: {count}\nArea: {area}\n")
    return 0 if all(i in by_id for i in ARENA_IDS) else 3


if __name__ == "__main__":
    raise SystemExit(main())
