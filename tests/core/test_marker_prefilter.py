"""No marker, no wait: a marker search of a grey (or a busy thresholded) image is
skipped when the adaptive threshold shows no dark square next to a light one
(src/arenabench/pipeline/marker_prefilter.py).

Wherever the check passes, the search runs as without it, so the tests assert both: the check
passes on every image with markers, and ``detect`` gives byte-identical results with it on and
off (default configuration, and the grey-only one where the check runs first)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from marks import integration_but
from paths import TESTS

from arenabench.aruco import aruco_dictionary
from arenabench.eval.bench.items import markerless_images
from arenabench.pipeline import DetectConfig, marker_prefilter
from arenabench.pipeline.detection import detect

EXAMPLE = TESTS / "data" / "task1c_image.jpg"
CONFIGS = (DetectConfig(), DetectConfig(threshold=None))


def _result(image: np.ndarray, config: DetectConfig) -> str:
    """``detect``'s JSON without timings and pass counts (they differ by design)."""
    d = detect(image, config).to_dict()
    d.pop("timings_ms")
    d["details"] = {k: v for k, v in d["details"].items() if k != "marker_passes"}
    return json.dumps(d, sort_keys=True)


def _assert_same_either_way(image: np.ndarray, monkeypatch, label: str) -> list[str]:
    gray = cv2.cvtColor(cv2.resize(image, (1000, 1000)), cv2.COLOR_BGR2GRAY)
    assert marker_prefilter.could_hold_marker(gray), f"{label}: the check would skip it"
    binary = cv2.threshold(gray, 70, 255, cv2.THRESH_BINARY)[1]
    if marker_prefilter.worth_checking(binary, source="threshold"):
        assert marker_prefilter.could_hold_marker(binary), f"{label}: thresholded, skipped"
    fast = [_result(image, c) for c in CONFIGS]
    monkeypatch.setattr(marker_prefilter, "PREFILTER", False)
    full = [_result(image, c) for c in CONFIGS]
    monkeypatch.setattr(marker_prefilter, "PREFILTER", True)
    assert fast == full, label
    return fast


def _noisy(image: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    noise = np.random.default_rng(seed).normal(0.0, sigma, image.shape)
    return np.clip(image.astype(np.float64) + noise, 0, 255).astype(np.uint8)


def _sheet(name: str, ids: list[int], side: int, angle: float) -> np.ndarray:
    """1000 x 1000 white sheet with markers ``ids`` of ``side`` px, turned ``angle`` degrees
    (drawn 4x larger and shrunk with area averaging, as a camera would see them)."""
    d = aruco_dictionary(name)
    img = np.full((1000, 1000), 255, np.uint8)
    for k, mid in enumerate(ids):
        tile = np.full((side * 8, side * 8), 255, np.uint8)
        tile[side * 2 : side * 6, side * 2 : side * 6] = cv2.aruco.generateImageMarker(
            d, int(mid), side * 4)
        rot = cv2.getRotationMatrix2D((side * 4, side * 4), angle, 1.0)
        big = cv2.warpAffine(tile, rot, (side * 8, side * 8), borderValue=255)
        small = cv2.resize(big, (side * 2, side * 2), interpolation=cv2.INTER_AREA)
        x, y = 150 + 300 * k, 200 + 250 * (k % 2)
        img[y : y + side * 2, x : x + side * 2] = small
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)


def test_noise_is_skipped_without_a_pass():
    for seed in range(4):
        image = markerless_images(seed)["noise"]
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        binary = cv2.threshold(gray, 70, 255, cv2.THRESH_BINARY)[1]
        assert marker_prefilter.worth_checking(binary, source="threshold")  # busy
        assert not marker_prefilter.could_hold_marker(gray)
        assert not marker_prefilter.could_hold_marker(binary)
        result = detect(image)
        assert result.status == "markers_not_found" and result.marker_ids == []
        assert result.details["marker_passes"] == 0


@pytest.mark.integration
def test_blank_and_boxes_keep_their_results(monkeypatch):
    images = markerless_images(3)
    _assert_same_either_way(images["boxes"], monkeypatch, "boxes")
    blank = images["blank"]
    assert not marker_prefilter.could_hold_marker(blank[:, :, 0])
    fast = [_result(blank, c) for c in CONFIGS]
    monkeypatch.setattr(marker_prefilter, "PREFILTER", False)
    assert fast == [_result(blank, c) for c in CONFIGS]


@pytest.mark.parametrize("sigma", integration_but([0.0, 6.0, 15.0, 25.0, 40.0,
                                            pytest.param(80.0, marks=pytest.mark.integration)],
                                           0.0, 15.0))
def test_the_example_at_every_noise_level(sigma, monkeypatch):
    image = cv2.imread(str(EXAMPLE))
    image = _noisy(image, sigma, 7) if sigma else image
    fast = _assert_same_either_way(image, monkeypatch, f"sigma {sigma}")
    if sigma <= 40.0:
        assert '"status": "ok"' in fast[0]


@pytest.mark.integration
@pytest.mark.parametrize("name", ["DICT_4X4_100", "DICT_5X5_250", "DICT_7X7_50",
                                  "DICT_APRILTAG_36h11"])
def test_sheets_of_one_to_three_markers(name, monkeypatch):
    found = 0
    for side in (16, 24, 48, 96):
        for angle in (0.0, 30.0, 45.0):
            ids = [3, 17, 40][: 1 + (side + int(angle)) % 3]
            for noisy in (False, True):
                image = _sheet(name, ids, side, angle)
                image = _noisy(image, 10.0, side) if noisy else image
                fast = _assert_same_either_way(image, monkeypatch,
                                               f"{name} {ids} {side} px {angle} deg")
                found += json.loads(fast[1])["marker_ids"] != []
    # read where OpenCV can (not the smallest), and where the search goes past its first stage
    # (one with fewer than four candidates ends it: src/arenabench/pipeline/markers.py)
    assert found >= 2


@pytest.mark.parametrize("side", [24, 48, 96])
@pytest.mark.integration
def test_a_marker_pasted_on_noise(side, monkeypatch):
    image = np.random.default_rng(side).integers(0, 256, (1000, 1000), dtype=np.uint8)
    q = side // 2
    image[300 - q : 300 + side + q, 300 - q : 300 + side + q] = 255
    image[300 : 300 + side, 300 : 300 + side] = cv2.aruco.generateImageMarker(
        aruco_dictionary("DICT_4X4_100"), 80, side)
    fast = _assert_same_either_way(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), monkeypatch,
                                   f"{side} px")
    assert '"marker_ids": [80]' in fast[0]


@pytest.mark.acceptance  # every preset's scenes rendered and detected twice: minutes
def test_every_preset_gives_the_same_results(tmp_path, monkeypatch):
    from arenabench.generator.commands.generate import main as generate_main
    from arenabench.generator.parameters.presets import preset_names

    for k, preset in enumerate(preset_names()):
        data = tmp_path / preset
        assert generate_main(["--preset", preset, "--count", "24", "--seed", str(31 + k),
                              "--out", str(data), "--no-progress", "--workers", "2"]) == 0
        for path in sorted((data / "images").iterdir()):
            image = cv2.imread(str(path))
            for variant, label in ((image, ""), (_noisy(image, 25.0, k), " sigma 25")):
                _assert_same_either_way(variant, monkeypatch, f"{preset} {path.name}{label}")


def test_the_seed_profile_searches_as_published():
    result = detect(markerless_images(0)["noise"], DetectConfig(profile="seed"))
    assert result.details["marker_passes"] >= 1  # not skipped
