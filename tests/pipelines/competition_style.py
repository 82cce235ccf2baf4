"""What the five competition-style test pipelines (``style_*.py``) share: the competition's
command line and ``obstacles.txt`` format, and marker detection as teams wrote it.

Each ``style_*.py`` module has ``detect(image_bgr) -> {"count", "area", "marker_ids",
"status"}`` (for ``arenabench eval --pipeline style_x:detect`` with this folder on
``sys.path``) and runs as a competition command: ``python3 style_x.py --image PATH`` writes
``obstacles.txt`` into the working directory, exactly the competition's format::

    Aruco ID: [90, 95, 85, 80]
    Obstacles: 2
    Area: 72092.5

Marker ids are listed in the order ``cv2.aruco.ArucoDetector`` reports them (as teams wrote
``ids.flatten().tolist()``). Exit status 3 when the four markers are not found (the harness's
"markers not found"); ``obstacles.txt`` is then written with the ids found, 0 and 0.0.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

#: The competition arena's marker ids: north-west, north-east, south-east, south-west.
ARENA_IDS = (80, 85, 90, 95)
#: The rectified view teams warp to.
WIDTH = HEIGHT = 1000
#: Exit status for "markers not found" (the harness's convention).
EXIT_MARKERS_NOT_FOUND = 3


def detect_markers(image_bgr: np.ndarray) -> tuple[tuple[np.ndarray, ...], list[int]]:
    """ArUco markers as teams detect them: DICT_4X4_250, default parameters, on grey.

    Returns
    -------
    (corners, ids)
        ``corners[k]`` is a (1, 4, 2) array and ``ids[k]`` its id, in detection order.
    """
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_250), cv2.aruco.DetectorParameters()
    )
    gray = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
    corners, ids, _ = detector.detectMarkers(gray)
    return tuple(corners), ([] if ids is None else [int(i) for i in ids.flatten()])


def inner_corners_by_id(corners, ids) -> np.ndarray | None:
    """Corner k of the k-th arena marker by id (0 of 80, 1 of 85, 2 of 90, 3 of 95): on the
    competition arena (markers printed rotated 180 deg) these are the four inner corners.
    ``None`` unless all four ids were found."""
    by_id = {i: c[0] for c, i in zip(corners, ids, strict=True)}
    if not all(i in by_id for i in ARENA_IDS):
        return None
    return np.float32([by_id[i][k] for k, i in enumerate(ARENA_IDS)])



def warp_by_id(image_bgr: np.ndarray, corners, ids, *, size: int = WIDTH) -> np.ndarray | None:
    """The arena warped to ``size`` x ``size`` from :func:`inner_corners_by_id` (north-west
    corner to (0, 0), clockwise); ``None`` unless all four markers were found."""
    src = inner_corners_by_id(corners, ids)
    if src is None:
        return None
    dst = np.float32([[0, 0], [size, 0], [size, size], [0, size]])
    return cv2.warpPerspective(image_bgr, cv2.getPerspectiveTransform(src, dst), (size, size))

def answer(count: int, area: float, marker_ids: list[int]) -> dict[str, Any]:
    """The result dict ``detect`` returns."""
    return {"status": "ok", "count": int(count), "area": float(area),
            "marker_ids": list(marker_ids)}


def not_found(marker_ids: list[int]) -> dict[str, Any]:
    """The result when the four markers are not all found."""
    return {"status": "markers_not_found", "count": 0, "area": 0.0,
            "marker_ids": list(marker_ids)}


def write_obstacles(result: dict[str, Any], path: str = "obstacles.txt") -> None:
    """Write ``result`` in the competition's ``obstacles.txt`` format."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"Aruco ID: {list(result['marker_ids'])}\n")
        f.write(f"Obstacles: {result['count']}\n")
        f.write(f"Area: {result['area']}\n")


def main(detect: Callable[[np.ndarray], dict[str, Any]], argv: list[str] | None = None) -> int:
    """The competition command line: ``--image PATH``; writes ./obstacles.txt."""
    parser = argparse.ArgumentParser(description="Task 1C: count obstacles and their area.")
    parser.add_argument("--image", required=True, help="input image")
    args = parser.parse_args(argv)
    image = cv2.imread(args.image)
    if image is None:
        print(f"error: cannot read image {args.image}", file=sys.stderr)
        return 2
    result = detect(image)
    write_obstacles(result)
    return EXIT_MARKERS_NOT_FOUND if result["status"] != "ok" else 0
