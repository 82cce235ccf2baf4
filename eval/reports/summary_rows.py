"""The summary as (label, value) rows, shared by the Markdown and HTML reports and the CLI."""

from __future__ import annotations

from typing import Any

from arenabench.eval.scoring.metric_registry import (
    METRIC,
    ROW_SEPARATORS,
    fmt,
    summary_row_groups,
)
from arenabench.eval.scoring.phase_summary import PHASE_DEPENDENT_MEANING, verdict_words
from arenabench.eval.scoring.results import Report, Summary

#: Columns of a breakdown table (a row per bin of a scene parameter; report.json's
#: ``breakdown``).
BREAKDOWN_COLUMNS: tuple[str, ...] = (
    "bin", "n", "pass rate", "count exact", "median |area err|", "failures",
)


def breakdown_cells(row: dict) -> tuple[str, ...]:
    """One bin's cells, in :data:`BREAKDOWN_COLUMNS` order (plain text: the writer escapes)."""
    fails = ", ".join(f"{c} {v}" for c, v in row["failures"].items()) or "-"
    return (str(row["bin"]), str(row["n"]), fmt(row["pass_rate"], pct=True),
            fmt(row["count_exact_rate"], pct=True), fmt(row["area_rel_err_median"]), fails)


def summary_rows(summary: Summary) -> list[tuple[str, str]]:
    """Every summary metric as a labelled string (rows from the metric registry)."""
    s = summary
    d = s.to_dict()
    rows = [("images", str(s.n))]
    for row, metrics in summary_row_groups("summary"):
        text = ROW_SEPARATORS.get(row, " / ").join(m.format(m.value(d)) for m in metrics)
        if row == METRIC["pass_rate"].row:
            text += f" ({s.n_passed}/{s.n})"
        rows.append((row, text))
    rows += phase_rows(s)
    for row, (m,) in summary_row_groups("failures"):
        count = m.value(d)
        rows.append((row, str(0 if count is None else count)))
    return rows


def phase_rows(summary: Summary) -> list[tuple[str, str]]:
    """The phase check's rows (none when it did not run)."""
    pc = summary.phase_check
    if pc is None:
        return []
    robust, dependent = METRIC["robust_failure_rate"], METRIC["phase_dependent_failure_rate"]
    return [
        (robust.row,
         f"{robust.format(summary.robust_failure_rate)} ({pc['robust']}/{summary.n})"),
        (dependent.row,
         f"{dependent.format(summary.phase_dependent_failure_rate)} "
         f"({pc['phase_dependent']}/{summary.n}; {pc['phases']} phases per failure)"),
        ("phase-dependent means", PHASE_DEPENDENT_MEANING.split(": ", 1)[1]),
        *((f"phase check: {text.split(': ', 1)[0]}", text.split(": ", 1)[1]) if ": " in text
          else ("phase check", text) for text in verdict_words(pc)),
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
        phase += "".join(f", {text}" for text in verdict_words(s.phase_check))
    return (
        f"{report.pipeline}: pass rate {fmt(s.pass_rate, pct=True)} ({s.n_passed}/{s.n}, "
        f"95 % CI {fmt(lo, pct=True)}-{fmt(hi, pct=True)}){phase}; failures: {fails}"
    )


def interpreter_text(interpreter: dict) -> str:
    """A report's ``interpreter`` record in words: the versions, then what it is."""
    from arenabench.eval.runs import Interpreter

    return Interpreter.from_dict(interpreter).describe()


def _failure_detail(result: Any) -> str:
    """The first line of a failing image's message, or what it answered against the GT."""
    p = result.prediction
    line = ((p.message or "").strip().splitlines() or [""])[0]
    return line or (f"gt {result.truth.count} obstacles / {result.truth.area:.0f} px, "
                    f"answered {p.count} / {p.area}")


def first_failure_line(report: Report) -> str | None:
    """``first failure: ID: CATEGORY: first line of its message``, with how many images
    ended the same way (same category, same first line) when more than one did: what
    ``check`` and ``eval`` print, so that a run where every image met the same crash (a
    script the sandbox cannot see, a missing module) says what it was. ``None`` when no
    image failed."""
    failing = [r for r in report.images if not r.passed]
    if not failing:
        return None
    first = failing[0]
    detail = _failure_detail(first)
    same = sum(1 for r in failing
               if r.category == first.category and _failure_detail(r) == detail)
    hit = f" (the same on {same} of {report.summary.n} images)" if same > 1 else ""
    return f"first failure: {first.id}: {first.category}: {detail[:200]}{hit}"
