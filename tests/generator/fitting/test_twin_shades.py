"""The twin's reading of greys and boxes (generator/fitting/shades.py) on real renders: the floor's
grey, the background beyond a margin the twin does not yet know, and a box that a printed line
touches."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from twin_blind import hidden_case

from arenabench.generator.fitting.shades import floor_level, read_shades
from arenabench.generator.model.shading import floor_factor
from arenabench.generator.rendering.render import Renderer

#: A blind round trip's hidden scene (tests/twin_blind.py) drawn for a small image: a plain
#: floor with four boxes, a lighter background beyond a margin of a tenth of the arena.
SEED, PX = 9, 480


@pytest.fixture(scope="module")
def rendered():
    scene = hidden_case(SEED, image_px=PX).scene
    with Renderer() as r:
        bgr = cv2.cvtColor(r.render(scene).rgb, cv2.COLOR_RGB2BGR)
    return scene, bgr


def _read(scene, bgr):
    # the twin reads the greys before it knows the margin: the markers' square only
    return read_shades(bgr, scene.camera, replace(scene.arena, margin_m=0.0), scene.markers)


def test_a_plain_floors_grey_is_its_own():
    """One grey (a plain floor in a PNG) is read as that grey, not the darkest of a tie."""
    assert floor_level(np.full(5000, 234.0)) == 234
    spread = np.concatenate([np.full(3000, 230.0), np.full(2000, 231.0), np.full(900, 120.0)])
    assert floor_level(spread) == 230
    # a lit textured floor spread about 252 and clipped at 255: not the pile of 255s
    rng = np.random.default_rng(0)
    clipped = np.clip(np.rint(rng.normal(252.0, 3.0, 50_000)), 0, 255)
    assert abs(floor_level(clipped) - 252) <= 1


@pytest.mark.integration
def test_the_background_beyond_an_unknown_margin(rendered):
    scene, bgr = rendered
    assert scene.arena.margin_m > 0.05 * scene.arena.side_m
    shades = _read(scene, bgr)
    lit = round(scene.arena.floor_rgb[0] * min(floor_factor(scene.lighting), 1.0))
    assert abs(shades.floor_rgb[0] - lit) <= 1
    assert abs(lit - scene.background_rgb[0]) > 8  # told apart by the image
    assert shades.background_rgb is not None  # and not the margin's floor grey:
    assert abs(shades.background_rgb[0] - scene.background_rgb[0]) <= 1


@pytest.mark.integration
def test_a_box_that_a_printed_line_touches_is_still_a_box(rendered):
    scene, bgr = rendered
    plain = _read(scene, bgr)
    assert len(plain.boxes) == len(scene.obstacles) == 4
    # a 2 px dark lane line across the arena through the middle of the lowest box
    lowest = min(plain.boxes, key=lambda b: b.obstacle.center_m[1])
    v = _row(scene, lowest.obstacle.center_m)
    lined = bgr.copy()
    cv2.line(lined, (0, v), (PX - 1, v + 3), (90, 90, 90), 2)
    shades = _read(scene, lined)
    assert len(shades.boxes) == 4
    for a, b in zip(sorted(shades.boxes, key=_key), sorted(plain.boxes, key=_key), strict=True):
        assert abs(a.obstacle.length_m - b.obstacle.length_m) < 0.05 * b.obstacle.length_m
        assert abs(a.obstacle.width_m - b.obstacle.width_m) < 0.05 * b.obstacle.width_m


def _key(box) -> tuple[float, float]:
    return tuple(round(v, 1) for v in box.obstacle.center_m)


def _row(scene, xy) -> int:
    """The image row of floor point ``xy``."""
    from arenabench.generator.model import camera as cam

    px = cam.project(np.array([[xy[0], xy[1], 0.0]]), cam.intrinsics(scene.camera),
                     cam.world_from_camera(scene.camera))[0]
    return round(float(px[1]))
