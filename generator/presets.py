"""Named scene presets as data, and ``--set key=value`` override parsing and validation.

A preset maps dotted parameter names to a fixed value or a :class:`Range`. Ranges are written
``"lo:hi"`` on the command line and ``[lo, hi]`` in JSON: uniform over [lo, hi) for real
parameters, over the integers lo..hi inclusive for integer ones. Every parameter is declared
once in :data:`arenabench.generator.params.PARAMS` with its kind, bounds and neutral value;
anything else is refused with an error naming the key.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from arenabench.cliopts import plain_number
from arenabench.frame import COMPETITION_DICTIONARY
from arenabench.generator.params import DEFAULTS, NEUTRAL, PARAMETERS, Param, Range, Value
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
EXAMPLE_SCENE = Path(__file__).resolve().parent / "scenes" / "task1c_example.json"

#: Built-in presets kept as preset files (package data, docs/formats.md "Preset files"):
#: name -> file. The file is the preset's only source; its ``[preset]`` name is the key.
PRESET_FILES: dict[str, Path] = {
    "eyrc": Path(__file__).resolve().parent / "assets" / "presets" / "eyrc.toml",
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
            from arenabench.generator.preset_files import builtin_preset

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
#: (:func:`arenabench.generator.preset_files.resolve_preset`).
PRESETS: Mapping[str, tuple[str, dict[str, Value]]] = _Presets(
    (*PRESET_FILES, *_IN_CODE), _IN_CODE)


def preset_names() -> list[str]:
    """Names of the built-in presets."""
    return list(PRESETS)


def get_preset(name: Any) -> dict[str, Value]:
    """A copy of preset ``name``'s parameters (``name``: a built-in preset's name, or a
    :class:`~arenabench.generator.preset_files.ResolvedPreset`).

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


def _number(key: str, text: str, kind: str) -> float | int:
    try:
        value = plain_number(text.strip(" "))  # plain ASCII decimal, as every number typed
        if kind == "int":
            if value != int(value):
                raise ValueError
            return int(value)
        return value
    except (ValueError, OverflowError):
        raise ValueError(f"--set {key}: invalid {kind} value {text!r}") from None


def _check_bounds(key: str, value: float, spec: Param, raw: Any) -> None:
    b = spec.bounds
    if b is not None and not b.lo <= value <= b.hi:
        raise ValueError(f"--set {key}: value {_shown(raw)} out of range [{b.lo:g}, {b.hi:g}]")


def _check_choice(key: str, number: float | int, spec: Param, raw: Any) -> float | int:
    """``number`` when it is one of an int parameter's choices (or it has none)."""
    if spec.choices and str(number) not in spec.choices:
        raise ValueError(f"--set {key}: invalid value {_shown(raw)} (choices: "
                         f"{', '.join(spec.choices)})")
    return number


def _shown(raw: Any) -> str:
    """``raw`` as error messages show it (a range as ``(lo, hi)``, like the input tuple)."""
    return repr((raw.lo, raw.hi)) if isinstance(raw, Range) else repr(raw)


#: Short names accepted wherever a parameter is named (``--set``, ``--vary``); results and GT
#: always use the canonical name on the right.
ALIASES: dict[str, str] = {
    "noise.sigma": "degrade.noise_sigma",
    "noise.poisson_photons": "degrade.poisson_photons",
    "blur.motion_px": "degrade.motion_blur_px",
    "blur.defocus_px": "degrade.defocus_px",
    "jpeg.quality": "degrade.jpeg_quality",
    "exposure.ev": "degrade.exposure_ev",
}


def canonical_key(key: str) -> str:
    """The canonical parameter name for ``key`` (itself, or what an alias stands for)."""
    return ALIASES.get(key, key)


def validate_value(key: str, value: Value) -> Value:
    """Check and normalise a parameter value (fixed or range) for ``key``.

    A range may be given as a :class:`Range` or as a two-item list or tuple (JSON); it is
    returned as a :class:`Range` (a range with equal ends as that one value).

    Raises
    ------
    ValueError
        Naming the key and the value: unknown key, wrong type, out of bounds, bad range.
    """
    if key not in PARAMETERS:
        raise ValueError(f"--set: unknown parameter {key!r}"
                         f"{did_you_mean(key, [*PARAMETERS, *ALIASES])} (list them: "
                         "arenabench presets --params)")
    spec = PARAMETERS[key]
    if spec.numeric:
        if isinstance(value, (Range, tuple, list)):
            ends = (value.lo, value.hi) if isinstance(value, Range) else tuple(value)
            if len(ends) != 2:
                raise ValueError(f"--set {key}: a range needs two ends, got {value!r}")
            lo, hi = (_number(key, str(v), spec.kind) for v in ends)
            if lo > hi:
                raise ValueError(f"--set {key}: empty range {_shown(value)} (lo > hi)")
            _check_bounds(key, lo, spec, value)
            _check_bounds(key, hi, spec, value)
            if lo == hi:
                return _check_choice(key, lo, spec, value)
            if spec.choices and not spec.values_in(lo, hi):
                raise ValueError(f"--set {key}: range {_shown(value)} holds none of the "
                                 f"choices {', '.join(spec.choices)}")
            return Range(lo, hi)
        if isinstance(value, bool):
            raise ValueError(f"--set {key}: invalid {spec.kind} value {value!r}")
        number = _number(key, str(value), spec.kind)
        _check_bounds(key, number, spec, value)
        return _check_choice(key, number, spec, value)
    if spec.kind == "bool":
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in ("1", "true", "yes", "on"):
            return True
        if text in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"--set {key}: invalid bool value {value!r} (true/false)")
    if spec.kind in ("rgb", "ids"):
        parts = value.split(",") if isinstance(value, str) else list(value)
        want = 3 if spec.kind == "rgb" else 4
        try:
            nums = tuple(int(plain_number(str(p).strip(" "), "int")) for p in parts)
        except ValueError:
            raise ValueError(f"--set {key}: invalid value {value!r}") from None
        if len(nums) != want:
            raise ValueError(f"--set {key}: expected {want} comma-separated integers, "
                             f"got {value!r}")
        if spec.kind == "rgb" and not all(0 <= n <= 255 for n in nums):
            raise ValueError(f"--set {key}: colour values must be 0..255, got {value!r}")
        if spec.kind == "ids" and not all(n >= 0 for n in nums):
            raise ValueError(f"--set {key}: ids must be >= 0, got {value!r}")
        if spec.kind == "ids" and len(set(nums)) != len(nums):
            raise ValueError(f"--set {key}: the four corners' ids must differ (a pipeline tells "
                             f"the corners apart by them), got {value!r}")
        return nums
    text = str(value)
    if spec.choices and text not in spec.choices:
        raise ValueError(f"--set {key}: invalid value {text!r} (choices: "
                         f"{', '.join(spec.choices)})")
    return text


def parse_override(text: str) -> tuple[str, Value]:
    """Parse one ``key=value`` (``value`` may be ``lo:hi``) into a validated pair.

    Raises
    ------
    ValueError
        When the text has no ``=``, or the key or value is invalid.
    """
    if "=" not in text:
        raise ValueError(f"--set: expected key=value, got {text!r}")
    key, raw = (s.strip() for s in text.split("=", 1))
    key = canonical_key(key)
    if key not in PARAMETERS:
        validate_value(key, raw)
    spec = PARAMETERS[key]
    if spec.numeric and ":" in raw:
        lo, _, hi = raw.partition(":")
        return key, validate_value(key, (lo, hi))
    return key, validate_value(key, raw)


def parse_overrides(items: list[str] | None) -> dict[str, Value]:
    """Parse a list of ``key=value`` strings (later ones win)."""
    out: dict[str, Value] = {}
    for item in items or []:
        key, value = parse_override(item)
        out[key] = value
    return out


def resolve(preset: Any, overrides: dict[str, Value] | None = None) -> dict[str, Value]:
    """Preset parameters with ``overrides`` applied, every value validated (``preset``: a
    name, a parameter mapping or a
    :class:`~arenabench.generator.preset_files.ResolvedPreset`)."""
    params = dict(preset) if isinstance(preset, Mapping) else get_preset(preset)
    params = {**DEFAULTS, **params}
    for key, value in (overrides or {}).items():
        params[key] = value
    missing = sorted(set(PARAMETERS) - set(params))
    if missing:
        raise ValueError(f"preset lacks parameters: {', '.join(missing)}")
    return {k: validate_value(k, v) for k, v in params.items()}


def format_value(value: Value) -> str:
    """The ``--set`` spelling of a value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Range):
        return str(value)
    if isinstance(value, tuple):
        return ",".join(str(v) for v in value)
    if isinstance(value, float):
        return f"{value:.10g}"
    return str(value)
