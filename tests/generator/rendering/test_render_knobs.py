"""The rendering parameters a twin states: the edge model (``render.edge_samples``,
``render.edge_resolve``), the fill lights on the boxes' east and west faces
(``lighting.east_fill``, ``lighting.west_fill``) and the JPEG chroma subsampling of the files
(``output.jpeg_subsampling``), on real renders; at their neutral values they change nothing."""

from __future__ import annotations

import json
from dataclasses import replace

import cv2
import numpy as np
import pytest
from clirun import run_cli
from paths import ROOT

from arenabench.generator.model.lights import fill_lights, shadow_mesh_arrays
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.model.scene import (
    DirectionalLight,
    Obstacle,
    RenderSpec,
    Scene,
    load_scene,
)
from arenabench.generator.model.shading import shade_factors
from arenabench.generator.parameters.param_values import parse_overrides
from arenabench.generator.rendering.edges import obstacle_region
from arenabench.generator.rendering.render import Renderer
from arenabench.imageio import decode_image, encode_jpeg, jpeg_settings

SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"
#: Edge models rendered once for the module: (edge_samples, edge_resolve).
MODELS = ((1, "linear"), (1, "srgb"), (2, "linear"), (2, "srgb"), (4, "linear"), (4, "srgb"))


@pytest.fixture(scope="module")
def example() -> Scene:
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def grey(example, renderer) -> dict:
    """Grey renders of the example under every edge model; "hard" by ``antialias=False``
    (how hard edges were asked for before the parameter) and "default" with no render
    section."""
    def g(rgb):
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)

    out = {m: g(renderer.render(replace(example, render=RenderSpec(*m))).rgb) for m in MODELS}
    out["default"] = g(renderer.render(example).rgb)
    with Renderer(antialias=False) as hard:
        out["hard"] = g(hard.render(example).rgb)
    return out


# ----------------------------------------------------------------------------- edges

@pytest.mark.integration
def test_one_and_two_samples_render_the_former_bytes(example, renderer, grey):
    """One sample is the former hard-edged render (``antialias=False``), whatever the resolve;
    two samples in linear light is the default, and a scene states no render section then."""
    assert np.array_equal(grey[1, "linear"], grey["hard"])
    assert np.array_equal(grey[1, "srgb"], grey["hard"])
    assert np.array_equal(grey[2, "linear"], grey["default"])
    assert "render" not in example.to_dict()
    four = replace(example, render=RenderSpec(edge_samples=4, edge_resolve="srgb"))
    assert four.to_dict()["render"] == {"edge_samples": 4, "edge_resolve": "srgb"}
    assert Scene.from_dict(four.to_dict()) == four
    with Renderer(antialias=False) as hard:  # antialias=False stays hard whatever the scene
        assert np.array_equal(cv2.cvtColor(hard.render(four).rgb, cv2.COLOR_RGB2GRAY),
                              grey["hard"])
        for preset in ("eyrc-jitter", "eyrc-oblique", "warehouse"):  # tilted, lit, textured
            one = sample_scene(preset, seed=4, index=1,
                               overrides={"render.edge_samples": 1}).scene
            assert np.array_equal(renderer.render(one).rgb,
                                  hard.render(replace(one, render=RenderSpec())).rgb), preset


def test_the_edge_models_differ_only_along_the_boxes(example, grey):
    """Every model gives the same pixels outside the obstacles' region; inside, four samples
    blend more pixels than two (quarter steps as well as halves)."""
    x0, y0, x1, y1 = obstacle_region(example)
    outside = np.ones(grey["hard"].shape, bool)
    outside[y0:y1, x0:x1] = False
    blended = {}
    for model in MODELS:
        assert np.array_equal(grey[model][outside], grey["hard"][outside]), model
        blended[model] = int((grey[model] != grey["hard"]).sum())
    assert blended[1, "linear"] == 0
    assert blended[2, "linear"] == blended[2, "srgb"] > 300
    assert blended[4, "linear"] == blended[4, "srgb"] > 1.5 * blended[2, "linear"]


def test_four_samples_give_quarter_blends_and_srgb_values_give_160(example, grey):
    """docs/rendering.md, "Edges": the half blend of a dark face (71) and the floor (248) is 188
    in linear light, 160 in sRGB values; two samples never make a quarter blend (145, 221 in
    linear light), four do."""
    x0, y0, x1, y1 = obstacle_region(example)

    def count(model, *levels):
        return int(np.isin(grey[model][y0:y1, x0:x1], levels).sum())

    assert count((2, "linear"), 188) > 300 and count((2, "linear"), 160) == 0
    assert count((2, "srgb"), 160) > 200 and count((2, "srgb"), 188) == 0
    assert count((2, "linear"), 145, 221) == 0
    assert count((4, "linear"), 145, 221) > 30
    assert count((4, "srgb"), 115, 204) > 30  # the quarter blends of 71 and 248 in sRGB values


@pytest.mark.integration
def test_four_samples_reuse_the_static_layer_to_the_byte():
    """The twin's consecutive scenes share the static layer under any edge model: a reused
    renderer gives a fresh renderer's bytes."""
    scenes = [sample_scene("eyrc", seed=3, index=i, overrides={"render.edge_samples": 4,
                                                                "render.edge_resolve": "srgb"})
              .scene for i in range(3)]
    with Renderer() as r:
        images = [r.render(s).rgb for s in scenes]
        assert r._static is not None
    for scene, image in zip(scenes, images, strict=True):
        with Renderer() as fresh:
            assert np.array_equal(fresh.render(scene).rgb, image)


def test_a_range_of_edge_samples_draws_among_the_choices():
    """``render.edge_samples=1:4`` draws 1, 2 or 4 per scene (never 3), recorded in the GT's
    params and landing in the scene; a fixed value is not recorded (the params keys of the
    presets do not change)."""
    drawn, overrides = [], parse_overrides(["render.edge_samples=1:4"])
    for index in range(30):
        s = sample_scene("eyrc", seed=0, index=index, overrides=overrides)
        assert s.scene.render.edge_samples == s.params["render.edge_samples"]
        drawn.append(s.params["render.edge_samples"])
    assert set(drawn) == {1, 2, 4}
    fixed = sample_scene("eyrc", seed=0, index=0, overrides={"render.edge_samples": 4})
    plain = sample_scene("eyrc", seed=0, index=0)
    assert fixed.params == plain.params and fixed.scene.render.edge_samples == 4
    assert replace(fixed.scene, render=RenderSpec()) == plain.scene


# ----------------------------------------------------------------------------- fill lights

#: Two tall boxes either side of the camera: the west one shows its east face, the east one
#: its west face (and both their tops).
BOXES = (Obstacle(center_m=(-0.9, 0.1), yaw_deg=0.0, length_m=0.4, width_m=0.3, height_m=0.5,
                  color_rgb=(120, 120, 120)),
         Obstacle(center_m=(0.9, -0.3), yaw_deg=0.0, length_m=0.4, width_m=0.3, height_m=0.5,
                  color_rgb=(120, 120, 120)))


def _lit(scene: Scene, east: float, west: float) -> Scene:
    lights = scene.lighting.directional[:1] + fill_lights(east=east, west=west)
    return replace(scene, lighting=replace(scene.lighting, directional=lights))


def _shade(scene: Scene, normal) -> int:
    return int(np.clip(np.round(120 * shade_factors(np.array([normal]), scene.lighting)[0]),
                       0, 255))


def test_fill_lights_light_only_the_east_or_west_faces(example, renderer):
    """Hard edges, so that every pixel shows one surface: an east fill changes exactly the
    pixels showing the west box's east face, to the shade it computes (lighter); a west fill
    the east box's west face; the floor, the markers, the tops and the north and south faces
    keep every byte."""
    base = replace(example, obstacles=BOXES, render=RenderSpec(edge_samples=1))
    plain = renderer.render(base, masks=True)
    mask, before = plain.instance_mask, cv2.cvtColor(plain.rgb, cv2.COLOR_RGB2GRAY)
    for east, west, box, normal in ((0.5, 0.0, 1, (1.0, 0.0, 0.0)),
                                    (0.0, 0.7, 2, (-1.0, 0.0, 0.0))):
        lit = _lit(base, east, west)
        after = cv2.cvtColor(renderer.render(lit).rgb, cv2.COLOR_RGB2GRAY)
        changed = after != before
        assert changed.sum() > 500, (east, west)  # the face is in view
        assert (mask[changed] == box).all()  # only that box
        assert set(before[changed].tolist()) == {_shade(base, normal)}  # only that face
        assert set(after[changed].tolist()) == {_shade(lit, normal)}
        assert _shade(lit, normal) > _shade(base, normal)  # lighter
        for other in ((0, 0, 1), (0, 1, 0), (0, -1, 0), tuple(-c for c in normal)):
            assert _shade(lit, other) == _shade(base, other), other
        # every pixel of the box showing that face changed
        assert (changed == ((mask == box) & (before == _shade(base, normal)))).all()


def test_fill_lights_with_edge_samples_and_shadows(example, renderer):
    """With the default two-sample edges the change stays on the lit face and the edge pixels
    next to it; the shadow (of the first light only) and the floor are the same with and
    without fills."""
    base = replace(example, obstacles=BOXES,
                   lighting=replace(example.lighting, shadow_strength=0.6))
    lit = _lit(base, 0.8, 0.8)
    assert lit.lighting.directional[0] == base.lighting.directional[0]
    for a, b in zip(shadow_mesh_arrays(base), shadow_mesh_arrays(lit), strict=True):
        assert np.array_equal(a, b)
    hard = renderer.render(replace(base, render=RenderSpec(edge_samples=1)), masks=True)
    hard_lit = renderer.render(replace(lit, render=RenderSpec(edge_samples=1))).rgb
    faces = np.any(hard.rgb != hard_lit, axis=2).astype(np.uint8)
    near = cv2.dilate(faces, np.ones((3, 3), np.uint8)).astype(bool)
    changed = np.any(renderer.render(base).rgb != renderer.render(lit).rgb, axis=2)
    assert changed.sum() > 1000 and not (changed & ~near).any()
    floor = (hard.instance_mask == 0) & ~near
    assert np.array_equal(renderer.render(base).rgb[floor], renderer.render(lit).rgb[floor])


def test_fill_lights_from_a_preset_follow_the_main_light():
    """``--set lighting.east_fill=...`` adds a horizontal light travelling west after the main
    light; the other draws are unchanged (named streams), and a fixed fill is not recorded in
    the GT's params, a range is."""
    plain = sample_scene("eyrc-jitter", seed=2, index=1)
    east = sample_scene("eyrc-jitter", seed=2, index=1,
                        overrides={"lighting.east_fill": 0.3, "lighting.west_fill": 0.2})
    assert east.scene.lighting.directional == (
        plain.scene.lighting.directional[0],
        DirectionalLight(direction=(-1.0, 0.0, 0.0), intensity=0.3),
        DirectionalLight(direction=(1.0, 0.0, 0.0), intensity=0.2))
    assert east.params == plain.params
    assert replace(east.scene, lighting=plain.scene.lighting) == plain.scene
    drawn = sample_scene("eyrc-jitter", seed=2, index=1,
                         overrides=parse_overrides(["lighting.east_fill=0.2:0.6"]))
    assert 0.2 <= drawn.params.pop("lighting.east_fill") <= 0.6
    assert drawn.params == plain.params
    assert fill_lights(east=0.0, west=0.0) == ()


# ----------------------------------------------------------------------------- command line

@pytest.mark.parametrize("setting", [
    "render.edge_samples=3", "render.edge_samples=0", "render.edge_samples=8",
    "render.edge_samples=2.5", "render.edge_samples=3:3", "render.edge_resolve=gamma",
    "lighting.east_fill=-0.1", "lighting.east_fill=2.5", "lighting.west_fill=nan",
    "lighting.west_fill=bright", "output.jpeg_subsampling=411",
    "output.jpeg_subsampling=4:2:0",
])
def test_values_out_of_bounds_are_refused_in_one_line(tmp_path, setting):
    out = tmp_path / "set"
    proc = run_cli("generate", "--preset", "eyrc", "--count", "1", "--out", str(out),
                   "--no-progress", "--set", setting)
    assert proc.returncode == 2 and not out.exists(), proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and setting.split("=")[0] in lines[0], lines


def test_a_dataset_with_other_knobs_records_them_and_rerenders_from_its_gt(tmp_path, renderer):
    """A JPEG set at quality 80, 4:4:4, four-sample sRGB edges and an east fill: the files'
    own tables say 80 and 4:4:4, dataset.json names the edges and the chroma, and the GT's
    scene re-renders to the image's bytes (a phase check re-renders it so)."""
    out = tmp_path / "set"
    proc = run_cli("generate", "--preset", "eyrc", "--count", "2", "--seed", "5", "--out",
                   str(out), "--no-progress", "--workers", "1",
                   "--set", "output.jpeg_quality=80", "--set", "output.jpeg_subsampling=444",
                   "--set", "render.edge_samples=4", "--set", "render.edge_resolve=srgb",
                   "--set", "lighting.east_fill=0.4")
    assert proc.returncode == 0, proc.stderr
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["render"]["jpeg_chroma"] == "4:4:4" and meta["render"]["jpeg_quality"] == 80
    assert meta["render"]["edges"].startswith("four samples per pixel at (-0.125, -0.375)")
    assert meta["render"]["edges"].endswith("averaged in sRGB values")
    for index in range(2):
        data = (out / "images" / f"{index:06d}.jpg").read_bytes()
        assert jpeg_settings(data) == (80, "444")
        gt = json.loads((out / "gt" / f"{index:06d}.json").read_text())
        assert gt["scene"]["render"] == {"edge_samples": 4, "edge_resolve": "srgb"}
        assert gt["scene"]["lighting"]["directional"][1] == {"direction": [-1.0, 0.0, 0.0],
                                                             "intensity": 0.4}
        rgb = renderer.render(Scene.from_dict(gt["scene"])).rgb
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        assert encode_jpeg(bgr, quality=80, subsampling="444") == data
        assert decode_image(data).shape == bgr.shape
