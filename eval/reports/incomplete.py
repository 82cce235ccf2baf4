"""The INCOMPLETE banner of an interrupted or partial run, declared once.

Every HTML and Markdown report, sweep page and leaderboard of a run that did not finish
carries, first thing under its title, the line ``INCOMPLETE: 8 of 24 images`` and labels its
figures as partial (they cover only the images that ran).
"""

from __future__ import annotations

import html

#: Inline style of the HTML banner (pages are self-contained: no external CSS).
BANNER_STYLE = ("background:#b00020;color:#fff;font-weight:bold;padding:8px 12px;"
                "margin:8px 0;border-radius:4px;font-size:1.1em")
#: Said of every figure of a partial run.
PARTIAL_NOTE = "every figure below is partial: it covers only the images that ran"


def incomplete_text(done: int, total: int | None, *, unit: str = "images") -> str:
    """``"INCOMPLETE: 8 of 24 images"`` (``"INCOMPLETE: 8 images"`` when the total is
    unknown)."""
    if total is None:
        return f"INCOMPLETE: {done} {unit}"
    return f"INCOMPLETE: {done} of {total} {unit}"


def banner_html(done: int, total: int | None, *, unit: str = "images") -> str:
    """The banner as one HTML block (``id="incomplete"``)."""
    text = html.escape(incomplete_text(done, total, unit=unit))
    return (f'<div id="incomplete" class="incomplete" role="alert" style="{BANNER_STYLE}">'
            f"{text} ({html.escape(PARTIAL_NOTE)})</div>")


def banner_markdown(done: int, total: int | None, *, unit: str = "images") -> list[str]:
    """The banner as Markdown lines (a bold quote block and a blank line)."""
    return [f"> **{incomplete_text(done, total, unit=unit)}** ({PARTIAL_NOTE})", ""]


def partial(label: str, complete: bool) -> str:
    """``label`` marked ``(partial)`` when the run is not complete."""
    return label if complete else f"{label} (partial)"
