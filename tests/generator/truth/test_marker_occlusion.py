"""Ground truth sees a marker that a box covers: the floor a box hides from the
camera (its vertices projected onto the floor) counts in each marker's ``occluded_fraction``,
as floor patches do; a real render and a real ArUco detector agree."""

from __future__ import annotations

import json
from dataclasses import replace

import cv2
import numpy as np
import pytest
from clirun import run_cli

from arenabench.generator.model.layout import marker_square
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.model.scene import Obstacle
from arenabench.generator.truth.groundtruth import compute_ground_truth

CORNERS = ("nw", "ne", "se", "sw")


def _scene_with_boxes(boxes):
    """eyrc scene 0 of seed 7 with ``boxes`` in place of its own: (corner, fraction, height m)
    each: a box over the whole marker (fraction 1), or one that covers that fraction of the
    marker's width from its inner side and reaches 0.2 m towards the arena's middle."""
    scene = sample_scene("eyrc", seed=7, index=0).scene
    obstacles = []
    for corner, fraction, height in boxes:
        x0, x1, y0, y1 = marker_square(scene.arena, scene.markers, corner)
        side = x1 - x0
        if fraction >= 1:
            xa, xb = x0 - 0.15 * side, x1 + 0.15 * side
        elif corner in ("nw", "sw"):  # the inner side is the east one
            xa, xb = x1 - fraction * side, x1 + 0.2
        else:
            xa, xb = x0 - 0.2, x0 + fraction * side
        obstacles.append(Obstacle(center_m=((xa + xb) / 2, (y0 + y1) / 2), yaw_deg=0.0,
                                  length_m=xb - xa, width_m=side * 1.3, height_m=height,
                                  color_rgb=(200, 120, 40)))
    return replace(scene, obstacles=tuple(obstacles))


def test_a_box_over_a_marker_hides_it_in_the_ground_truth():
    scene = _scene_with_boxes([(c, 1.0, 0.25) for c in CORNERS])
    gt = compute_ground_truth(scene)
    for m in gt["markers"]:
        assert m["occluded_fraction"] == pytest.approx(1.0) and m["visible"] is False
    clear = compute_ground_truth(_scene_with_boxes([]))
    assert all(m["occluded_fraction"] == 0.0 and m["visible"] for m in clear["markers"])


def test_a_tall_box_beside_a_marker_hides_what_its_side_leans_over():
    # a box that covers the inner half of a marker's footprint hides more of it than half
    # (its sides lean outwards in the image, away from the camera's nadir)
    half = compute_ground_truth(_scene_with_boxes([("ne", 0.5, 0.001)]))["markers"][1]
    tall = compute_ground_truth(_scene_with_boxes([("ne", 0.5, 0.6)]))["markers"][1]
    assert half["occluded_fraction"] == pytest.approx(0.5, abs=0.01)
    assert tall["occluded_fraction"] > half["occluded_fraction"] + 0.05
    assert not half["visible"] and not tall["visible"]


@pytest.mark.integration
def test_render_of_boxes_over_the_markers_records_what_a_detector_sees(tmp_path):
    scene = _scene_with_boxes([("nw", 1.0, 0.25), ("se", 1.0, 0.25)])
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene.to_dict()))
    r = run_cli("render", str(path), "--out", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr
    gt = json.loads((tmp_path / "out" / "gt" / "000000.json").read_text())
    image = cv2.imread(str(next((tmp_path / "out" / "images").iterdir())), cv2.IMREAD_GRAYSCALE)
    dictionary = cv2.aruco.getPredefinedDictionary(
        getattr(cv2.aruco, gt["markers"][0]["dictionary"]))
    _, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(image)
    found = set() if ids is None else {int(i) for i in np.ravel(ids)}
    visible = {m["id"] for m in gt["markers"] if m["visible"]}
    assert found == visible and len(visible) == 2
    assert {m["corner"] for m in gt["markers"] if not m["visible"]} == {"nw", "se"}
