"""Derived facts of a scene (generator/truth/scene_facts.py) against hand-built scenes."""

from __future__ import annotations

import pytest

from arenabench.generator.dataset.make import ground_truth_record
from arenabench.generator.model.scene import ArenaSpec, CameraSpec, MarkerSpec, Obstacle, Scene
from arenabench.generator.truth.scene_facts import FACTS, derived_facts

# 8 m arena, 0.48 m markers: the inner-corner frame spans x, y in [-3.52, 3.52] m.
HALF = 3.52
PX_PER_M = 1000.0 / (2 * HALF)
ALTITUDE = 8.7


def _scene(*obstacles: Obstacle) -> Scene:
    return Scene(arena=ArenaSpec(), markers=MarkerSpec(),
                 camera=CameraSpec(altitude_m=ALTITUDE), obstacles=obstacles)


def _box(x: float, y: float, length: float, width: float, height: float = 0.001) -> Obstacle:
    return Obstacle(center_m=(x, y), yaw_deg=0.0, length_m=length, width_m=width,
                    height_m=height)


def test_aspect_touching_and_edge_distance_of_flat_boxes():
    facts = derived_facts(_scene(
        _box(0.0, 0.0, 0.4, 0.1),        # aspect 4
        _box(0.25, 0.0, 0.1, 0.1),       # its left side is the first box's right side
        _box(HALF - 0.15, 1.0, 0.1, 0.1),  # right side 0.1 m from the frame's edge
        _box(3.9, -1.0, 0.2, 0.02),      # in the margin, outside the frame: ignored
    ))
    assert facts["derived.max_aspect_ratio"] == pytest.approx(4.0)
    assert facts["derived.max_visible_aspect_ratio"] == pytest.approx(4.0, abs=1e-3)
    assert facts["derived.touching_boxes"] == 2
    assert facts["derived.min_box_gap_px"] == pytest.approx(0.0, abs=1e-6)
    # flat boxes: silhouette = footprint (to 0.1 px at 1 mm height)
    assert facts["derived.min_edge_distance_px"] == pytest.approx(0.1 * PX_PER_M, abs=0.1)


def test_edge_distance_is_the_visible_silhouettes_and_gap_between_apart_boxes():
    tall = _box(3.0, 0.0, 0.1, 0.1, height=1.0)
    facts = derived_facts(_scene(tall, _box(0.0, 0.0, 0.2, 0.1)))
    # the top's outer edge (x = 3.05) seen from straight above the origin lands further out
    top_x = 3.05 * ALTITUDE / (ALTITUDE - 1.0)
    assert facts["derived.min_edge_distance_px"] == pytest.approx((HALF - top_x) * PX_PER_M,
                                                                  abs=1e-6)
    assert facts["derived.max_aspect_ratio"] == pytest.approx(2.0)
    # the tall cube's silhouette: its top, projected further out, stretches it along x
    stretch = (top_x - 2.95) / 0.1
    assert facts["derived.max_visible_aspect_ratio"] == pytest.approx(
        max(2.0, stretch / (ALTITUDE / (ALTITUDE - 1.0))), rel=1e-3)
    assert facts["derived.touching_boxes"] == 0
    # the flat box's right side at x = 0.1, the tall box's silhouette starts at x = 2.95
    assert facts["derived.min_box_gap_px"] == pytest.approx((2.95 - 0.1) * PX_PER_M, abs=0.01)


def test_a_box_crossing_the_frame_edge_has_a_negative_distance():
    facts = derived_facts(_scene(_box(HALF, 0.0, 0.2, 0.2)))
    assert facts["derived.min_edge_distance_px"] == pytest.approx(-0.1 * PX_PER_M, abs=0.1)
    assert facts["derived.touching_boxes"] == 0


def test_boxes_just_apart_but_closer_than_a_pixel_touch():
    gap_m = 0.5 / PX_PER_M  # half a frame pixel
    facts = derived_facts(_scene(_box(-0.05, 0.0, 0.1, 0.1),
                                 _box(0.05 + gap_m, 0.0, 0.1, 0.1)))
    assert facts["derived.touching_boxes"] == 2
    assert facts["derived.min_box_gap_px"] == pytest.approx(0.5, abs=0.01)


def test_no_boxes():
    facts = derived_facts(_scene())
    assert facts == {"derived.max_aspect_ratio": 0.0, "derived.max_visible_aspect_ratio": 0.0,
                     "derived.min_edge_distance_px": 500.0,
                     "derived.touching_boxes": 0, "derived.min_box_gap_px": 1000.0}


def test_the_gt_params_hold_every_fact():
    record = ground_truth_record(_scene(_box(0.0, 0.0, 0.3, 0.1)), sid="000000",
                                 preset="hand", params={"obstacles.count": 1})
    params = record.to_dict()["params"]
    assert set(FACTS) <= set(params)
    assert params["obstacles.count"] == 1
    assert params["derived.max_aspect_ratio"] == pytest.approx(3.0)
