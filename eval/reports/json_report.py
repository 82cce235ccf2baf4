"""``report.json``: summary + per image, schema ``arenabench.report/1``."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

from arenabench.eval.scoring.results import Report
from arenabench.fileio import read_regular
from arenabench.jsonstream import Streamed, write_json_stream


def write_json(report: Report, path: str | os.PathLike[str]) -> Path:
    """Write ``report`` as canonical JSON (the images one at a time: a run of any size)."""
    images = report.images
    entries = images.dicts() if hasattr(images, "dicts") else (r.to_dict() for r in images)
    doc = replace(report, images=(), n_done=report.images_done).to_dict()
    doc["images"] = Streamed(entries)
    return write_json_stream(path, doc)


def read_json(path: str | os.PathLike[str]) -> Report:
    """Read a ``report.json``.

    Raises
    ------
    ValueError
        When the file is not JSON or not an ``arenabench.report/1`` report (names the file).
    """
    if Path(path).exists() and not Path(path).is_file():
        raise ValueError(f"{path}: not a regular file (a folder, pipe or device)")
    try:
        data = json.loads(read_regular(path).decode("utf-8"))  # never blocks on a FIFO
        return Report.from_dict(data)
    except (OSError, json.JSONDecodeError, KeyError, ValueError, TypeError) as exc:
        raise ValueError(f"{path}: not a readable arenabench report ({exc})") from None
