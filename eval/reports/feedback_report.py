"""``feedback.md`` and ``feedback.html``: what a team may be handed back of its grade on a
hidden set (``grade`` writes them beside each team's report; docs/grading.md says what they
hold and why that is safe).

A team's own reports (``report.html`` ...) show every hidden image with its ground truth; this
one shows only figures over the whole set: the pass rate, the failure categories, the
phase check's counts, systematic errors and the scene facts that separate failures from
passes. Never an image, an image id, a ground-truth or predicted number of one image, the
order of the images, a minimum or maximum over them, or anything the team's script printed
(its output could carry what it saw of a hidden image).
"""

from __future__ import annotations

import html
import os
from pathlib import Path

from arenabench.eval.scoring.breakdown import systematic_text
from arenabench.eval.scoring.metric_registry import summary_row_groups
from arenabench.eval.scoring.phase_summary import PHASE_DEPENDENT_MEANING, verdict_words
from arenabench.eval.scoring.results import HARNESS_STATUSES, Report
from arenabench.fileio import atomic_write_text

from .incomplete import banner_html, banner_markdown
from .markdown_report import TOP_CAUSES

#: The files, by format.
FEEDBACK_FILES: dict[str, str] = {"md": "feedback.md", "html": "feedback.html"}
#: Summary statistics left out: each is one image's value.
_ONE_IMAGE_STATS = (".min", ".max")
#: Failure categories whose message starts with the harness's own words (``exit status 1``,
#: ``timed out after 60 s ...``, ``memory limit (...) reached``) before any of the script's.
_HARNESS_WORDED = ("crash", "timeout", "limit")
#: Most distinct reasons listed per category.
MAX_REASONS = 3
#: What a team can run to see its failures with their images, on scenes it may see.
REPRODUCE = ("arenabench check map.py: the same checks on 200 twin scenes you may see, with "
             "every failure's image, its ground truth and what your script printed")


def _summary_rows(report: Report) -> list[tuple[str, str]]:
    s = report.summary
    d = s.to_dict()
    rows = [("images", str(s.n)), ("passed", f"{s.n_passed} of {s.n}")]
    for group in ("summary", "phase") if s.phase_check is not None else ("summary",):
        for _, metrics in summary_row_groups(group):
            for m in metrics:
                if not m.name.endswith(_ONE_IMAGE_STATS):
                    rows.append((m.label, m.format(m.value(d))))
    if s.phase_check is not None:
        rows.append(("phase-dependent means", PHASE_DEPENDENT_MEANING.split(": ", 1)[1]))
        rows += [("phase check", text) for text in verdict_words(s.phase_check)]
    return rows


def _reason(message: str) -> str:
    """The harness's words at the start of a failure message (what follows ``: `` may be the
    script's)."""
    return message.split(": ", 1)[0].strip()[:80]


def _failure_rows(report: Report) -> list[tuple[str, str]]:
    """One row per failure category that happened: how many images, and for a crash, a
    timeout or a limit the harness's reasons (``exit status 1``) with their counts."""
    from collections import Counter

    reasons: dict[str, Counter] = {c: Counter() for c in _HARNESS_WORDED}
    for r in report.images:
        if r.category in reasons and r.prediction.message:
            reasons[r.category][_reason(r.prediction.message)] += 1
    rows = []
    for category, n in report.summary.failures.items():
        if not n:
            continue
        text = f"{n} image{'s' if n != 1 else ''}"
        if reasons.get(category):
            text += " (" + "; ".join(f"{why}: {k}" for why, k in
                                     reasons[category].most_common(MAX_REASONS)) + ")"
        if category in HARNESS_STATUSES:
            text += " - the run gave no usable answer"
        rows.append((category, text))
    return rows


def _cause_lines(report: Report) -> list[str]:
    """Systematic errors, then the ranked facts (direction and strength: no medians, which
    over a few failures are a few images' values)."""
    lines = []
    if (text := systematic_text(report.systematic)) is not None:
        lines.append(text)
    for c in report.causes[:TOP_CAUSES]:
        lines.append(f"failures have {c['direction']} {c['param']} (strength "
                     f"{c['strength']:.2f}{', clear' if c['p_value'] < 0.05 else ''})")
    return lines


def _header(report: Report, team: str) -> tuple[str, str]:
    title = f"arenabench: feedback for {team}"
    about = (f"Graded on {report.summary.n} hidden images (tolerance {report.tolerance:g}, "
             f"area reference {report.area_reference}). This page holds only figures over the "
             "whole set: no image, no image id, no number of a single image.")
    return title, about


def feedback_markdown(report: Report, *, team: str) -> str:
    """The text of ``feedback.md``."""
    title, about = _header(report, team)
    lines = [f"# {title}", "",
             *([] if report.complete else banner_markdown(report.images_done, report.n_total)),
             about, "", "## Summary", "", "| metric | value |", "|---|---|"]
    esc = lambda t: t.replace("|", "\\|").replace("\n", " ")  # noqa: E731
    lines += [f"| {esc(k)} | {esc(v)} |" for k, v in _summary_rows(report)]
    failures = _failure_rows(report)
    lines += ["", "## Failures", ""]
    lines += ([f"- {k}: {esc(v)}" for k, v in failures] if failures
              else ["Every image passed."])
    causes = _cause_lines(report)
    if causes:
        lines += ["", "## Likely causes", "", *(f"- {esc(c)}" for c in causes)]
    lines += ["", "## See your failures", "", f"Run `{REPRODUCE.split(': ', 1)[0]}`: "
              f"{REPRODUCE.split(': ', 1)[1]}."]
    return "\n".join(lines) + "\n"


def feedback_html(report: Report, *, team: str) -> str:
    """The text of ``feedback.html`` (self-contained: no image, no script, no link)."""
    e = html.escape
    title, about = _header(report, team)
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>{e(title)}</title><style>body{{font-family:system-ui,sans-serif;"
             "margin:24px;color:#222}table{border-collapse:collapse}td,th{border:1px solid "
             "#ccc;padding:3px 8px;text-align:left}th{background:#f3f3f3}</style></head><body>",
             f"<h1>{e(title)}</h1>",
             "" if report.complete else banner_html(report.images_done, report.n_total),
             f"<p>{e(about)}</p>", "<h2>Summary</h2>",
             "<table><tr><th>metric</th><th>value</th></tr>"]
    parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in _summary_rows(report)]
    parts.append("</table><h2>Failures</h2>")
    failures = _failure_rows(report)
    if failures:
        parts.append("<ul>" + "".join(f"<li><b>{e(k)}</b>: {e(v)}</li>" for k, v in failures)
                     + "</ul>")
    else:
        parts.append("<p>Every image passed.</p>")
    causes = _cause_lines(report)
    if causes:
        parts.append("<h2>Likely causes</h2><ul>" + "".join(f"<li>{e(c)}</li>" for c in causes)
                     + "</ul>")
    cmd, what = REPRODUCE.split(": ", 1)
    parts += ["<h2>See your failures</h2>", f"<p>Run <code>{e(cmd)}</code>: {e(what)}.</p>",
              "</body></html>"]
    return "\n".join(parts) + "\n"


def write_feedback(report: Report, out_dir: str | os.PathLike[str], *, team: str
                   ) -> dict[str, Path]:
    """Write ``feedback.md`` and ``feedback.html`` into ``out_dir`` (atomically).

    Returns
    -------
    dict
        Format -> written path.
    """
    out = Path(out_dir)
    return {
        "md": atomic_write_text(out / FEEDBACK_FILES["md"], feedback_markdown(report, team=team)),
        "html": atomic_write_text(out / FEEDBACK_FILES["html"],
                                  feedback_html(report, team=team)),
    }
