"""Per-parameter curves of a sweep and its **breakdown points**.

Grouping. A grid axis has one group per value given. A random sweep's continuous axis
(``a:b``) is cut into equal-width bins from the easy end ``a`` to ``b``, each represented by its
centre; a random sweep's stepped or listed axis has one group per value.

Pooling of the other axes (``breakdown_mode``):

- ``marginal`` (default): a group holds every image whose point has that value (or bin) of
  the parameter, whatever the other axes' values: the curve is averaged over the others;
- ``axis``: only points where every other axis is at its first (easy) value: the curve is the
  one-dimensional section through the easy corner (grid sweeps only).

Breakdown point of a parameter: scanning its groups from the easy end (the first value
given), the furthest value whose pass rate's lower 95 % Wilson bound is at least the
threshold, stopping at the first group that misses it; ``None`` when the first group already
misses it. Groups with no images (every scene skipped) count as misses.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from arenabench.eval.scoring.metrics import summarize
from arenabench.eval.scoring.results import ImageResult, Summary

from .grid import Axis

#: Bins of a random sweep's continuous axis.
RANDOM_BINS = 8


@dataclass(frozen=True)
class CurvePoint:
    """Metrics of one group of an axis.

    Attributes
    ----------
    value : Any
        The parameter value (bin centre for a binned axis).
    label : str
        Tick label.
    summary : Summary
        Harness summary over the group's images.
    """

    value: Any
    label: str
    summary: Summary


def _fmt(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def axis_groups(axis: Axis, *, random: bool, bins: int = RANDOM_BINS) -> list[tuple[Any, str]]:
    """The groups of an axis from the easy end: ``[(value, label), ...]``."""
    if random and axis.continuous:
        lo, hi = float(axis.lo), float(axis.hi)  # type: ignore[arg-type]
        edges = np.linspace(lo, hi, bins + 1)
        return [
            (round(float((a + b) / 2), 6), f"{_fmt(float(a))}..{_fmt(float(b))}")
            for a, b in itertools.pairwise(edges)
        ]
    return [(v, _fmt(v)) for v in axis.values]


def group_of(axis: Axis, value: Any, *, random: bool, bins: int = RANDOM_BINS) -> int:
    """Index of the group of ``axis`` that ``value`` falls in."""
    if random and axis.continuous:
        lo, hi = float(axis.lo), float(axis.hi)  # type: ignore[arg-type]
        t = (float(value) - lo) / (hi - lo)
        return int(min(max(int(np.floor(t * bins)), 0), bins - 1))
    return axis.values.index(value)


def _point_ok(params: dict[str, Any], axis: Axis, axes: Sequence[Axis], mode: str) -> bool:
    if mode == "marginal":
        return True
    return all(params[o.key] == o.values[0] for o in axes if o.key != axis.key)


def axis_curve(
    axis: Axis,
    *,
    axes: Sequence[Axis],
    points: Sequence[dict[str, Any]],
    results: dict[int, list[ImageResult]],
    random: bool,
    mode: str = "marginal",
    bins: int = RANDOM_BINS,
) -> list[CurvePoint]:
    """Metrics of one pipeline along one axis.

    Parameters
    ----------
    axis : Axis
        The parameter.
    axes : sequence of Axis, keyword-only
        All axes of the sweep.
    points : sequence of dict, keyword-only
        Point parameters by point index.
    results : dict, keyword-only
        Point index -> that pipeline's per-image results.
    random : bool, keyword-only
        Whether the sweep drew random points.
    mode : {"marginal", "axis"}, keyword-only
        How the other axes are pooled (module docstring).
    bins : int, keyword-only
        Bins of a random continuous axis.

    Returns
    -------
    list of CurvePoint
        One per group, from the easy end.
    """
    groups = axis_groups(axis, random=random, bins=bins)
    members: list[list[ImageResult]] = [[] for _ in groups]
    for p, params in enumerate(points):
        if _point_ok(params, axis, axes, mode):
            members[group_of(axis, params[axis.key], random=random, bins=bins)].extend(
                results.get(p, [])
            )
    return [
        CurvePoint(value=v, label=label,
                   summary=summarize([r.score for r in m], [r.prediction for r in m]))
        for (v, label), m in zip(groups, members, strict=True)
    ]


def breakdown_value(curve: Sequence[CurvePoint], *, threshold: float) -> Any:
    """Furthest value from the easy end whose pass-rate lower 95 % bound is >= ``threshold``
    (contiguous from the easy end), or ``None``."""
    best = None
    for point in curve:
        if point.summary.n == 0 or point.summary.pass_rate_ci95[0] < threshold:
            break
        best = point.value
    return best


def scenes_needed(threshold: float) -> int | None:
    """Fewest scenes, all passing, whose pass rate's lower 95 % Wilson bound reaches
    ``threshold`` (``None`` when no number does: a threshold of 1 or more)."""
    from arenabench.eval.scoring.metrics import wilson_interval

    if threshold >= 1.0:
        return None
    n = 1
    while wilson_interval(n, n)[0] < threshold:
        n *= 2
    lo = n // 2 + 1 if n > 1 else 1
    while lo < n:  # the smallest n in (n/2, n] that reaches it
        mid = (lo + n) // 2
        if wilson_interval(mid, mid)[0] >= threshold:
            n = mid
        else:
            lo = mid + 1
    return n


def breakdown_reason(curve: Sequence[CurvePoint], *, threshold: float) -> str:
    """Why a parameter has no breakdown point (:func:`breakdown_value` gave ``None``), in
    words: its first value fails, has no scenes, or passes on too few scenes for the pass
    rate's lower 95 % bound to reach ``threshold`` (then the point cannot be determined with
    this many scenes)."""
    first = curve[0].summary if curve else None
    if first is None or first.n == 0:
        return "none (no scenes at the first value)"
    if first.pass_rate < threshold:
        return "none (fails at the first value)"
    need = scenes_needed(threshold)
    more = (f"; at least {need} passing scenes per value are needed" if need is not None
            else "; no number of scenes can reach a threshold of 1")
    return (f"cannot be determined with {first.n} scene(s) at the first value (pass rate "
            f"{first.pass_rate:.0%}, but its lower 95 % bound {first.pass_rate_ci95[0]:.0%} "
            f"is below the threshold {threshold:g}{more})")


def breakdown_texts(result: Any) -> dict[str, dict[str, str]]:
    """``{pipeline: {parameter: text}}`` of a :class:`~arenabench.eval.sweep.records.SweepResult`:
    each breakdown point as its ``--set`` spelling, or :func:`breakdown_reason` where there is
    none."""
    from arenabench.generator.parameters.param_values import format_value

    spec = result.spec
    out: dict[str, dict[str, str]] = {}
    for pipe, values in result.breakdown.items():
        by_point: dict[int, list[ImageResult]] = {}
        for r in result.images:
            if r["pipeline"] == pipe:
                by_point.setdefault(r["point"], []).append(ImageResult.from_dict(r))
        texts = {}
        for axis in spec.axes:
            value = values.get(axis.key)
            if value is not None:
                texts[axis.key] = format_value(value)
                continue
            curve = axis_curve(axis, axes=spec.axes, points=result.points, results=by_point,
                               random=spec.random is not None, mode=spec.breakdown_mode)
            texts[axis.key] = breakdown_reason(curve, threshold=spec.threshold)
        out[pipe] = texts
    return out


def heat_grid(
    ax0: Axis,
    ax1: Axis,
    *,
    points: Sequence[dict[str, Any]],
    results: dict[int, list[ImageResult]],
    random: bool,
    bins: int = RANDOM_BINS,
) -> np.ndarray:
    """Pass rate over two axes (marginal over any others): array ``(len(g0), len(g1))``, NaN
    where a cell has no images."""
    g0 = axis_groups(ax0, random=random, bins=bins)
    g1 = axis_groups(ax1, random=random, bins=bins)
    passed = np.zeros((len(g0), len(g1)))
    total = np.zeros((len(g0), len(g1)))
    for p, params in enumerate(points):
        i = group_of(ax0, params[ax0.key], random=random, bins=bins)
        j = group_of(ax1, params[ax1.key], random=random, bins=bins)
        rs = results.get(p, [])
        passed[i, j] += sum(r.passed for r in rs)
        total[i, j] += len(rs)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, passed / np.maximum(total, 1), np.nan)
