"""No marker, no wait: a marker search ends once no candidate can be identified by a later
dictionary (src/arenabench/pipeline/markers.py, "Uniform candidates end the search"), with the
same result as the search over every stage wherever markers are present (and where not)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from paths import TESTS

from arenabench.pipeline import marker_prefilter, markers
from arenabench.pipeline.detection import detect

EXAMPLE = TESTS / "data" / "task1c_image.jpg"


def _boxes(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.full((1000, 1000, 3), 200, np.uint8)
    for _ in range(12):
        x, y = (int(v) for v in rng.integers(50, 880, 2))
        cv2.rectangle(img, (x, y), (x + 60, y + 80), (40, 40, 40), -1)
    return img


def _both(image: np.ndarray, monkeypatch) -> tuple[dict, dict, int, int]:
    """detect() with the shortcuts and without them (this one and the grey-image pre-check of
    tests/core/test_marker_prefilter.py): results (timings and passes left out), and the passes."""
    fast = detect(image)
    monkeypatch.setattr(markers, "UNIFORM_SHORTCUT", False)
    monkeypatch.setattr(marker_prefilter, "PREFILTER", False)
    full = detect(image)
    monkeypatch.setattr(markers, "UNIFORM_SHORTCUT", True)
    monkeypatch.setattr(marker_prefilter, "PREFILTER", True)
    out = []
    for d in (fast, full):
        r = {k: v for k, v in d.to_dict().items() if k != "timings_ms"}
        r["details"] = dict(r["details"])
        out.append((r, r["details"].pop("marker_passes")))
    return out[0][0], out[1][0], out[0][1], out[1][1]


def _noisy(image: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    noise = np.random.default_rng(seed).normal(0.0, sigma, image.shape)
    return np.clip(image.astype(np.float64) + noise, 0, 255).astype(np.uint8)


@pytest.mark.integration
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_image_of_only_boxes_ends_after_one_pass_per_source(seed, monkeypatch):
    fast, full, passes_fast, passes_full = _both(_boxes(seed), monkeypatch)
    assert fast == full and fast["status"] == "markers_not_found"
    assert passes_fast == 2 and passes_full > 10  # thresholded + grey, against every stage


@pytest.mark.parametrize("sigma", [0.0, 2.0, 6.0, 15.0])
def test_the_example_gives_the_same_result(sigma, monkeypatch):
    image = cv2.imread(str(EXAMPLE))
    fast, full, _, _ = _both(_noisy(image, sigma, 7) if sigma else image, monkeypatch)
    assert fast == full
    if sigma <= 6.0:
        assert fast["status"] == "ok"


@pytest.mark.integration
def test_markers_covered_by_a_box_still_searched(monkeypatch):
    image = cv2.imread(str(EXAMPLE))
    covered = image.copy()
    h, w = covered.shape[:2]
    cv2.rectangle(covered, (0, 0), (w // 2, h // 2), (40, 40, 40), -1)  # hides one marker
    fast, full, _, _ = _both(covered, monkeypatch)
    assert fast == full and fast["status"] == "markers_not_found"


@pytest.mark.integration
def test_twin_scenes_give_the_same_result(tmp_path, monkeypatch):
    from arenabench.generator.commands.generate import main as generate_main

    data = tmp_path / "eyrc"
    assert generate_main(["--preset", "eyrc", "--count", "24", "--seed", "5", "--out",
                          str(data), "--no-progress", "--workers", "2"]) == 0
    for k, path in enumerate(sorted((data / "images").iterdir())):
        image = cv2.imread(str(path))
        for variant in (image, _noisy(image, 6.0, k), _noisy(image, 25.0, k)):
            fast, full, _, _ = _both(variant, monkeypatch)
            assert fast == full, path.name
