"""The summary as (label, value) rows, shared by the Markdown and HTML reports and the CLI."""

from __future__ import annotations

from ..phase_check import PHASE_DEPENDENT_MEANING
from ..records import CATEGORIES, Report, Summary


def fmt(value: object, *, pct: bool = False, digits: int = 4) -> str:
    """Human form of a metric value (``-`` for missing)."""
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{100 * value:.1f} %" if pct else f"{value:.{digits}g}"
    return str(value)


def summary_rows(summary: Summary) -> list[tuple[str, str]]:
    """Every summary metric as a labelled string."""
    s = summary
    lo, hi = s.pass_rate_ci95
    a, sg = s.area_rel_err, s.area_rel_err_signed
    rows = [
        ("images", str(s.n)),
        ("pass rate", f"{fmt(s.pass_rate, pct=True)} ({s.n_passed}/{s.n})"),
        ("pass rate 95 % CI (Wilson)", f"{fmt(lo, pct=True)} - {fmt(hi, pct=True)}"),
        ("count exact rate", fmt(s.count_exact_rate, pct=True)),
        ("count MAE", fmt(s.count_mae)),
        (
            "|area rel err| median / p95 / max",
            " / ".join(fmt(a.get(k)) for k in ("median", "p95", "max")),
        ),
        (
            "signed area rel err median / p5 / p95",
            " / ".join(fmt(sg.get(k)) for k in ("median", "p5", "p95")),
        ),
        ("signed area rel err min / max", " / ".join(fmt(sg.get(k)) for k in ("min", "max"))),
        ("marker id accuracy", fmt(s.marker_id_accuracy, pct=True)),
        (
            "latency ms median / p95",
            " / ".join(fmt(s.latency_ms.get(k), digits=3) for k in ("median", "p95")),
        ),
    ]
    rows += phase_rows(s)
    rows += [(f"failures: {c}", str(s.failures.get(c, 0))) for c in CATEGORIES]
    return rows


def phase_rows(summary: Summary) -> list[tuple[str, str]]:
    """The phase check's rows (none when it did not run)."""
    pc = summary.phase_check
    if pc is None:
        return []
    return [
        ("robust failures (fail at every phase)",
         f"{fmt(summary.robust_failure_rate, pct=True)} ({pc['robust']}/{summary.n})"),
        ("phase-dependent failures",
         f"{fmt(summary.phase_dependent_failure_rate, pct=True)} "
         f"({pc['phase_dependent']}/{summary.n}; {pc['phases']} phases per failure)"),
        ("phase-dependent means", PHASE_DEPENDENT_MEANING.split(": ", 1)[1]),
    ]


def headline(report: Report) -> str:
    """One line: pipeline, pass rate with CI, failures."""
    s = report.summary
    lo, hi = s.pass_rate_ci95
    fails = ", ".join(f"{c} {v}" for c, v in s.failures.items() if v) or "none"
    phase = ""
    if s.phase_check is not None:
        phase = (f"; robust failures {fmt(s.robust_failure_rate, pct=True)}, phase-dependent "
                 f"{fmt(s.phase_dependent_failure_rate, pct=True)}")
    return (
        f"{report.pipeline}: pass rate {fmt(s.pass_rate, pct=True)} ({s.n_passed}/{s.n}, "
        f"95 % CI {fmt(lo, pct=True)}-{fmt(hi, pct=True)}){phase}; failures: {fails}"
    )
