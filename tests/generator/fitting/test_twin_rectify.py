"""The no-texture twin's texture grid (generator/fitting/rectify.py): the sides that put printed
markers' outer corners on texel boundaries, and the search that picks one on a real render."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from arenabench.generator import Renderer
from arenabench.generator.fitting import rectify
from arenabench.generator.fitting.markers import find_markers
from arenabench.generator.fitting.regions import marker_squares
from arenabench.generator.model.layout import floor_extent
from arenabench.generator.model.sampler import sample_scene


@pytest.fixture(scope="module")
def eyrc_scene():
    """Scene 0 of eyrc, boxes left out: the competition's texture (2,880 texels over 3.7 m,
    its markers' outer corners 144 texels in from its edge)."""
    scene = sample_scene("eyrc", seed=0, index=0).scene
    return replace(scene, obstacles=())


@pytest.fixture(scope="module")
def fitted(eyrc_scene):
    """The same scene as a twin without the texture has it: the geometry, a plain floor."""
    return replace(eyrc_scene, arena=replace(eyrc_scene.arena, texture="plain"))


def test_the_sides_tried_put_the_outer_corners_on_texel_boundaries(eyrc_scene):
    arena = eyrc_scene.arena
    e = floor_extent(arena)
    share = (e - arena.side_m / 2) / (2 * e)
    sides = rectify.aligned_sides(eyrc_scene)
    lo, hi = rectify.GRID_SIDES
    assert sides == sorted(set(sides)) and lo <= sides[0] and sides[-1] <= hi
    offsets = [share * n for n in sides]  # texels from the texture's edge to the corners
    steps = [round(o / rectify.GRID_ALIGN) for o in offsets]
    assert all(abs(o - rectify.GRID_ALIGN * k) <= share / 2 + 1e-9
               for o, k in zip(offsets, steps, strict=True))
    assert steps == list(range(steps[0], steps[-1] + 1))  # every aligned grid, once
    assert 2880 in sides  # the competition's own
    with pytest.raises(ValueError, match=r"arena\.margin_m"):
        rectify.aligned_sides(replace(eyrc_scene, arena=replace(arena, margin_m=0.0)))


def test_the_refined_grids_keep_the_corners_on_the_same_boundary(fitted):
    half = fitted.arena.side_m / 2
    for n in range(2868, 2893):
        extent = rectify.aligned_extent(fitted, n, 144)
        moved = rectify.with_extent(fitted, extent)
        assert floor_extent(moved.arena) == pytest.approx(extent, abs=1e-8)
        assert (extent - half) * n / (2 * extent) == pytest.approx(144, abs=1e-6)
    # the competition's own: 144 texels in at 2,880 is the floor's 3.7 m
    assert rectify.aligned_extent(fitted, 2880, 144) == pytest.approx(1.85, abs=1e-9)


@pytest.mark.integration
def test_the_search_finds_the_grid_the_markers_were_printed_on(eyrc_scene, fitted):
    """The image: a render of the competition's texture. The scene the twin would have fitted:
    the same, geometry exact. Of the aligned sides near it, the painted markers match the
    image best on the texture's own 2,880 texels; refined, on a grid that keeps the corners
    144 texels in and the texel within 0.05 % of the texture's (painted markers are not the
    texture's resized ones: 2,881 texels over 0.99996 of the extent match them as well)."""
    with Renderer() as renderer:
        rgb = renderer.render(eyrc_scene).rgb
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        mask = np.zeros(gray.shape, bool)
        for m in marker_squares(find_markers(gray), gray.shape).values():
            mask |= m
        said = []
        grid = rectify.texel_grid_search(bgr, gray, fitted, np.zeros(gray.shape, bool),
                                         mask, renderer, sides=(2700, 3100), refine=2,
                                         progress=said.append)
        first = [line for line in said if "refined" not in line]
        assert len(first) == len(rectify.aligned_sides(fitted, sides=(2700, 3100))) > 2
        assert "(best 2880: " in first[-1], first  # the first stage: the texture's own side
        assert len(said) - len(first) == 4  # 2878, 2879, 2881, 2882, each on its own extent
        half = fitted.arena.side_m / 2
        assert (grid.extent_m - half) * grid.side / (2 * grid.extent_m) == pytest.approx(144)
        assert 2 * grid.extent_m / grid.side == pytest.approx(3.7 / 2880, rel=5e-4)
        assert abs(grid.side - 2880) <= 2 and grid.cost < 2.0, said
    with pytest.raises(ValueError, match="no side"):
        rectify.texel_grid_search(bgr, gray, fitted, np.zeros(gray.shape, bool), mask,
                                  renderer, sides=(2881, 2900))
