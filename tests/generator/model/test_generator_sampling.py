"""Scene model, presets, --set overrides and the seeded sampler (no rendering)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from shapely.geometry import Polygon

from arenabench.generator.model.layout import box_footprint, reference_corners_world
from arenabench.generator.model.sampler import SamplingError, sample_scene
from arenabench.generator.model.scene import CameraSpec, Obstacle, Scene
from arenabench.generator.parameters.param_values import (
    format_value,
    parse_override,
    parse_overrides,
)
from arenabench.generator.parameters.params import PARAMETERS, Range
from arenabench.generator.parameters.presets import PRESETS, resolve


def test_every_preset_declares_every_parameter():
    for name in PRESETS:
        params = resolve(name)
        assert set(params) == set(PARAMETERS), name


@pytest.mark.parametrize(
    ("text", "key", "value"),
    [
        ("camera.tilt_deg=10:30", "camera.tilt_deg", Range(10.0, 30.0)),
        ("obstacles.count=3", "obstacles.count", 3),
        ("obstacles.count=1:5", "obstacles.count", Range(1, 5)),
        ("markers.ids=1,2,3,4", "markers.ids", (1, 2, 3, 4)),
        ("arena.floor_rgb=200,210,220", "arena.floor_rgb", (200, 210, 220)),
        ("camera.markers_in_view=false", "camera.markers_in_view", False),
        ("arena.texture=speckle", "arena.texture", "speckle"),
        ("markers.dictionary=DICT_5X5_100", "markers.dictionary", "DICT_5X5_100"),
    ],
)
def test_parse_override_accepts_values_and_ranges(text, key, value):
    assert parse_override(text) == (key, value)


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("camera.tilt=10", "camera.tilt"),
        ("nonsense", "key=value"),
        ("camera.tilt_deg=abc", "camera.tilt_deg"),
        ("camera.tilt_deg=30:10", "camera.tilt_deg"),
        ("camera.tilt_deg=0:95", "camera.tilt_deg"),
        ("obstacles.count=2.5", "obstacles.count"),
        ("obstacles.count=-1", "obstacles.count"),
        ("arena.floor_rgb=1,2", "arena.floor_rgb"),
        ("arena.texture=marble", "arena.texture"),
        ("camera.markers_in_view=maybe", "camera.markers_in_view"),
    ],
)
def test_parse_override_rejects_with_the_key_named(text, needle):
    with pytest.raises(ValueError, match=needle.replace(".", r"\.")):
        parse_override(text)


def test_format_value_round_trips_through_parse():
    for key, value in resolve("eyrc").items():
        assert parse_override(f"{key}={format_value(value)}") == (key, value), key


def test_same_seed_and_index_give_the_same_scene_in_any_order():
    a = [sample_scene("eyrc-jitter", seed=11, index=i).scene for i in range(6)]
    b = [sample_scene("eyrc-jitter", seed=11, index=i).scene for i in reversed(range(6))][::-1]
    assert a == b
    assert sample_scene("eyrc-jitter", seed=12, index=0).scene != a[0]
    assert len({s.obstacles for s in a}) == 6


def test_override_of_one_parameter_leaves_other_draws_alone():
    base = sample_scene("eyrc-jitter", seed=3, index=4)
    tilted = sample_scene("eyrc-jitter", seed=3, index=4,
                          overrides=parse_overrides(["lighting.ambient=0.6"]))
    assert base.scene.obstacles == tilted.scene.obstacles
    assert base.params["camera.tilt_deg"] == tilted.params["camera.tilt_deg"]
    assert tilted.params["lighting.ambient"] == 0.6


def test_eyrc_jitter_scenes_respect_the_preset():
    inner = reference_corners_world(*_arena_markers())[0, 0]  # x of the NW inner corner
    for i in range(30):
        s = sample_scene("eyrc-jitter", seed=1, index=i)
        sc = s.scene
        assert 1 <= len(sc.obstacles) <= 5
        assert s.params["obstacles.count"] == len(sc.obstacles)
        assert 0 <= sc.camera.tilt_deg <= 6
        assert sc.markers.ids == (80, 85, 90, 95) and sc.markers.rotation_deg == 180
        shapes = [Polygon(box_footprint(o)) for o in sc.obstacles]
        for k, shape in enumerate(shapes):
            assert np.all(np.abs(np.asarray(shape.exterior.coords)) <= abs(inner))
            for other in shapes[k + 1:]:
                assert shape.distance(other) >= 0.3 - 1e-5


def _arena_markers():
    sc = sample_scene("eyrc-jitter", seed=0, index=0).scene
    return sc.arena, sc.markers


def test_impossible_placement_fails_naming_the_parameters():
    overrides = parse_overrides(["obstacles.count=40", "obstacles.length_m=2",
                                 "obstacles.width_m=2", "obstacles.max_tries=20"])
    with pytest.raises(SamplingError, match=r"obstacles\.count=40.*obstacles\.min_gap_m"):
        sample_scene("eyrc-jitter", seed=0, index=0, overrides=overrides)


def test_unreachable_camera_fails_naming_the_parameters():
    overrides = parse_overrides(["camera.altitude_m=3", "camera.max_tries=5"])
    with pytest.raises(SamplingError, match=r"camera\.altitude_m"):
        sample_scene("eyrc-jitter", seed=0, index=0, overrides=overrides)


def test_scene_json_round_trip():
    sc = sample_scene("eyrc-jitter", seed=5, index=2).scene
    text = json.dumps(sc.to_dict())
    assert Scene.from_dict(json.loads(text)) == sc


@pytest.mark.parametrize(
    ("factory", "needle"),
    [
        (lambda: Obstacle(center_m=(0, 0), yaw_deg=0, length_m=-1, width_m=1, height_m=1),
         "length_m"),
        (lambda: CameraSpec(width=8), "camera.width"),
        (lambda: CameraSpec(tilt_deg=85), "camera.tilt_deg"),
        (lambda: CameraSpec(eye_m=(0, 0, 5)), "look_at_m"),
    ],
)
def test_scene_parts_validate_their_values(factory, needle):
    with pytest.raises(ValueError, match=needle):
        factory()


def test_presets_cli_lists_and_shows_parseable_parameters(capsys):
    from arenabench.generator.commands import presets as presets_cli

    assert presets_cli.main([]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in PRESETS)
    assert presets_cli.main(["--show", "eyrc"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(PARAMETERS)
    assert dict(parse_override(line) for line in lines) == resolve("eyrc")
    assert presets_cli.main(["--params"]) == 0
    assert "camera.tilt_deg" in capsys.readouterr().out
    assert presets_cli.main(["--show", "nosuch"]) == 2
    assert "nosuch" in capsys.readouterr().err


def test_package_exports_the_in_memory_api():
    import arenabench.generator as gen

    for name in gen.__all__:
        assert getattr(gen, name) is not None, name
    with pytest.raises(AttributeError):
        gen.nothing_here  # noqa: B018
