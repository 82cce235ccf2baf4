"""Report writers: ``report.json``, ``results.csv``, ``report.md``, ``report.html``,
``junit.xml``."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from arenabench.cliopts import formats_problem
from arenabench.eval.datasets.reader import Dataset
from arenabench.eval.scoring.results import Report

from .csv_report import write_csv
from .html_report import write_html
from .json_report import write_json
from .junit_report import write_junit
from .markdown_report import write_markdown


@dataclass(frozen=True)
class ReportFile:
    """One report format: the file it writes and its writer (every writer is called with the
    report, the file's path and the dataset, which only the HTML report uses)."""

    name: str
    write: Callable[[Report, Path, Dataset | None], None]


#: Every report format, by its ``--formats`` name: the one table of them.
REPORT_FILES: dict[str, ReportFile] = {
    "json": ReportFile("report.json", lambda report, path, dataset: write_json(report, path)),
    "csv": ReportFile("results.csv", lambda report, path, dataset: write_csv(report, path)),
    "md": ReportFile("report.md", lambda report, path, dataset: write_markdown(report, path)),
    "html": ReportFile("report.html",
                       lambda report, path, dataset: write_html(report, path, dataset=dataset)),
    "junit": ReportFile("junit.xml", lambda report, path, dataset: write_junit(report, path)),
}

#: Format -> the file it writes (derived from :data:`REPORT_FILES`).
FORMATS: dict[str, str] = {fmt: f.name for fmt, f in REPORT_FILES.items()}


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
    written: dict[str, Path] = {}
    for fmt in formats:
        file = REPORT_FILES[fmt]
        file.write(report, out / file.name, dataset)
        written[fmt] = out / file.name
    return written


__all__ = [
    "FORMATS",
    "REPORT_FILES",
    "ReportFile",
    "write_csv",
    "write_html",
    "write_json",
    "write_junit",
    "write_markdown",
    "write_reports",
]
