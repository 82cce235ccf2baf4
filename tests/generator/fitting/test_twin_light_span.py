"""The lights an open light allows (generator/fitting/light_span.py): every one gives the faces
the image shows, and they span the shades of the faces it does not show."""

from __future__ import annotations

import math

import numpy as np
import pytest

from arenabench.generator.fitting.light_span import (
    FACE_TOLERANCE,
    NORMAL_AZIMUTH_DEG,
    light_extremes,
)
from arenabench.generator.fitting.scene_fit import BoxObservation, fit_lighting
from arenabench.generator.model.scene import DirectionalLight, LightingSpec, Obstacle
from arenabench.generator.model.shading import floor_factor, shade_factors

SOUTH = (0.0, -1.0, 0.0)


def _spec(light) -> LightingSpec:
    el, az = math.radians(light.elevation_deg), math.radians(light.azimuth_deg)
    d = (-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), -math.sin(el))
    return LightingSpec(ambient=light.ambient,
                        directional=(DirectionalLight(direction=d, intensity=light.intensity),))


def _normal(direction: str) -> np.ndarray:
    a = math.radians(NORMAL_AZIMUTH_DEG[direction])
    return np.array([math.cos(a), math.sin(a), 0.0])


@pytest.mark.parametrize("floor", [1.0, 0.8])
def test_every_light_keeps_the_faces_seen_and_spans_the_unseen(floor):
    top, south = 120.0, 75.0  # a box whose top and south face the image shows
    box = BoxObservation(obstacle=Obstacle(center_m=(0.0, 0.0), length_m=0.5, width_m=0.3,
                                           height_m=0.3, yaw_deg=0.0, color_rgb=(120,) * 3),
                         top_gray=top, side_faces=((SOUTH, south),), iou=1.0)
    unseen = ["east", "west", "north"]
    extremes = light_extremes([box], unseen, floor=floor)
    assert [(e.direction, e.end) for e in extremes] == [
        (d, end) for d in unseen for end in ("darkest", "lightest")]
    for e in extremes:
        spec = _spec(e.light)
        # the floor (and a top face) keep their factor; the south face its grey
        assert floor_factor(spec) == pytest.approx(floor, abs=1e-4)
        got = top * shade_factors(np.array([SOUTH]), spec)[0] / floor
        assert abs(got - south) <= FACE_TOLERANCE + 0.05
        # the ratio it reports is the face's factor relative to a top's
        ratio = shade_factors(np.array([_normal(e.direction)]), spec)[0] / floor
        assert ratio == pytest.approx(e.ratio, abs=1e-3)
        assert 0.0 <= e.light.ambient <= 2.0 and 0.0 <= e.light.intensity <= 2.0
    for d in unseen:  # the unseen faces' shades are open: darkest and lightest differ
        dark, light = (e.ratio for e in extremes if e.direction == d)
        assert dark < light - 0.2
    # the twin's own light (the weakest that gives them) lies inside every span
    own = fit_lighting([box])
    for d in unseen:
        dark, light = (e.ratio for e in extremes if e.direction == d)
        assert dark - 1e-3 <= shade_factors(np.array([_normal(d)]), own)[0] <= light + 1e-3


def test_with_no_face_seen_any_light_goes():
    box = BoxObservation(obstacle=Obstacle(center_m=(0.0, 0.0), length_m=0.5, width_m=0.3,
                                           height_m=0.3, yaw_deg=0.0, color_rgb=(120,) * 3),
                         top_gray=120.0, side_faces=(), iou=1.0)
    extremes = light_extremes([box], ["south"])
    dark, light = extremes
    assert dark.ratio == pytest.approx(0.0, abs=1e-6)  # no ambient, lit from the north
    assert light.ratio > 1.0  # a low light from the south: lighter than a top
