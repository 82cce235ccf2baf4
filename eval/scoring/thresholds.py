"""``--fail-under`` thresholds: parse ``metric=value`` specs and check a summary against them.

The names and directions come from the metric registry
(:data:`arenabench.eval.scoring.metric_registry.GATED`): a metric where higher is better (pass
rate, its CI's lower end, count exact rate, marker id accuracy) is a minimum, the run fails when it
is *below* the value; one where lower is better (errors, latencies, failure counts and rates) is a
maximum, the run fails when it is *above*; a signed error fails when its magnitude is above.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from .metric_registry import GATED, METRIC, lookup, split_metric_specs
from .results import Summary


@dataclass(frozen=True)
class Threshold:
    """One ``metric=value`` limit; ``minimum`` says which direction fails."""

    metric: str
    value: float
    minimum: bool

    def check(self, summary: Summary) -> str | None:
        """``None`` when met, else a one-line reason."""
        actual = lookup(summary.to_dict(), self.metric)
        if actual is None or not math.isfinite(actual):
            return f"{self.metric} is not available (no data) but a threshold {self.value:g} is set"
        if self.minimum and actual < self.value:
            return f"{self.metric} {actual:.4g} < {self.value:g}"
        if METRIC[self.metric].direction == "nearer_zero" and abs(actual) > self.value:
            return f"|{self.metric}| {abs(actual):.4g} > {self.value:g} (maximum)"
        if not self.minimum and actual > self.value:
            return f"{self.metric} {actual:.4g} > {self.value:g} (maximum)"
        return None

    def gate_line(self, summary: Summary) -> str:
        """One line saying the gate, the value found and the outcome, for the log:
        ``gate pass_rate >= 0.95: 0.9667: pass`` (or ``FAILED``)."""
        actual = lookup(summary.to_dict(), self.metric)
        nearer = METRIC[self.metric].direction == "nearer_zero"
        name = f"|{self.metric}|" if nearer else self.metric
        if actual is None or not math.isfinite(actual):
            found = "no data"
        else:
            found = f"{abs(actual) if nearer else actual:.4g}"
        outcome = "pass" if self.check(summary) is None else "FAILED"
        return f"gate {name} {'>=' if self.minimum else '<='} {self.value:g}: {found}: {outcome}"


def parse_thresholds(specs: Iterable[str]) -> list[Threshold]:
    """Parse ``"pass_rate=0.95"`` specs (each may hold several, comma-separated).

    Raises
    ------
    ValueError
        Naming the bad spec, metric or value (a metric twice, a value it cannot reach:
        :meth:`~arenabench.eval.scoring.metric_registry.Metric.check_limit`).
    """
    out: list[Threshold] = []
    for name, raw in split_metric_specs(specs, option="--fail-under",
                                        known=[m.name for m in GATED]):
        value = METRIC[name].check_limit(raw, option="--fail-under")
        out.append(Threshold(metric=name, value=value, minimum=METRIC[name].minimum))
    return out


def check_thresholds(summary: Summary, thresholds: Iterable[Threshold]) -> list[str]:
    """Reasons for every threshold missed (empty when all are met)."""
    return [r for t in thresholds if (r := t.check(summary)) is not None]
