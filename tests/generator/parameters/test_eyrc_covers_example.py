"""The eyrc preset is the twin of the fitted competition example: same camera, light, colours
and arena; only the boxes vary, axis-aligned, with the example's boxes inside the ranges."""

import json
import math

import cv2
import pytest
from paths import ROOT, TESTS

from arenabench.generator import Renderer, make_sample
from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.parameters.params import Range
from arenabench.generator.parameters.presets import PRESETS

SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"
IMAGE = TESTS / "data" / "task1c_image.jpg"


def _inside(value, spec):
    lo, hi = (spec.lo, spec.hi) if isinstance(spec, Range) else (spec, spec)
    return lo - 1e-9 <= value <= hi + 1e-9


@pytest.fixture(scope="module")
def example():
    return json.loads(SCENE.read_text())


def _detected_order(gray) -> list[int]:
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_100),
        cv2.aruco.DetectorParameters())
    _, ids, _ = detector.detectMarkers(gray)
    return [int(i) for i in ids.ravel()]


def test_twin_holds_the_example_camera_light_and_arena_fixed(example):
    eyrc = PRESETS["eyrc"][1]
    cam = example["camera"]
    light = example["lighting"]["directional"][0]
    d = light["direction"]
    fixed = {
        "camera.altitude_m": cam["altitude_m"], "camera.fov_deg": cam["fov_deg"],
        "camera.tilt_deg": cam["tilt_deg"], "camera.yaw_deg": cam["yaw_deg"],
        "camera.roll_deg": cam["roll_deg"], "camera.target_x_m": cam["target_m"][0],
        "camera.target_y_m": cam["target_m"][1],
        "lighting.ambient": example["lighting"]["ambient"],
        "lighting.intensity": light["intensity"],
        "lighting.elevation_deg": math.degrees(math.asin(-d[2])),
        "background.gray": example["background_rgb"][0],
        "markers.side_m": example["markers"]["side_m"],
        "arena.side_m": example["arena"]["side_m"],
        "arena.margin_m": example["arena"]["margin_m"],
    }
    for key, value in fixed.items():
        assert not isinstance(eyrc[key], Range), key
        assert eyrc[key] == pytest.approx(value, abs=1e-5), key
    assert eyrc["arena.texture"] == example["arena"]["texture"] == comp.TEXTURE_NAME
    assert example["markers"]["ids"] == list(eyrc["markers.ids"])
    assert example["markers"]["rotation_deg"] == eyrc["markers.rotation_deg"]


def test_example_boxes_are_in_the_twin_ranges(example):
    eyrc = PRESETS["eyrc"][1]
    assert _inside(len(example["obstacles"]), eyrc["obstacles.count"])
    assert eyrc["obstacles.yaw_step_deg"] == 90.0
    for box in example["obstacles"]:
        for field, key in (("length_m", "obstacles.length_m"), ("width_m", "obstacles.width_m"),
                           ("height_m", "obstacles.height_m")):
            assert _inside(box[field], eyrc[key]), (field, box[field], eyrc[key])
        assert abs(box["yaw_deg"]) < 0.5  # axis-aligned in the example too
        assert _inside(box["color_rgb"][0], eyrc["obstacles.gray"])


def test_example_boxes_keep_the_twins_edge_margin(example):
    """The twin's margin to the markers' inner square admits the example's boxes (box 2 stands
    0.168 m from it)."""
    eyrc = PRESETS["eyrc"][1]
    inner = example["arena"]["side_m"] / 2 - example["markers"]["side_m"]
    margins = []
    for box in example["obstacles"]:
        hx, hy = box["length_m"] / 2, box["width_m"] / 2  # axis-aligned, yaw ~0
        (x, y) = box["center_m"]
        margins.append(min(inner - abs(x) - hx, inner - abs(y) - hy))
    assert min(margins) == pytest.approx(0.1684, abs=5e-4)
    assert eyrc["obstacles.edge_margin_m"] <= min(margins)


@pytest.mark.integration
def test_twin_box_images_stay_inside_the_marker_frame():
    """Like the example's (closest 22.3 px), every twin box's image, leaning top included,
    lies inside the frame: no box is cut by the warp's border (Canny-style loops stay closed).
    """
    from arenabench.generator.model.sampler import sample_scene
    from arenabench.generator.truth.groundtruth import compute_ground_truth

    example_gt = compute_ground_truth(_example_scene())
    assert _frame_clearance(example_gt) == pytest.approx(22.3, abs=0.1)
    for index in range(200):
        gt = compute_ground_truth(sample_scene("eyrc", seed=0, index=index).scene)
        assert _frame_clearance(gt) > 2.0, index


def _example_scene():
    from arenabench.generator.model.scene import load_scene

    return load_scene(SCENE)


def _frame_clearance(gt) -> float:
    """Smallest distance (frame px) from any box's visible outline to the 1000 px frame edge."""
    pts = [p for o in gt["obstacles"] for p in o["visible_frame_px"]]
    return min(min(x, y, 1000 - x, 1000 - y) for x, y in pts)


@pytest.mark.integration
def test_twin_scenes_keep_the_real_images_marker_order():
    """cv2.aruco sorts markers by outline length: every twin scene must give the real order."""
    real = _detected_order(cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE))
    assert real == [90, 95, 85, 80]
    yaws = set()
    with Renderer() as renderer:
        for index in range(200):
            s = make_sample("eyrc", seed=0, index=index, renderer=renderer)
            assert _detected_order(cv2.cvtColor(s.bgr, cv2.COLOR_BGR2GRAY)) == real, index
            yaws.update(round(o["yaw_deg"], 6) for o in s.gt["obstacles"])
    assert yaws == {0.0, 90.0}
