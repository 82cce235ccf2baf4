"""``results.csv``: one row per image (metrics, numbers, then the scene parameters)."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import IO

from arenabench.eval.scoring.results import Report
from arenabench.jsonstream import atomic_text_writer

COLUMNS: tuple[str, ...] = (
    "id",
    "pass",
    "category",
    "status",
    "gt_count",
    "pred_count",
    "gt_area",
    "pred_area",
    "area_rel_err",
    "area_err_kind",
    "marker_ids_ok",
    "gt_marker_ids",
    "pred_marker_ids",
    "latency_ms",
    "message",
    "image",
    "phase_passes",
    "phase_n",
    "phase_class",
)


def _cell(value: object) -> object:
    if value is None:
        return ""
    if isinstance(value, (list, tuple)):
        return " ".join(str(v) for v in value)
    return value


def write_csv(report: Report, path: str | os.PathLike[str]) -> Path:
    """Write one row per image; scene parameters follow as ``param:<name>`` columns (rows
    written as they come: a run of any size)."""
    with atomic_text_writer(path) as fh:
        _write_rows(report, fh)
    return Path(path)


def _write_rows(report: Report, fh: IO[str]) -> None:
    images = report.images  # results kept in a file: their JSON is enough for the names
    entries = images.dicts() if hasattr(images, "dicts") else images
    params = sorted({k for r in entries
                     for k in (r["params"] if isinstance(r, dict) else r.params)})
    writer = csv.writer(fh, lineterminator="\n")
    writer.writerow([*COLUMNS, *(f"param:{p}" for p in params)])
    for r in report.images:
        p, s = r.prediction, r.score
        row = [
            r.id,
            int(s.passed),
            s.category,
            p.status,
            r.truth.count,
            p.count,
            r.truth.area,
            p.area,
            s.area_rel_err,
            s.area_err_kind,
            "" if s.marker_ids_ok is None else int(s.marker_ids_ok),
            list(r.truth.marker_ids),
            None if p.marker_ids is None else list(p.marker_ids),
            None if (ms := p.measured_latency_ms) is None else round(ms, 3),
            p.message,
            r.image,
            *((None, None, None) if r.phase is None
              else (r.phase.passes, r.phase.n, r.phase.label)),
        ]
        writer.writerow([_cell(v) for v in row] + [_cell(r.params.get(k)) for k in params])
