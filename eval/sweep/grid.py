"""Sweep axes: ``--vary KEY=SPEC`` parsing, grid points and random points.

A ``--vary`` is an override of the preset parameter ``KEY`` (any name of
:data:`arenabench.generator.parameters.presets.PARAMETERS`), so every parameter the generator knows
can be
swept. ``SPEC`` is one of

- ``a:b:step``: ``a, a+step, ...`` up to ``b`` inclusive (``step`` may be negative, e.g.
  ``jpeg.quality=95:15:-20``);
- ``a:b``: five evenly spaced values from ``a`` to ``b`` in a grid; the continuous range in a
  random sweep;
- ``v1,v2,...``: these values, in this order (numbers, or words for text parameters);
- ``v``: one value.

The **first value is the easy end** of the axis: breakdown points are scanned away from it.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from arenabench.generator.parameters.param_values import canonical_key, format_value, validate_value
from arenabench.generator.parameters.params import PARAMETERS, Range
from arenabench.plain_numbers import plain_number

#: Values a two-part ``a:b`` range gives in a grid sweep.
DEFAULT_RANGE_STEPS = 5
#: Most values one axis may have (guards against ``0:1000:0.001``).
MAX_AXIS_VALUES = 10000


@dataclass(frozen=True)
class Axis:
    """One varied parameter.

    Attributes
    ----------
    key : str
        Preset parameter name (``camera.tilt_deg``).
    spec : str
        The ``SPEC`` as written.
    values : tuple
        Grid values in the order given (validated; the first is the easy end).
    lo, hi : float or None
        Ends of a continuous ``a:b`` range (random sweeps draw uniformly from it); ``None`` for
        stepped ranges and lists (random sweeps pick one of ``values``).
    """

    key: str
    spec: str
    values: tuple[Any, ...]
    lo: float | None = None
    hi: float | None = None

    @property
    def numeric(self) -> bool:
        """Whether the values are numbers (plots use a numeric x axis)."""
        return PARAMETERS[self.key].kind in ("float", "int")

    @property
    def continuous(self) -> bool:
        """Whether a random sweep draws from a continuous range (``a:b``)."""
        return self.lo is not None

    def to_dict(self) -> dict[str, Any]:
        """JSON form (``sweep.json["vary"]`` entries)."""
        out: dict[str, Any] = {"key": self.key, "spec": self.spec, "values": list(self.values)}
        if self.continuous:
            out["range"] = [self.lo, self.hi]
        return out


def _fail(key: str, spec: str, why: str) -> ValueError:
    return ValueError(f"--vary {key}={spec}: {why}")


def _validated(key: str, spec: str, value: Any) -> Any:
    try:
        out = validate_value(key, value)
    except ValueError as exc:
        raise _fail(key, spec, str(exc).replace(f"--set {key}: ", "")) from None
    if isinstance(out, Range):
        raise _fail(key, spec, f"value {value!r} is a range, not a single value")
    return out


def _number(key: str, spec: str, text: str) -> float:
    try:
        value = plain_number(text.strip(" "))  # plain ASCII decimal, as every number typed
    except ValueError:
        raise _fail(key, spec, f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise _fail(key, spec, f"{text!r} is not a finite number")
    return value


def _stepped(key: str, spec: str, a: float, b: float, step: float) -> list[float]:
    if step == 0 or (b - a) * step < 0:
        raise _fail(key, spec, f"step {step:g} does not lead from {a:g} to {b:g}")
    n = math.floor((b - a) / step + 1e-9) + 1
    if n > MAX_AXIS_VALUES:
        raise _fail(key, spec, f"{n} values (at most {MAX_AXIS_VALUES})")
    # multiply, do not accumulate: 0:40:5 gives exactly 0, 5, ..., 40
    return [round(a + i * step, 10) for i in range(n)]


def parse_vary(text: str) -> Axis:
    """Parse one ``KEY=SPEC``.

    Parameters
    ----------
    text : str
        E.g. ``"camera.tilt_deg=0:40:5"``, ``"noise.sigma=0,5,10"``, ``"lighting.ambient=0.3:0.9"``.

    Returns
    -------
    Axis

    Raises
    ------
    ValueError
        One line naming the key and the spec: unknown parameter (as ``--set`` reports it), a
        malformed spec, a value of the wrong type or out of the parameter's bounds.
    """
    if "=" not in text:
        raise ValueError(f"--vary: expected KEY=SPEC, got {text!r}")
    key, spec = (s.strip() for s in text.split("=", 1))
    key = canonical_key(key)
    if key not in PARAMETERS:
        try:
            validate_value(key, spec)
        except ValueError as exc:
            raise ValueError(str(exc).replace("--set:", f"--vary {key}={spec}:")) from None
    if not spec:
        raise _fail(key, spec, "empty spec")
    numeric = PARAMETERS[key].kind in ("float", "int")
    lo = hi = None
    if numeric and ":" in spec:
        parts = spec.split(":")
        if len(parts) not in (2, 3) or not all(p.strip() for p in parts):
            raise _fail(key, spec, "a range is a:b or a:b:step")
        nums = [_number(key, spec, p.strip()) for p in parts]
        if len(nums) == 3:
            raw: list[Any] = _stepped(key, spec, *nums)
        else:
            a, b = nums
            if a == b:
                raise _fail(key, spec, "empty range (a == b); give one value instead")
            raw = [round(float(v), 10) for v in np.linspace(a, b, DEFAULT_RANGE_STEPS)]
            if PARAMETERS[key].kind == "int":
                raw = list(dict.fromkeys(round(v) for v in raw))
            lo, hi = a, b
        values = [_validated(key, spec, v) for v in raw]
        if lo is not None:
            _validated(key, spec, lo)
            _validated(key, spec, hi)
    elif PARAMETERS[key].kind in ("rgb", "ids"):
        # colours and id lists hold commas themselves: alternatives are separated by ';'
        values = [_validated(key, spec, v.strip()) for v in spec.split(";")]
    else:
        values = [_validated(key, spec, v.strip()) for v in spec.split(",")]
    if len(set(map(repr, values))) != len(values):
        raise _fail(key, spec, "values repeat")
    return Axis(key=key, spec=spec, values=tuple(values), lo=lo, hi=hi)


def parse_varies(items: list[str]) -> tuple[Axis, ...]:
    """Parse several ``KEY=SPEC`` (each key at most once).

    Raises
    ------
    ValueError
        For a bad spec or a key given twice.
    """
    axes = tuple(parse_vary(t) for t in items)
    keys = [a.key for a in axes]
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise ValueError(f"--vary: parameter {dup[0]!r} is varied twice")
    return axes


def grid_points(axes: tuple[Axis, ...]) -> list[dict[str, Any]]:
    """Every combination of the axes' values (the first axis varies slowest).

    Returns
    -------
    list of dict
        ``[{key: value, ...}, ...]``; one empty point when there are no axes.
    """
    combos = itertools.product(*(a.values for a in axes))
    return [dict(zip((a.key for a in axes), combo, strict=True)) for combo in combos]


def random_points(axes: tuple[Axis, ...], *, n: int, rng: np.random.Generator) -> list[dict]:
    """``n`` points drawn independently per axis.

    A continuous ``a:b`` axis is drawn uniformly from ``[min, max]`` (integers inclusive for
    integer parameters; floats rounded to 6 decimals); a stepped range or a list is drawn
    uniformly from its values.

    Parameters
    ----------
    axes : tuple of Axis
    n : int, keyword-only
        Number of points (>= 1).
    rng : numpy.random.Generator, keyword-only
        The only source of randomness.
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    points: list[dict[str, Any]] = []
    for _ in range(int(n)):
        point: dict[str, Any] = {}
        for axis in axes:
            if axis.continuous:
                a, b = sorted((float(axis.lo), float(axis.hi)))  # type: ignore[arg-type]
                if PARAMETERS[axis.key].kind == "int":
                    value: Any = int(rng.integers(math.ceil(a), math.floor(b) + 1))
                else:
                    value = round(float(rng.uniform(a, b)), 6)
            else:
                value = axis.values[int(rng.integers(len(axis.values)))]
            point[axis.key] = value
        points.append(point)
    return points


def point_label(params: dict[str, Any]) -> str:
    """``key=value`` pairs of a point, comma-separated (``--set`` spellings)."""
    return ", ".join(f"{k}={format_value(v)}" for k, v in params.items()) or "(preset)"
