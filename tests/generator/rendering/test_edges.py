"""The edge models (generator/rendering/edges.py) and how the renderer draws them: the offset
samples,
their resolve, the obstacles' region and the reusable static layer."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from marks import integration_but
from test_twin_fidelity import SCENE

from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.model.scene import RenderSpec, load_scene
from arenabench.generator.parameters.params import PARAMETERS
from arenabench.generator.rendering.edges import (
    EDGE_PATTERNS,
    EDGE_RESOLVES,
    EDGE_SAMPLES,
    SAME_SURFACE_MAX_DIFF,
    edge_model,
    linear_to_srgb,
    obstacle_region,
    resolve_samples,
    srgb_to_linear,
)
from arenabench.generator.rendering.render import Renderer


def test_srgb_round_trip_and_known_values():
    values = np.arange(256, dtype=np.uint8)
    assert np.array_equal(linear_to_srgb(srgb_to_linear(values)), values)
    assert srgb_to_linear(np.uint8(0)) == 0.0 and srgb_to_linear(np.uint8(255)) == 1.0
    assert int(linear_to_srgb(0.5)) == 188  # mid-grey in linear light


def test_resolve_blends_only_where_the_samples_differ():
    centre = np.full((2, 3, 3), 71, np.uint8)
    first = centre.copy()
    second = centre.copy()
    second[0, 0] = 248                            # an edge: dark face and floor
    second[1, 1] = 71 + SAME_SURFACE_MAX_DIFF     # texture-level difference: same surface
    n = resolve_samples(centre, [first, second])
    assert n == 1
    assert centre[0, 0].tolist() == [188, 188, 188]  # half of 71 and 248 in linear light
    assert (centre.reshape(-1, 3)[1:] == 71).all()


def test_resolve_refuses_mismatched_samples():
    with pytest.raises(ValueError, match="shaped like the centre"):
        resolve_samples(np.zeros((2, 2, 3), np.uint8), [np.zeros((2, 3, 3), np.uint8),
                                                         np.zeros((2, 2, 3), np.uint8)])
    with pytest.raises(ValueError, match="one or more"):
        resolve_samples(np.zeros((2, 2, 3), np.uint8), [])
    with pytest.raises(ValueError, match="resolve must be one of linear, srgb"):
        resolve_samples(np.zeros((2, 2, 3), np.uint8), [np.zeros((2, 2, 3), np.uint8)],
                        resolve="gamma")


def test_samples_sit_on_the_diagonal_either_side_of_the_centre():
    (ax, ay), (bx, by) = EDGE_SAMPLES
    assert (ax + bx, ay + by) == (0.0, 0.0) and abs(ax) == abs(ay) == 0.25


def test_the_patterns_are_the_standard_ones_and_the_parameters_choices():
    """One pattern per choice of render.edge_samples, one resolve per choice of
    render.edge_resolve; the 4-sample pattern is the standard rotated grid (Vulkan's standard
    sample locations, D3D's standard pattern): (-2, -6), (6, -2), (-6, 2), (2, 6) sixteenths
    of a pixel from the centre, each sample alone in its row and column quarter."""
    assert sorted(EDGE_PATTERNS) == sorted(int(c) for c in
                                           PARAMETERS["render.edge_samples"].choices)
    assert sorted(EDGE_RESOLVES) == sorted(PARAMETERS["render.edge_resolve"].choices)
    assert EDGE_PATTERNS[1] == ((0.0, 0.0),)
    assert EDGE_PATTERNS[2] == EDGE_SAMPLES
    four = [(round(x * 16), round(y * 16)) for x, y in EDGE_PATTERNS[4]]
    assert four == [(-2, -6), (6, -2), (-6, 2), (2, 6)]
    corner_origin = sorted((x + 0.5, y + 0.5) for x, y in EDGE_PATTERNS[4])
    assert corner_origin == [(0.125, 0.625), (0.375, 0.125), (0.625, 0.875), (0.875, 0.375)]
    assert len({x for x, _ in four}) == len({y for _, y in four}) == 4
    assert edge_model(RenderSpec()) == (
        "two samples per pixel at (-0.25, -0.25) and (0.25, 0.25) px from its centre on the "
        "obstacles' region, averaged in linear light")
    assert edge_model(RenderSpec(edge_samples=1)) == "one sample per pixel (hard edges)"
    assert "four samples" in edge_model(RenderSpec(edge_samples=4, edge_resolve="srgb"))


def test_two_sample_resolve_is_the_former_one_to_the_byte():
    """The N-sample resolve on two samples gives exactly what the two-sample resolve gave
    (absolute difference above SAME_SURFACE_MAX_DIFF in a channel -> (a + b) / 2 in linear
    light), on random samples with every kind of difference."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        centre = rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)
        first = rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)
        second = np.clip(first.astype(int) + rng.integers(-12, 13, first.shape), 0,
                         255).astype(np.uint8)
        second[rng.random((40, 50)) < 0.2] = rng.integers(0, 256, 3, dtype=np.uint8)
        want = centre.copy()
        diff = cv2.absdiff(first, second)
        ys, xs = np.nonzero((diff > SAME_SURFACE_MAX_DIFF).any(axis=2))
        want[ys, xs] = linear_to_srgb(
            (srgb_to_linear(first[ys, xs]) + srgb_to_linear(second[ys, xs])) * 0.5)
        got = centre.copy()
        assert resolve_samples(got, [first, second]) == len(ys) > 0
        assert np.array_equal(got, want)


def test_four_samples_blend_in_quarters_and_srgb_resolves_average_the_values():
    """Four samples give quarter blends; the sRGB-value resolve gives 160 for the half blend
    of 71 and 248 where linear light gives 188 (docs/rendering.md, "Edges")."""
    dark, floor = np.full((1, 5, 3), 71, np.uint8), np.full((1, 5, 3), 248, np.uint8)

    def four(n_floor, resolve):
        centre = dark.copy()
        samples = [floor if k < n_floor else dark for k in range(4)]
        resolve_samples(centre, samples, resolve=resolve)
        return int(centre[0, 0, 0])

    lin71, lin248 = srgb_to_linear(np.uint8(71)), srgb_to_linear(np.uint8(248))
    for k in (1, 2, 3):
        assert four(k, "linear") == int(linear_to_srgb((k * lin248 + (4 - k) * lin71) / 4))
    assert [four(k, "linear") for k in (1, 2, 3)] == [145, 188, 221]
    assert [four(k, "srgb") for k in (1, 2, 3)] == [115, 160, 204]  # 115.25, 159.5, 203.75
    assert four(0, "linear") == 71 and four(4, "srgb") == 71  # one surface: centre kept
    one = dark.copy()
    assert resolve_samples(one, [floor]) == 0 and (one == 71).all()


@pytest.fixture(scope="module")
def example():
    return load_scene(SCENE)


def test_offset_pass_samples_where_it_says(example):
    """A pass at offset (dx, dy) shows at pixel (x, y) what the centre pass shows at
    (x + dx, y + dy): checked with whole-pixel offsets (geometry lands exactly; texture
    filtering may differ on a few pixels of the printed lines)."""
    with Renderer(antialias=False) as r:
        base = r.render(example).rgb
        flags = r._pr.RenderFlags.FLAT | r._pr.RenderFlags.SKIP_CULL_FACES
        full = (0, 0, example.camera.width, example.camera.height)
        shifted = {off: r._offset_pass(flags, full, off) for off in ((3, 0), (0, 3), (-2, 1))}
    for (dx, dy), image in shifted.items():
        inner = image[100:900, 100:900]
        right = np.any(inner != base[100 + dy:900 + dy, 100 + dx:900 + dx], axis=2).mean()
        wrong = np.any(inner != base[100 - dy:900 - dy, 100 - dx:900 - dx], axis=2).mean()
        assert right < 0.0005 and wrong > 20 * right, (dx, dy, right, wrong)


@pytest.mark.parametrize("preset", integration_but(["eyrc", "eyrc-oblique"], "eyrc-oblique"))
def test_region_holds_every_obstacle_pixel(renderer, preset):
    for index in range(8):
        scene = sample_scene(preset, seed=5, index=index).scene
        mask = renderer.render(scene, masks=True).instance_mask
        x0, y0, x1, y1 = obstacle_region(scene)
        inside = np.zeros_like(mask, dtype=bool)
        inside[y0:y1, x0:x1] = True
        assert mask.any() and not (mask.astype(bool) & ~inside).any()


def test_region_is_none_without_obstacles(example):
    from dataclasses import replace

    assert obstacle_region(replace(example, obstacles=())) is None


@pytest.mark.integration
@pytest.mark.parametrize("preset", ["eyrc", "eyrc-jitter", "warehouse"])
def test_static_layer_gives_the_same_bytes_as_a_fresh_renderer(preset):
    """A renderer reuses the floor, markers and background of consecutive scenes that share
    them (the twin's fixed camera) and draws only the obstacles' region: every image must be
    byte-identical to a full render by a fresh renderer."""
    scenes = [sample_scene(preset, seed=2, index=i).scene for i in range(12)]
    with Renderer() as r:
        images = [r.render(s).rgb for s in scenes]
        cached = r._static is not None
    assert cached == (preset == "eyrc")  # fixed camera and no overlays: the twin only
    for scene, image in zip(scenes, images, strict=True):
        with Renderer() as fresh:
            assert np.array_equal(fresh.render(scene).rgb, image)


def test_antialias_off_draws_no_blended_pixel(example):
    with Renderer(antialias=False) as r:
        gray = cv2.cvtColor(r.render(example).rgb, cv2.COLOR_RGB2GRAY)
    with Renderer() as r:
        soft = cv2.cvtColor(r.render(example).rgb, cv2.COLOR_RGB2GRAY)
    x0, y0, x1, y1 = obstacle_region(example)
    halves = [188, 198]  # dark face / floor and top face / floor, half blends
    assert not np.isin(gray[y0:y1, x0:x1], halves).any()
    assert np.isin(soft[y0:y1, x0:x1], halves).sum() > 300
