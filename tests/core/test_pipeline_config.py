"""DetectConfig: profiles, validation naming the field, serialisation; dictionary search."""

import cv2
import numpy as np
import pytest

from arenabench.frame import FrameSpec
from arenabench.pipeline import (
    ALL_DICTIONARIES,
    PUBLISHED_DICTIONARIES,
    DetectConfig,
    detect,
)
from arenabench.pipeline.markers import plan_stages, search_markers


def test_profiles_and_defaults():
    ref = DetectConfig()
    assert ref.profile == "reference"
    assert (ref.resize, ref.threshold, ref.min_area) == (1000, 70, 500.0)
    assert ref.uses_fallback and ref.dictionary_order == ALL_DICTIONARIES
    seed = DetectConfig.for_profile("seed")
    assert seed == DetectConfig(profile="seed")
    assert not seed.uses_fallback and seed.dictionary_order == PUBLISHED_DICTIONARIES
    assert len(PUBLISHED_DICTIONARIES) == 21
    assert DetectConfig.for_profile("seed", threshold=60).threshold == 60
    assert ref.with_(min_area=10.0).min_area == 10.0
    d = ref.to_dict()
    assert d["frame"] == {"size": 1000, "corners": "inner"} and d["profile"] == "reference"


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"profile": "fast"}, "profile"),
        ({"resize": 0}, "resize"),
        ({"resize": 10.5}, "resize"),
        ({"threshold": 256}, "threshold"),
        ({"threshold": True}, "threshold"),
        ({"min_area": -1}, "min_area"),
        ({"min_area": "big"}, "min_area"),
        ({"dictionaries": "DICT_4X4_50"}, "dictionaries"),
        ({"dictionaries": ()}, "dictionaries"),
        ({"frame": (1000, "inner")}, "frame"),
        ({"profile": "seed", "frame": FrameSpec(corners="outer")}, "frame.corners"),
        ({"obstacle_threshold": 0}, "obstacle_threshold"),
        ({"min_contrast": 0}, "min_contrast"),
        ({"marker_margin_px": -2}, "marker_margin_px"),
        ({"border_margin_px": -1}, "border_margin_px"),
        ({"open_px": 500}, "open_px"),
        ({"area_method": "hull"}, "area_method"),
        ({"marker_fallback": "yes"}, "marker_fallback"),
    ],
)
def test_bad_values_raise_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        DetectConfig(**kwargs)


def test_positional_arguments_are_refused():
    with pytest.raises(TypeError):
        DetectConfig("seed")  # type: ignore[misc]


def test_unknown_dictionary_is_a_value_error():
    img = np.full((100, 100, 3), 255, np.uint8)
    with pytest.raises(ValueError, match="DICT_9X9_1"):
        detect(img, DetectConfig(dictionaries=("DICT_9X9_1",)))


def test_stages_keep_published_order_and_start_small():
    stages = plan_stages(PUBLISHED_DICTIONARIES)
    flat = [n for stage in stages for n in stage]
    assert flat == list(PUBLISHED_DICTIONARIES)
    if hasattr(cv2.aruco.ArucoDetector, "detectMarkersMultiDict"):
        assert stages[0] == ("DICT_4X4_50", "DICT_4X4_100")
        assert len(stages) < len(PUBLISHED_DICTIONARIES)


def test_search_returns_first_dictionary_in_order():
    # ids 3, 7, 12, 20 of DICT_4X4_50 are also ids 3, 7, 12, 20 of DICT_4X4_100 (nested):
    # the first dictionary in order wins, as in the published loop.
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    img = np.full((400, 400), 255, np.uint8)
    for k, mid in enumerate((3, 7, 12, 20)):
        x, y = 40 + 200 * (k % 2), 40 + 200 * (k // 2)
        img[y : y + 120, x : x + 120] = cv2.aruco.generateImageMarker(d, mid, 120)
    for rule in ("seed", "reference"):
        res = search_markers(img, PUBLISHED_DICTIONARIES, rule=rule, source="gray")
        assert res.found and res.dictionary == "DICT_4X4_50" and res.ids == [3, 7, 12, 20]
        assert res.passes == 1
