"""The eyrc preset's distribution contains the fitted competition example."""

import json
import math
from pathlib import Path

import pytest

from arenabench.generator.presets import PRESETS

SCENE = Path(__file__).resolve().parents[1] / "generator" / "scenes" / "task1c_example.json"


def _inside(value, spec):
    lo, hi = spec if isinstance(spec, tuple) else (spec, spec)
    return lo <= value <= hi


@pytest.fixture(scope="module")
def example():
    return json.loads(SCENE.read_text())


def test_example_camera_lighting_and_markers_are_in_range(example):
    eyrc = PRESETS["eyrc"][1]
    cam = example["camera"]
    eye, at = cam["eye_m"], cam["look_at_m"]
    horizontal = math.hypot(at[0] - eye[0], at[1] - eye[1])
    tilt = math.degrees(math.atan2(horizontal, eye[2] - at[2]))
    light = example["lighting"]["directional"][0]
    elevation = math.degrees(math.asin(-light["direction"][2]))
    checks = {
        "camera.altitude_m": eye[2],
        "camera.fov_deg": cam["fov_deg"],
        "camera.tilt_deg": tilt,
        "camera.roll_deg": cam["roll_deg"],
        "camera.target_y_m": at[1],
        "markers.side_m": example["markers"]["side_m"],
        "lighting.ambient": example["lighting"]["ambient"],
        "lighting.intensity": light["intensity"],
        "lighting.elevation_deg": elevation,
        "background.gray": example["background_rgb"][0],
    }
    outside = {k: (v, eyrc[k]) for k, v in checks.items() if not _inside(v, eyrc[k])}
    assert not outside, outside
    assert example["markers"]["ids"] == list(eyrc["markers.ids"])
    assert example["markers"]["rotation_deg"] == eyrc["markers.rotation_deg"]


def test_example_boxes_are_in_range(example):
    eyrc = PRESETS["eyrc"][1]
    assert _inside(len(example["obstacles"]), eyrc["obstacles.count"])
    for box in example["obstacles"]:
        for field, key in (("length_m", "obstacles.length_m"), ("width_m", "obstacles.width_m"),
                           ("height_m", "obstacles.height_m"), ("yaw_deg", "obstacles.yaw_deg")):
            assert _inside(box[field], eyrc[key]), (field, box[field], eyrc[key])
        assert _inside(box["color_rgb"][0], eyrc["obstacles.gray"])
