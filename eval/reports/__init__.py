"""Report writers: ``report.json``, ``results.csv``, ``report.md``, ``report.html``,
``junit.xml``."""

from __future__ import annotations

import os
from pathlib import Path

from arenabench.cliopts import formats_problem
from arenabench.eval.datasets.reader import Dataset
from arenabench.eval.scoring.results import Report

from .csv_report import write_csv
from .html_report import write_html
from .json_report import write_json
from .junit_report import write_junit
from .markdown_report import write_markdown

FORMATS: dict[str, str] = {
    "json": "report.json",
    "csv": "results.csv",
    "md": "report.md",
    "html": "report.html",
    "junit": "junit.xml",
}


def write_reports(
    report: Report,
    out_dir: str | os.PathLike[str],
    *,
    formats: tuple[str, ...] = tuple(FORMATS),
    dataset: Dataset | None = None,
) -> dict[str, Path]:
    """Write the chosen report files into ``out_dir`` (atomically, one file per format).

    Parameters
    ----------
    report : Report
        The evaluation.
    out_dir : path-like
        Folder (created when missing).
    formats : tuple of str
        Subset of :data:`FORMATS`.
    dataset : Dataset, optional
        Gives the HTML report the GT polygons for its thumbnails.

    Returns
    -------
    dict
        Format -> written path.
    """
    problem = formats_problem(formats, tuple(FORMATS)) if formats else None
    if problem:
        raise ValueError(f"formats: {problem}")
    out = Path(out_dir)
    writers = {
        "json": write_json,
        "csv": write_csv,
        "md": write_markdown,
        "junit": write_junit,
    }
    written: dict[str, Path] = {}
    for fmt in formats:
        path = out / FORMATS[fmt]
        if fmt == "html":
            write_html(report, path, dataset=dataset)
        else:
            writers[fmt](report, path)
        written[fmt] = path
    return written


__all__ = [
    "FORMATS",
    "write_csv",
    "write_html",
    "write_json",
    "write_junit",
    "write_markdown",
    "write_reports",
]
