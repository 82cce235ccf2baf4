"""Markers of every cv2.aruco predefined dictionary, printed at every quarter turn, render and
are found by the reference pipeline: the right dictionary and ids, each marker's corners in the
GT's order, and the count."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from clirun import run_cli
from marks import integration_but

from arenabench.aruco import aruco_dictionary
from arenabench.generator.dataset.make import make_sample
from arenabench.generator.model.scene import MarkerSpec
from arenabench.pipeline import detect
from arenabench.pipeline.config import ALL_DICTIONARIES

#: Largest distance (px) between a GT marker corner and the one cv2.aruco reports (whole-pixel
#: corners, no refinement: 1.3-2.4 px measured on 1000 px renders, printed or drawn markers).
CORNER_TOLERANCE_PX = 3.0

AVAILABLE = tuple(name for name in ALL_DICTIONARIES if hasattr(cv2.aruco, name))


def _ids(name: str) -> tuple[int, int, int, int]:
    """Four ids spread over the dictionary: two near its end, its first, its middle one (not
    the last: DICT_ARUCO_ORIGINAL's last, 1023, is refused, see below)."""
    size = aruco_dictionary(name).bytesList.shape[0]
    return (size - 2, size - 3, 0, size // 2)


def _check(renderer, preset: str, name: str, rotation: float, ids=None) -> None:
    overrides = {"markers.dictionary": name, "markers.ids": ids or _ids(name),
                 "markers.rotation_deg": rotation}
    sample = make_sample(preset, seed=1, index=0, overrides=overrides, renderer=renderer)
    found = detect(sample.bgr)
    where = (preset, name, rotation)
    assert found.status == "ok" and found.dictionary == name, (where, found.status,
                                                               found.dictionary)
    gt_markers = sample.gt["markers"]
    assert sorted(found.marker_ids) == sorted(m["id"] for m in gt_markers), where
    for m in gt_markers:
        error = np.abs(np.asarray(found.marker_corners[m["id"]], float)
                       - np.asarray(m["corners_px"], float)).max()
        assert error < CORNER_TOLERANCE_PX, (where, m["id"], error)
    assert found.count == sample.gt["count"], where


#: A sample: every family (4x4 .. 7x7, the original ArUco, AprilTag, ArUco MIP), every quarter
#: turn, on a drawn arena and on the competition's (its printed markers covered).
SAMPLE = [
    ("eyrc-jitter", "DICT_4X4_50", 0.0), ("eyrc", "DICT_5X5_100", 90.0),
    ("eyrc-jitter", "DICT_6X6_250", 270.0), ("eyrc", "DICT_7X7_1000", 180.0),
    ("eyrc-jitter", "DICT_ARUCO_ORIGINAL", -90.0), ("eyrc", "DICT_APRILTAG_16h5", 0.0),
    ("eyrc-jitter", "DICT_APRILTAG_25h9", 90.0), ("eyrc", "DICT_APRILTAG_36h10", 180.0),
    ("eyrc-jitter", "DICT_APRILTAG_36h11", 270.0), ("eyrc", "DICT_ARUCO_MIP_36h12", 0.0),
]


@pytest.mark.parametrize(("preset", "name", "rotation"), integration_but(SAMPLE, first=3))
def test_a_sample_of_dictionaries_and_turns_is_found_as_drawn(renderer, preset, name, rotation):
    if name not in AVAILABLE:
        pytest.skip(f"this OpenCV has no {name}")
    _check(renderer, preset, name, rotation)


@pytest.mark.integration
@pytest.mark.parametrize("name", AVAILABLE)
def test_every_dictionary_at_every_turn_is_found_as_drawn(renderer, name):
    for rotation in (0.0, 90.0, 180.0, 270.0):
        _check(renderer, "eyrc", name, rotation)


def test_a_marker_that_looks_the_same_turned_is_refused_in_one_line(tmp_path):
    """DICT_ARUCO_ORIGINAL's id 1023 is the one predefined marker that looks the same turned
    half a turn (measured over every dictionary): no detector can tell which of its corners is
    the first, so at 180 deg cv2.aruco reported its corners 51.7 px from the GT's, in the
    other order. Such an id is refused before any work, naming the id and the dictionary."""
    with pytest.raises(ValueError, match=r"id 1023 of DICT_ARUCO_ORIGINAL looks the same"):
        MarkerSpec(dictionary="DICT_ARUCO_ORIGINAL", ids=(1023, 1, 2, 3))
    out = tmp_path / "set"
    proc = run_cli("generate", "--preset", "eyrc-jitter", "--count", "1", "--out", str(out),
                   "--no-progress", "--set", "markers.dictionary=DICT_ARUCO_ORIGINAL",
                   "--set", "markers.ids=1023,1,2,3")
    assert proc.returncode == 2 and not out.exists()
    assert len(proc.stderr.strip().splitlines()) == 1 and "1023" in proc.stderr
