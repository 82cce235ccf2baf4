"""``report.json``: summary + per image, schema ``arenabench.report/1``."""

from __future__ import annotations

import json
import os
from pathlib import Path

from arenabench.fileio import atomic_write_json

from ..results import Report


def write_json(report: Report, path: str | os.PathLike[str]) -> Path:
    """Write ``report`` as canonical JSON."""
    return atomic_write_json(path, report.to_dict())


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
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        return Report.from_dict(data)
    except (OSError, json.JSONDecodeError, KeyError, ValueError, TypeError) as exc:
        raise ValueError(f"{path}: not a readable arenabench report ({exc})") from None
