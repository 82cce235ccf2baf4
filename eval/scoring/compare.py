"""Compare two reports: metrics side by side and images that changed verdict."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .metric_registry import GATED, METRIC, Metric, fmt, lookup, split_metric_specs
from .results import Report

#: The metrics compared, in report order (the registry's gated metrics).
COMPARED_METRICS: tuple[Metric, ...] = GATED


@dataclass(frozen=True)
class Comparison:
    """What changed between two reports."""

    metrics: list[tuple[str, Any, Any, str]]  # (name, old, new, direction of the registry)
    newly_failing: list[tuple[str, str | None]]  # (id, new category)
    newly_passing: list[tuple[str, str | None]]  # (id, old category)
    category_changed: list[tuple[str, str | None, str | None]]
    only_old: list[str]
    only_new: list[str]


def dataset_problem(old: Report, new: Report, *, old_name: str = "old",
                    new_name: str = "new") -> tuple[str | None, str | None]:
    """Whether two reports can be compared image by image: ``(problem, warning)``.

    ``problem`` (one line) when their ``manifest_sha256`` differ: the same id names unrelated
    scenes in two datasets. ``warning`` when a report has none (written before the key
    existed, or of a dataset made in memory): the images are then matched by id unchecked.
    """
    a, b = old.manifest_sha256, new.manifest_sha256
    if a is not None and b is not None and a != b:
        return (f"--compare: {old_name} and {new_name} are reports on different datasets "
                f"(manifest sha256 {a[:12]} vs {b[:12]}): the same image id names unrelated "
                "scenes there; compare two runs on one dataset"), None
    missing = [n for n, r in ((old_name, old), (new_name, new)) if r.manifest_sha256 is None]
    if missing:
        return None, (f"{' and '.join(missing)} record no manifest_sha256: images are matched "
                      "by id without checking that both reports scored the same dataset")
    return None, None


def compare(old: Report, new: Report) -> Comparison:
    """Compare ``old`` with ``new`` (images matched by id)."""
    so, sn = old.summary.to_dict(), new.summary.to_dict()
    metrics = [(m.name, lookup(so, m.name), lookup(sn, m.name), m.direction)
               for m in COMPARED_METRICS]
    a = {r.id: r for r in old.images}
    b = {r.id: r for r in new.images}
    common = [i for i in a if i in b]
    return Comparison(
        metrics=metrics,
        newly_failing=[(i, b[i].category) for i in common if a[i].passed and not b[i].passed],
        newly_passing=[(i, a[i].category) for i in common if not a[i].passed and b[i].passed],
        category_changed=[
            (i, a[i].category, b[i].category)
            for i in common
            if not a[i].passed and not b[i].passed and a[i].category != b[i].category
        ],
        only_old=[i for i in a if i not in b],
        only_new=[i for i in b if i not in a],
    )


def format_comparison(cmp: Comparison, *, old_name: str = "old", new_name: str = "new") -> str:
    """Plain-text rendering: a metrics table (with better/worse marks) and verdict changes."""
    rows = [("metric", old_name, new_name, "change")]
    for name, o, n, _ in cmp.metrics:
        change = ""
        if isinstance(o, (int, float)) and isinstance(n, (int, float)) and o != n:
            better = METRIC[name].worsening(o, n) < 0
            change = f"{n - o:+.4g} ({'better' if better else 'worse'})"
        rows.append((name, fmt(o), fmt(n), change))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.append("")
    lines.append(f"pass -> fail: {len(cmp.newly_failing)}")
    lines += [f"  {i}: now {c}" for i, c in cmp.newly_failing]
    lines.append(f"fail -> pass: {len(cmp.newly_passing)}")
    lines += [f"  {i}: was {c}" for i, c in cmp.newly_passing]
    if cmp.category_changed:
        lines.append(f"failure category changed: {len(cmp.category_changed)}")
        lines += [f"  {i}: {o} -> {n}" for i, o, n in cmp.category_changed]
    if cmp.only_old or cmp.only_new:
        lines.append(f"images only in old: {len(cmp.only_old)}; only in new: {len(cmp.only_new)}")
    return "\n".join(lines) + "\n"


def parse_regression_limits(specs: list[str]) -> dict[str, float]:
    """Parse ``--fail-on-regression`` specs, ``metric=delta`` (comma-separated or repeated):
    the largest worsening of ``metric`` (in its own units) that still passes.

    Raises
    ------
    ValueError
        Naming the bad spec, metric (with a "did you mean" hint) or value.
    """
    out: dict[str, float] = {}
    for name, raw in split_metric_specs(specs, option="--fail-on-regression",
                                        known=[m.name for m in COMPARED_METRICS], what="delta"):
        out[name] = METRIC[name].check_limit(raw, option="--fail-on-regression")
    return out


def regression_gate_lines(cmp: Comparison, limits: dict[str, float]) -> list[str]:
    """One line per ``--fail-on-regression`` gate, passing or not, for the log:
    ``gate pass_rate worsens by at most 0.02: 0.95 -> 0.94: pass`` (``FAILED``; ``not judged``
    when a report lacks the metric)."""
    lines = []
    failed = {r.split(" ", 1)[0] for r in regressions(cmp, limits)}
    for name, old, new, _ in cmp.metrics:
        if name not in limits:
            continue
        judged = all(isinstance(v, (int, float)) for v in (old, new))
        outcome = "not judged" if not judged else "FAILED" if name in failed else "pass"
        lines.append(f"gate {name} worsens by at most {limits[name]:g}: {fmt(old)} -> "
                     f"{fmt(new)}: {outcome}")
    return lines


def regressions(cmp: Comparison, limits: dict[str, float]) -> list[str]:
    """One reason per metric of ``limits`` that got worse by more than its delta (a metric
    missing from either report is not judged)."""
    reasons = []
    for name, old, new, _ in cmp.metrics:
        if name not in limits or not all(isinstance(v, (int, float)) for v in (old, new)):
            continue
        worse = METRIC[name].worsening(old, new)
        if worse > limits[name]:
            reasons.append(f"{name} {fmt(old)} -> {fmt(new)} (worse by {worse:.4g}, more than "
                           f"{limits[name]:g})")
    return reasons
