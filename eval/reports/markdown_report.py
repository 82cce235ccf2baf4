"""``report.md``: the summary table, failures and the parameter breakdown in Markdown."""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path

from arenabench.eval.scoring.breakdown import shown_breakdown, strongest_cause_text, systematic_text
from arenabench.eval.scoring.results import Report
from arenabench.fileio import atomic_write_text

from .incomplete import banner_markdown, partial
from .summary_rows import (
    BREAKDOWN_COLUMNS,
    breakdown_cells,
    fmt,
    interpreter_text,
    summary_rows,
)

#: Ranked causes a report lists.
TOP_CAUSES = 5


def phase_cell(phase) -> str:
    """The phase check's verdict of an image (:meth:`PhaseResult.text`: ``k/N robust``,
    ``k/N phase-dependent``, ``0/N depends on open PARAM``, ``0/0 unchecked``, with the runs
    that did not complete); ``-`` when not checked."""
    return "-" if phase is None else phase.text()


def _esc(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown(report: Report, *, max_failures: int = 30) -> str:
    """The Markdown text of the report."""
    lines = [
        f"# arenabench evaluation: {report.pipeline}",
        "",
        *([] if report.complete else banner_markdown(report.images_done, report.n_total)),
        f"- dataset: `{report.dataset}`",
        f"- area reference: `{report.area_reference}`, tolerance {report.tolerance:g}",
        *([] if report.interpreter is None
          else [f"- interpreter: {_esc(interpreter_text(report.interpreter))}"]),
        "",
        f"## {partial('Summary', report.complete)}",
        "",
        "| metric | value |",
        "|---|---|",
    ]
    lines += [f"| {_esc(k)} | {_esc(v)} |" for k, v in summary_rows(report.summary)]
    lines += _causes_lines(report)
    failing, n_failing = [], 0  # the first max_failures kept: a big run fails 10^5 times
    for r in report.images:
        if not r.passed:
            n_failing += 1
            if len(failing) < max_failures:
                failing.append(r)
    if n_failing:
        lines += [
            "",
            "## Failing images",
            "",
            "| id | category | phase passes | gt count | pred count | gt area | pred area "
            "| area rel err | message |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in failing:
            p = r.prediction
            lines.append(
                f"| {r.id} | {r.category} | {phase_cell(r.phase)} | {r.truth.count} | "
                f"{fmt(p.count)} | {r.truth.area:.1f} | {fmt(p.area)} | "
                f"{fmt(r.score.area_rel_err)} | {_esc(p.message)[:120]} |"
            )
        if n_failing > max_failures:
            lines.append(f"\n... and {n_failing - max_failures} more (see results.csv)")
    keys = shown_breakdown(report)
    if keys:
        lines += [
            "",
            "## Breakdown by scene parameter",
            "",
            f"The {len(keys)} parameters that best separate failures from passes (all of "
            "them: `breakdown` in report.json).",
            "",
        ]
        for key in keys:
            lines += [
                f"### {key}",
                "",
                _md_row(_md_label(c) for c in BREAKDOWN_COLUMNS),
                "|" + "---|" * len(BREAKDOWN_COLUMNS),
            ]
            lines += [_md_row(breakdown_cells(row)) for row in report.breakdown[key]]
            lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def _causes_lines(report: Report) -> list[str]:
    """The "Likely causes" section: systematic errors, then the ranked scene facts."""
    if not report.causes and not report.systematic:
        return []
    lines = ["", "## Likely causes", ""]
    if (text := systematic_text(report.systematic)) is not None:
        lines += [f"{_esc(text)}.", ""]
    if report.causes:
        lines += [
            "Scene parameters and derived facts that best separate failing from passing images "
            "(strength = |2 AUC - 1|: 0 none, 1 every failure beyond every pass).",
            "",
            "| parameter | strength | failures have | median in failures | median in passes "
            "| p |",
            "|---|---|---|---|---|---|",
        ]
        for c in report.causes[:TOP_CAUSES]:
            lines.append(
                f"| {c['param']} | {c['strength']:.2f} | {c['direction']} values | "
                f"{fmt(c['fail_median'])} | {fmt(c['pass_median'])} | {c['p_value']:.2g} |")
        lines += ["", f"{_esc(strongest_cause_text(report.causes))}."]
    return lines


def _md_row(cells: Iterable[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _md_label(label: str) -> str:
    """A column label in a Markdown table: ``|x|`` (absolute value) is written ``abs x``."""
    return re.sub(r"\|([^|]+)\|", r"abs \1", label)


def write_markdown(report: Report, path: str | os.PathLike[str]) -> Path:
    """Write ``report.md``."""
    return atomic_write_text(path, markdown(report))
