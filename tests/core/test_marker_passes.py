"""Marker search savings: nested dictionaries share a pass; too few candidates end the search.

Both must leave the search's result unchanged: the first dictionary in order that yields the
markers, with the same ids and corners as one pass per dictionary gives.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from marks import integration_but

from arenabench.aruco import aruco_dictionary
from arenabench.pipeline import ALL_DICTIONARIES, PUBLISHED_DICTIONARIES
from arenabench.pipeline.markers import (
    available_dictionaries,
    correction_bits,
    extends,
    pass_plan,
    plan_stages,
    search_markers,
)

NAMES = available_dictionaries(ALL_DICTIONARIES, strict=False)
MULTI = hasattr(cv2.aruco.ArucoDetector, "detectMarkersMultiDict")


def _sheet(name: str, ids, *, size: int = 520, side: int = 150) -> np.ndarray:
    d = aruco_dictionary(name)
    img = np.full((size, size), 255, np.uint8)
    for k, mid in enumerate(ids):
        x, y = 40 + 260 * (k % 2), 40 + 260 * (k // 2)
        img[y : y + side, x : x + side] = cv2.aruco.generateImageMarker(d, int(mid), side)
    return img


def _one_pass_per_dictionary(image: np.ndarray, rule: str):
    """The published loop: one detectMarkers per dictionary, first that satisfies the rule."""
    from arenabench.pipeline.markers import (
        DictionaryHits,
        select_reference_four,
        select_seed_four,
    )

    select = select_seed_four if rule == "seed" else select_reference_four
    for name in NAMES:
        det = cv2.aruco.ArucoDetector(aruco_dictionary(name), cv2.aruco.DetectorParameters())
        corners, ids, _ = det.detectMarkers(image)
        hits = DictionaryHits(name)
        for c, i in zip(corners, [] if ids is None else ids.ravel(), strict=True):
            hits.ids.append(int(i))
            hits.corners.append(np.asarray(c, np.float64).reshape(4, 2))
        chosen = select(hits)
        if chosen is not None:
            return name, chosen[0], chosen[1]
    return None, [], []


def test_nesting_and_correction_decide_what_shares_a_pass():
    assert extends("DICT_4X4_100", "DICT_4X4_50")
    assert extends("DICT_5X5_1000", "DICT_5X5_50")
    # DICT_6X6_1000 corrects fewer bits than DICT_6X6_250: one pass would miss markers
    assert correction_bits("DICT_6X6_1000") < correction_bits("DICT_6X6_250")
    assert not extends("DICT_6X6_1000", "DICT_6X6_250")
    assert not extends("DICT_5X5_1000", "DICT_4X4_50")  # other marker size
    assert pass_plan(("DICT_4X4_50", "DICT_4X4_100")) == [
        ("DICT_4X4_100", ("DICT_4X4_50", "DICT_4X4_100"))]


def test_stages_cover_every_dictionary_in_order_and_start_with_the_competition():
    for names in (PUBLISHED_DICTIONARIES, NAMES):
        stages = plan_stages(names)
        assert [n for s in stages for n in s] == list(names)
        logical = [n for s in stages for _, group in pass_plan(s) for n in group]
        assert logical == list(names)
    if MULTI:
        assert [run for run, _ in pass_plan(plan_stages(NAMES)[0])] == ["DICT_4X4_100"]


@pytest.mark.parametrize("name, ids", integration_but([
    ("DICT_4X4_50", (3, 7, 12, 20)),
    ("DICT_4X4_100", (80, 85, 90, 95)),
    ("DICT_4X4_250", (10, 120, 200, 249)),
    ("DICT_5X5_250", (1, 60, 130, 240)),
    ("DICT_7X7_100", (5, 55, 70, 99)),
    ("DICT_6X6_1000", (300, 500, 700, 999)),
], first=3))
@pytest.mark.parametrize("rule", integration_but(["reference", "seed"], "reference"))
def test_same_result_as_one_pass_per_dictionary(name, ids, rule):
    img = _sheet(name, ids)
    img = cv2.GaussianBlur(img, (3, 3), 0.8)
    want = _one_pass_per_dictionary(img, rule)
    got = search_markers(img, NAMES, rule=rule, source="gray")
    assert got.found and got.dictionary == want[0] and got.ids == want[1]
    for a, b in zip(got.corners, want[2], strict=True):
        assert np.allclose(a, b)


def test_three_markers_search_every_stage_and_report_what_was_found():
    img = _sheet("DICT_4X4_100", (80, 85, 90))
    res = search_markers(img, NAMES, rule="reference", source="gray")
    assert not res.found
    assert res.ids == [80, 85, 90] and res.dictionary == "DICT_4X4_100"  # first with most
    assert res.passes == len(plan_stages(NAMES))


@pytest.mark.parametrize("image", [
    np.full((400, 400), 230, np.uint8),
    np.random.default_rng(0).integers(0, 256, (400, 400), dtype=np.uint8),
])
def test_too_few_candidates_stop_after_one_pass(image):
    res = search_markers(image, NAMES, rule="reference", source="gray")
    assert not res.found and res.ids == [] and res.passes == 1
