"""Parameter values: ``--set key=value`` parsing, validation against each parameter's
declaration (:data:`arenabench.generator.parameters.params.PARAMS`: kind, bounds, choices) and the
``--set`` spelling of a value. Ranges are written ``"lo:hi"`` on the command line and
``[lo, hi]`` in JSON: uniform over [lo, hi) for real parameters, over the integers lo..hi
inclusive for integer ones; anything undeclared is refused with an error naming the key."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from arenabench.generator.parameters.params import DEFAULTS, PARAMETERS, Param, Range, Value
from arenabench.limits import shown, text_problem
from arenabench.plain_numbers import plain_number
from arenabench.suggest import did_you_mean


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
    return repr((raw.lo, raw.hi)) if isinstance(raw, Range) else shown(raw)


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
        return _numeric(key, value, spec)
    return _BY_KIND.get(spec.kind, _text)(key, value, spec)


def _numeric(key: str, value: Value, spec: Param) -> Value:
    """A number, or a range of them (a :class:`Range`, or two ends in a list or tuple)."""
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


def _bool(key: str, value: Value, spec: Param) -> bool:
    """``true``/``false`` (and 1/0, yes/no, on/off)."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise ValueError(f"--set {key}: invalid bool value {value!r} (true/false)")


def _integers(key: str, value: Value, spec: Param) -> tuple[int, ...]:
    """An RGB colour (three 0..255) or four distinct marker ids (>= 0): ``"a,b,c"`` or a
    list."""
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


def _text(key: str, value: Value, spec: Param) -> str:
    """Printable text of bounded length, one of the choices where the parameter has them."""
    text = str(value)
    if (problem := text_problem(text)) is not None:
        raise ValueError(f"--set {key}: {problem}")
    if spec.choices and text not in spec.choices:
        raise ValueError(f"--set {key}: invalid value {text!r} (choices: "
                         f"{', '.join(spec.choices)})")
    return text


def _size(key: str, value: Value, spec: Param) -> tuple[float, float]:
    """A width and a height: ``"w,h"`` or two numbers, each within the parameter's bounds."""
    parts = value.split(",") if isinstance(value, str) else value
    if isinstance(parts, Range) or not isinstance(parts, (list, tuple)) or len(parts) != 2:
        raise ValueError(f"--set {key}: expected a width and a height (w,h), got {value!r}")
    if any(isinstance(p, bool) for p in parts):
        raise ValueError(f"--set {key}: invalid size {value!r}")
    sides = tuple(float(_number(key, str(p), "float")) for p in parts)
    for side in sides:
        _check_bounds(key, side, spec, value)
    return sides  # type: ignore[return-value]


def _file(key: str, value: Value, spec: Param | None = None) -> str:
    """An image file's reference (``textures/<sha256>.png``): a reference the texture cache
    holds, or a path (relative to the working folder), read into the cache; ``""``: none."""
    from arenabench.generator.assets import texture_store

    if not isinstance(value, str):
        raise ValueError(f"--set {key}: expected a file's path, got {value!r}")
    if not value:
        return ""
    try:
        if texture_store.is_ref(value):  # the cache's (or a textures/ folder here)
            if texture_store.has(value):  # every scene's resolve() comes here: a stat
                return value
            return texture_store.import_ref(value, Path.cwd(), where=value)
        return texture_store.import_texture(value)
    except ValueError as exc:
        raise ValueError(f"--set {key}: {exc}") from None


#: How a value of each non-numeric kind is checked (any other kind: text).
_BY_KIND: dict[str, Callable[[str, Value, Param], Value]] = {
    "bool": _bool, "size": _size, "file": _file, "rgb": _integers, "ids": _integers}


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


def resolve_params(params: Mapping[str, Value],
                   overrides: Mapping[str, Value] | None = None) -> dict[str, Value]:
    """``params`` over the defaults, with ``overrides`` applied, every value validated.

    Raises
    ------
    ValueError
        Naming the key and value of the first bad one, or the parameters missing.
    """
    merged = {**DEFAULTS, **params, **(overrides or {})}
    missing = sorted(set(PARAMETERS) - set(merged))
    if missing:
        raise ValueError(f"preset lacks parameters: {', '.join(missing)}")
    return {k: validate_value(k, v) for k, v in merged.items()}
