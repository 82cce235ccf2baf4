"""``report.md``: the summary table, failures and the parameter breakdown in Markdown."""

from __future__ import annotations

import os
from pathlib import Path

from arenabench.fileio import atomic_write_text

from ..breakdown import importance
from ..records import Report
from .incomplete import banner_markdown, partial
from .summary_rows import fmt, summary_rows


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
        "",
        f"## {partial('Summary', report.complete)}",
        "",
        "| metric | value |",
        "|---|---|",
    ]
    lines += [f"| {_esc(k)} | {_esc(v)} |" for k, v in summary_rows(report.summary)]
    failing = [r for r in report.images if not r.passed]
    if failing:
        lines += [
            "",
            "## Failing images",
            "",
            "| id | category | gt count | pred count | gt area | pred area | area rel err "
            "| message |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for r in failing[:max_failures]:
            p = r.prediction
            lines.append(
                f"| {r.id} | {r.category} | {r.truth.count} | {fmt(p.count)} | "
                f"{r.truth.area:.1f} | {fmt(p.area)} | {fmt(r.score.area_rel_err)} | "
                f"{_esc(p.message)[:120]} |"
            )
        if len(failing) > max_failures:
            lines.append(f"\n... and {len(failing) - max_failures} more (see results.csv)")
    if report.breakdown:
        lines += [
            "",
            "## Breakdown by scene parameter",
            "",
            "Parameters sorted by how much the pass rate varies across their bins.",
            "",
        ]
        for key in sorted(
            report.breakdown, key=lambda k: importance(report.breakdown[k]), reverse=True
        ):
            lines += [
                f"### {key}",
                "",
                "| bin | n | pass rate | count exact | median abs area err | failures |",
                "|---|---|---|---|---|---|",
            ]
            for row in report.breakdown[key]:
                fails = ", ".join(f"{c} {v}" for c, v in row["failures"].items()) or "-"
                lines.append(
                    f"| {row['bin']} | {row['n']} | {fmt(row['pass_rate'], pct=True)} | "
                    f"{fmt(row['count_exact_rate'], pct=True)} | "
                    f"{fmt(row['area_rel_err_median'])} | {fails} |"
                )
            lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def write_markdown(report: Report, path: str | os.PathLike[str]) -> Path:
    """Write ``report.md``."""
    return atomic_write_text(path, markdown(report))
