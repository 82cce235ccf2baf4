"""The parameter registry: typed ranges, one declaration per parameter, derived tables."""

from __future__ import annotations

import dataclasses

import pytest

from arenabench.generator.model.lens import LENS_PARAMS
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.model.scene import IMAGE_TEXTURE_FIELDS
from arenabench.generator.parameters.param_values import (
    format_value,
    parse_override,
    validate_value,
)
from arenabench.generator.parameters.params import (
    NEUTRAL,
    PARAMETERS,
    PARAMS,
    Param,
    Range,
    assemble,
)
from arenabench.generator.parameters.presets import resolve
from arenabench.generator.rendering.degrade import PARAM_NAMES, Degradations


@pytest.mark.parametrize(("lo", "hi", "needle"), [
    (2.0, 1.0, "lo > hi"), (float("nan"), 1.0, "finite"), ("a", 1.0, "numbers"),
    (True, 2, "numbers"),
])
def test_range_refuses_what_is_not_a_range(lo, hi, needle):
    with pytest.raises(ValueError, match=needle):
        Range(lo, hi)


def test_a_range_is_accepted_as_range_list_or_tuple_and_comes_back_typed():
    want = Range(0.0, 6.0)
    for given in (Range(0, 6), [0, 6], (0.0, 6.0), ["0", "6"]):
        assert validate_value("camera.tilt_deg", given) == want
    assert validate_value("camera.tilt_deg", [3, 3]) == 3.0  # equal ends: one value
    assert validate_value("obstacles.count", (1, 4)) == Range(1, 4)
    assert format_value(Range(0.25, 6.0)) == "0.25:6"
    with pytest.raises(ValueError, match=r"camera\.tilt_deg.*out of range"):
        validate_value("camera.tilt_deg", Range(0.0, 95.0))
    with pytest.raises(ValueError, match=r"camera\.tilt_deg.*two ends"):
        validate_value("camera.tilt_deg", [1, 2, 3])
    # a three-number colour is a colour, not a range
    assert parse_override("arena.floor_rgb=1,2,3") == ("arena.floor_rgb", (1, 2, 3))


def test_param_declarations_are_checked():
    with pytest.raises(ValueError, match="kind"):
        Param("x.y", "complex", "help")
    with pytest.raises(ValueError, match="draw"):
        Param("x.y", "float", "help", draw="sometimes")
    with pytest.raises(ValueError, match="lands"):
        Param("x.y", "float", "help", lands="nowhere.field")


def test_tables_are_derived_from_the_declarations():
    assert list(PARAMETERS) == [p.name for p in PARAMS]
    # every Degradations field is one declared parameter, and its default is the neutral value
    fields = {f.name: f.default for f in dataclasses.fields(Degradations)}
    assert set(PARAM_NAMES) == set(fields)
    for field, name in PARAM_NAMES.items():
        assert PARAMETERS[name].neutral == fields[field] == NEUTRAL[name], name
    assert LENS_PARAMS == ("camera.k1", "camera.k2", "camera.p1", "camera.p2", "camera.k3")
    for p in PARAMS:
        # numbers have bounds, and so does each side of a size
        assert p.help and (p.bounds is None) != (p.numeric or p.kind == "size"), p.name
        if p.neutral is not None:
            validate_value(p.name, p.neutral)


def test_every_value_lands_where_it_is_declared():
    # the edge model off its defaults: a scene file states its render section only then
    edges = {"render.edge_samples": 4, "render.edge_resolve": "srgb"}
    sampled = sample_scene("eyrc-hard", seed=0, index=3, overrides=edges)
    scene = sampled.scene.to_dict()
    values = {**resolve("eyrc-hard", edges), **sampled.params}
    sections = assemble(values)
    for p in PARAMS:
        if not p.lands or p.lands.startswith("degrade."):
            continue
        if p.lands.split(".")[-1] in IMAGE_TEXTURE_FIELDS:  # written for image textures only
            assert scene["arena"]["texture"] != "image" and values[p.name] == p.neutral
            continue
        if p.name == "markers.printed":  # written only when true
            assert "printed" not in scene["markers"] and values[p.name] is False
            continue
        node = scene
        for part in p.lands.split("."):
            node = node[int(part)] if part.isdigit() else node[part]
        want = values[p.name]
        assert node == (list(want) if isinstance(want, tuple) else want), p.name
    assert sections["camera"]["target_m"] == [values["camera.target_x_m"],
                                              values["camera.target_y_m"]]


def test_draws_are_keyed_by_name():
    from arenabench.generator.model.sampler import stream_rng

    seed, index = 3, 4
    s = sample_scene("eyrc-jitter", seed=seed, index=index)
    lo, hi = 0.58, 0.62  # eyrc-jitter's lighting.ambient
    u = stream_rng(seed, index, "lighting.ambient").random()
    assert s.params["lighting.ambient"] == pytest.approx(lo + u * (hi - lo), abs=1e-6)
    # turning other parameters into ranges (new draws, here before and after it in
    # declaration order) moves no other draw
    moved = sample_scene("eyrc-jitter", seed=seed, index=index, overrides={
        "arena.texture_seed": Range(0, 9), "degrade.noise_sigma": Range(0.0, 5.0),
        "lighting.spot_strength": Range(0.0, 0.5)})
    for key, value in s.params.items():
        if key not in ("degrade.noise_sigma", "lighting.spot_strength"):
            assert moved.params[key] == value, key
    assert moved.scene.obstacles == s.scene.obstacles
    with pytest.raises(ValueError, match="seed"):
        stream_rng(-1, 0, "x")


@pytest.mark.parametrize("ids", ["80,80,80,80", "80,85,80,95", (1, 2, 3, 1)])
def test_marker_ids_of_the_four_corners_must_differ(ids):
    from arenabench.generator.model.scene import MarkerSpec

    with pytest.raises(ValueError, match="the four corners' ids must differ"):
        validate_value("markers.ids", ids)
    with pytest.raises(ValueError, match=r"markers\.ids must be 4 different ids"):
        MarkerSpec(ids=tuple(int(i) for i in (ids.split(",") if isinstance(ids, str) else ids)))
    assert validate_value("markers.ids", "80,85,90,95") == (80, 85, 90, 95)
