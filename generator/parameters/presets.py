"""The built-in scene presets, and the ``--preset NAME|FILE`` rule.

A preset maps dotted parameter names to a fixed value or a :class:`Range` (the values:
:mod:`arenabench.generator.parameters.param_values`). The built-in ones are given here in code or as
preset files shipped with the package (:data:`PRESET_FILES`, read by
:mod:`arenabench.generator.parameters.preset_files`); :func:`resolve_preset` turns a ``--preset``
value
(a built-in name, or the path of a preset file) into a
:class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from arenabench.frame import COMPETITION_DICTIONARY
from arenabench.generator.parameters.param_values import resolve_params
from arenabench.generator.parameters.params import NEUTRAL, Range, Value
from arenabench.generator.parameters.preset_files import (
    ResolvedPreset,
    load_preset_file,
    preset_hash,
)
from arenabench.suggest import did_you_mean

#: The competition example's look, widened: a procedural 8 m arena, the camera, light, box greys
#: and yaw jittered around the fitted example.
_EYRC_JITTER: dict[str, Value] = {
    "arena.side_m": 8.0,
    "arena.margin_m": 0.45,
    "arena.floor_rgb": (250, 250, 250),
    "arena.texture": "plain",
    "arena.texture_seed": 0,
    "arena.border_width_m": 0.015,
    "arena.border_rgb": (20, 20, 20),
    "arena.grid_step_m": 0.0,
    "arena.grid_rgb": (200, 200, 200),
    "arena.logo_text": "eyantra",
    "arena.logo_rgb": (220, 50, 50),
    "markers.dictionary": COMPETITION_DICTIONARY,
    "markers.ids": (80, 85, 90, 95),
    "markers.side_m": Range(0.50, 0.56),
    "markers.rotation_deg": 180.0,
    "markers.quiet_zone_m": 0.04,
    "obstacles.count": Range(1, 5),
    "obstacles.length_m": Range(0.7, 2.2),
    "obstacles.width_m": Range(0.5, 1.2),
    "obstacles.height_m": Range(0.2, 0.8),
    "obstacles.yaw_deg": Range(-6.0, 6.0),
    "obstacles.gray": Range(100, 140),
    "obstacles.palette": "gray",
    "obstacles.min_gap_m": 0.3,
    "obstacles.edge_margin_m": 0.3,
    "obstacles.max_tries": 500,
    "camera.width": 1000,
    "camera.height": 1000,
    "camera.fov_deg": Range(58.0, 68.0),
    "camera.altitude_m": Range(7.8, 8.9),
    "camera.tilt_deg": Range(0.0, 6.0),
    "camera.yaw_deg": Range(-2.0, 2.0),
    "camera.roll_deg": Range(-0.5, 0.5),
    "camera.target_x_m": Range(-0.2, 0.2),
    "camera.target_y_m": Range(-0.1, 0.7),
    "camera.markers_in_view": True,
    "camera.max_tries": 100,
    "lighting.ambient": Range(0.58, 0.62),
    "lighting.intensity": Range(0.40, 0.50),
    "lighting.elevation_deg": Range(55.0, 70.0),
    "lighting.azimuth_deg": Range(0.0, 360.0),
    "background.gray": Range(218, 232),
    **NEUTRAL,
}

#: eyrc under what a real drone adds: every draw stays in a range a flight camera
#: plausibly sees; the reference pipeline's pass rate on it is a figure, not a tuning target.
_EYRC_HARD: dict[str, Value] = {
    **_EYRC_JITTER,
    "camera.tilt_deg": Range(0.0, 15.0),
    "camera.altitude_m": Range(8.3, 10.5),
    "camera.yaw_deg": Range(-15.0, 15.0),
    "camera.roll_deg": Range(-2.0, 2.0),
    "lighting.ambient": Range(0.45, 0.7),
    "lighting.intensity": Range(0.3, 0.6),
    "lighting.elevation_deg": Range(40.0, 80.0),
    "lighting.shadow_strength": Range(0.0, 0.4),
    "degrade.noise_sigma": Range(0.0, 6.0),
    "degrade.motion_blur_px": Range(0.0, 2.0),
    "degrade.motion_angle_deg": Range(0.0, 180.0),
    "degrade.defocus_px": Range(0.0, 1.0),
    "degrade.exposure_ev": Range(-0.5, 0.3),
    "degrade.vignetting": Range(0.0, 0.3),
    "degrade.jpeg_quality": Range(60, 95),
}

#: A marked arena on a real warehouse floor: concrete with stains and painted lane lines,
#: wooden pallets and coloured crates, tape and paper clutter, a drone-like camera.
_WAREHOUSE: dict[str, Value] = {
    **_EYRC_JITTER,
    "arena.floor_rgb": (168, 166, 160),
    "arena.texture": "concrete",
    "arena.texture_seed": Range(0, 7),
    "arena.margin_m": 1.2,
    "arena.border_rgb": (30, 30, 30),
    "arena.border_width_m": 0.03,
    "arena.logo_text": "",
    "background.gray": Range(120, 150),
    "obstacles.palette": "warehouse",
    "obstacles.count": Range(1, 6),
    "obstacles.height_m": Range(0.3, 0.9),
    "obstacles.yaw_deg": Range(-30.0, 30.0),
    "camera.altitude_m": Range(9.5, 11.0),
    "camera.tilt_deg": Range(0.0, 12.0),
    "camera.yaw_deg": Range(-20.0, 20.0),
    "lighting.ambient": Range(0.5, 0.7),
    "lighting.intensity": Range(0.3, 0.5),
    "lighting.elevation_deg": Range(45.0, 85.0),
    "lighting.shadow_strength": Range(0.0, 0.3),
    "distractors.tapes": Range(0, 2),
    "distractors.papers": Range(0, 3),
    "degrade.noise_sigma": Range(0.0, 4.0),
    "degrade.jpeg_quality": Range(70, 95),
}


#: The fitted competition example (camera, light, colours), shipped with the package: the
#: evidence the ``eyrc`` preset file's camera, light and colours were read from (a test keeps
#: them equal).
EXAMPLE_SCENE = Path(__file__).resolve().parents[1] / "scenes" / "task1c_example.json"

#: Built-in presets kept as preset files (package data, docs/formats.md "Preset files"):
#: name -> file. The file is the preset's only source; its ``[preset]`` name is the key.
PRESET_FILES: dict[str, Path] = {
    "eyrc": Path(__file__).resolve().parents[1] / "assets" / "presets" / "eyrc.toml",
}


class _Presets(Mapping[str, tuple[str, dict[str, Value]]]):
    """Built-in presets, name -> (description, parameters), in listing order; a preset of
    :data:`PRESET_FILES` is read (and validated) on first use."""

    def __init__(self, order: tuple[str, ...], given: dict[str, tuple[str, dict[str, Value]]]
                 ) -> None:
        self._order = order
        self._given = given

    def __getitem__(self, name: str) -> tuple[str, dict[str, Value]]:
        if name in self._given:
            return self._given[name]
        if name in PRESET_FILES and name in self._order:
            made = builtin_preset(name)
            self._given[name] = (made.description, dict(made.params))
            return self._given[name]
        raise KeyError(name)

    def __iter__(self) -> Iterator[str]:
        return iter(self._order)

    def __len__(self) -> int:
        return len(self._order)

    def __contains__(self, name: object) -> bool:
        return name in self._order


#: The built-in presets given in code: name -> (description, parameters).
_IN_CODE: dict[str, tuple[str, dict[str, Value]]] = {
    "eyrc-jitter": ("looks like the e-Yantra Task 1C example, widened: 8 m arena, camera, "
                    "light, box greys and yaw jittered, 1-5 grey boxes", _EYRC_JITTER),
    "eyrc-upright": ("eyrc-jitter with the markers printed upright (the published pipeline then "
                     "warps to the outer corners)", {**_EYRC_JITTER, "markers.rotation_deg": 0.0}),
    "eyrc-oblique": ("eyrc-jitter seen obliquely: tilt 10-30 deg, any heading, higher camera",
                     {**_EYRC_JITTER, "camera.tilt_deg": Range(10.0, 30.0),
                      "camera.yaw_deg": Range(-180.0, 180.0),
                      "camera.altitude_m": Range(9.5, 11.0),
                      "camera.target_x_m": Range(-0.3, 0.3),
                      "camera.target_y_m": Range(-0.3, 0.3)}),
    "eyrc-hard": ("eyrc-jitter as a real drone sees it: more tilt and altitude spread, varied "
                  "light and shadows, sensor noise, blur, exposure, vignetting, JPEG", _EYRC_HARD),
    "warehouse": ("an arena marked on a warehouse floor: concrete with stains and painted lanes, "
                  "wooden pallets and coloured crates, tape and paper clutter", _WAREHOUSE),
}

#: Named presets: name -> (description, parameters), ``eyrc`` first. ``eyrc`` is the preset
#: file :data:`PRESET_FILES` names (read on first use); ``--preset`` also takes a preset file
#: (:func:`arenabench.generator.parameters.presets.resolve_preset`).
PRESETS: Mapping[str, tuple[str, dict[str, Value]]] = _Presets(
    (*PRESET_FILES, *_IN_CODE), _IN_CODE)


#: The preset every command uses unless told otherwise: the hidden-test twin.
DEFAULT_PRESET = "eyrc"


def preset_name(preset: Any) -> str:
    """The name GT files and reports record for ``preset`` (a name, or a
    :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`)."""
    return preset if isinstance(preset, str) else str(preset.name)


def preset_names() -> list[str]:
    """Names of the built-in presets."""
    return list(PRESETS)


def get_preset(name: Any) -> dict[str, Value]:
    """A copy of preset ``name``'s parameters (``name``: a built-in preset's name, or a
    :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`).

    Raises
    ------
    ValueError
        For an unknown name (the message lists the known ones).
    """
    if not isinstance(name, str):  # a ResolvedPreset (a preset file)
        return dict(name.params)
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}{did_you_mean(name, PRESETS)} "
                         f"(known: {', '.join(PRESETS)})")
    return dict(PRESETS[name][1])


def resolve(preset: Any, overrides: dict[str, Value] | None = None) -> dict[str, Value]:
    """Preset parameters with ``overrides`` applied, every value validated (``preset``: a
    name, a parameter mapping or a
    :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`;
    :func:`arenabench.generator.parameters.param_values.resolve_params`)."""
    return resolve_params(dict(preset) if isinstance(preset, Mapping) else get_preset(preset),
                          overrides)


def resolve_preset(value: str | ResolvedPreset) -> ResolvedPreset:
    """What ``--preset VALUE`` names: a value naming an existing file is a preset file
    (:func:`load_preset_file`), anything else a built-in preset's name.

    Raises
    ------
    ValueError
        One line: an unknown name (with "did you mean" and the known names), a path that
        does not exist, or the preset file's problem (:class:`PresetFileError`).
    """
    if isinstance(value, ResolvedPreset):
        return value
    text = str(value)
    if text in PRESETS and not os.path.isfile(text):
        return builtin_preset(text)
    if text and os.path.lexists(text):
        if os.path.isdir(text):
            raise ValueError(f"preset file {text}: a folder, not a preset file (a set's "
                             "preset: give its dataset.json)")
        return load_preset_file(text)
    if os.sep in text or Path(text).suffix.lower() in (".toml", ".json"):
        raise ValueError(f"preset file {text}: no such file")
    raise ValueError(f"unknown preset {text!r}{did_you_mean(text, PRESETS)} (known: "
                     f"{', '.join(PRESETS)}; or the path of a preset file)")


_BUILTIN: dict[str, ResolvedPreset] = {}


def preset_key(preset: ResolvedPreset) -> str:
    """A name for folders of sets made from ``preset``: its name when its parameters are the
    built-in preset's of that name, else ``<name>-<10 hex digits of their hash>``
    (:func:`~arenabench.generator.parameters.preset_files.preset_hash`)."""
    if preset.name in PRESETS and builtin_preset(preset.name).params == preset.params:
        return preset.name
    return f"{preset.name}-{preset_hash(preset.params)}"


def builtin_preset(name: str) -> ResolvedPreset:
    """The built-in preset ``name`` (:data:`arenabench.generator.parameters.presets.PRESETS`),
    resolved.

    Raises
    ------
    ValueError
        For an unknown name (the message lists the known ones).
    """
    if name in _BUILTIN:
        return _BUILTIN[name]
    if name in PRESET_FILES:
        made = load_preset_file(PRESET_FILES[name])
        if made.name != name:  # pragma: no cover - a packaging error
            raise ValueError(f"{PRESET_FILES[name]}: [preset] name is {made.name!r}, not "
                             f"{name!r}")
    else:
        params = resolve(get_preset(name))
        made = ResolvedPreset(name=name, params=params, description=PRESETS[name][0])
    _BUILTIN[name] = made
    return made
