"""``--fail-under`` thresholds: parse ``metric=value`` specs and check a summary against them.

Rates (``pass_rate``, ``pass_rate_ci95.0``, ``count_exact_rate``, ``marker_id_accuracy``) are
minimums: the run fails when the metric is *below* the value. Errors, latencies and failure
counts (``count_mae``, ``area_rel_err.median|p95|max``, ``latency_ms.median|p95``,
``failures.<category>``) are maximums: the run fails when the metric is *above* the value.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from arenabench.suggest import did_you_mean

from .compare import lookup
from .records import CATEGORIES, Summary

MINIMUMS: tuple[str, ...] = (
    "pass_rate",
    "pass_rate_ci95.0",
    "count_exact_rate",
    "marker_id_accuracy",
)
MAXIMUMS: tuple[str, ...] = (
    "count_mae",
    "area_rel_err.median",
    "area_rel_err.p95",
    "area_rel_err.max",
    "latency_ms.median",
    "latency_ms.p95",
    *(f"failures.{c}" for c in CATEGORIES),
)


@dataclass(frozen=True)
class Threshold:
    """One ``metric=value`` limit; ``minimum`` says which direction fails."""

    metric: str
    value: float
    minimum: bool

    def check(self, summary: Summary) -> str | None:
        """``None`` when met, else a one-line reason."""
        d = summary.to_dict()
        if self.metric == "pass_rate_ci95.0":
            actual = summary.pass_rate_ci95[0]
        else:
            actual = lookup(d, self.metric)
        if actual is None or not math.isfinite(actual):
            return f"{self.metric} is not available (no data) but a threshold {self.value:g} is set"
        if self.minimum and actual < self.value:
            return f"{self.metric} {actual:.4g} < {self.value:g}"
        if not self.minimum and actual > self.value:
            return f"{self.metric} {actual:.4g} > {self.value:g} (maximum)"
        return None


def parse_thresholds(specs: Iterable[str]) -> list[Threshold]:
    """Parse ``"pass_rate=0.95"`` specs (each may hold several, comma-separated).

    Raises
    ------
    ValueError
        Naming the bad spec, metric or value.
    """
    out: list[Threshold] = []
    for spec in specs:
        for part in spec.split(","):
            part = part.strip()
            if not part:
                continue
            name, sep, raw = part.partition("=")
            name = name.strip()
            if not sep:
                raise ValueError(f"--fail-under expects metric=value, got {part!r}")
            if name not in MINIMUMS and name not in MAXIMUMS:
                known = ", ".join((*MINIMUMS, *MAXIMUMS))
                hint = did_you_mean(name, (*MINIMUMS, *MAXIMUMS)) or f" (known: {known})"
                raise ValueError(f"--fail-under: unknown metric {name!r}{hint}")
            try:
                value = float(raw)
            except ValueError:
                raise ValueError(
                    f"--fail-under: value of {name!r} is not a number: {raw!r}"
                ) from None
            if not math.isfinite(value):
                raise ValueError(f"--fail-under: value of {name!r} is not finite: {raw!r}")
            out.append(Threshold(metric=name, value=value, minimum=name in MINIMUMS))
    return out


def check_thresholds(summary: Summary, thresholds: Iterable[Threshold]) -> list[str]:
    """Reasons for every threshold missed (empty when all are met)."""
    return [r for t in thresholds if (r := t.check(summary)) is not None]
