"""The per-image results of a team whose grading did not finish, kept for the next run.

``OUT/teams/TEAM/partial-results.jsonl``: a header line, then one line per image whose run
came back, appended (and flushed) as each comes back::

    {"schema": "arenabench.grade-partial/1", "team": ..., "submission_sha256": ...,
     "dataset_manifest_sha256": ..., "options_sha256": ..., "sandbox_sha256": ...}
    {"index": 17, "id": "000017", "prediction": {"status": "ok", "count": 3, ...}}

The header holds the fingerprints of ``grade-state.json`` (dataset, submission, grading
options, what the preflight saw in the sandbox). A later grade reuses the lines when every
fingerprint is the same, and runs only the images not in the file; otherwise the file is
removed. A line cut short (a grade killed in the middle of a write) and a line that names
another image than the dataset's at its index are ignored. The file is removed once the
team's ``grade-state.json`` is written (the team is graded).
"""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TextIO

from arenabench.eval.scoring.results import Prediction
from arenabench.jsonstream import dumps_exact_line

from .seal import SEAL, intact, sealed

PARTIAL_FILE = "partial-results.jsonl"
#: Most bytes of a kept partial log read (one line per image: about 300 bytes each).
MAX_PARTIAL_BYTES = 512 * 1024**2
PARTIAL_SCHEMA = "arenabench.grade-partial/1"


class PartialLog:
    """Appends one team's results to its ``partial-results.jsonl`` as they come back.

    Parameters
    ----------
    path : Path
        The file; started afresh with ``header`` unless ``append`` (a file whose header
        matched, read by :func:`read_partial`).
    header : mapping
        The fingerprints (see the module docstring).
    append : bool, keyword-only
        Add to the file as it is.
    """

    def __init__(self, path: Path, header: Mapping[str, Any], *, append: bool = False) -> None:
        self.path = path
        self._header = {"schema": PARTIAL_SCHEMA, **header}
        self._append = append
        self._fh: TextIO | None = None

    def add(self, index: int, image_id: str, pred: Prediction) -> None:
        """Keep the result of image ``index`` (one line, flushed)."""
        if self._fh is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._fh = open(self.path, "a" if self._append else "w", encoding="utf-8")
            if not self._append:
                self._fh.write(dumps_exact_line(sealed(self._header)) + "\n")
            elif self._fh.tell() and not _ends_with_newline(self.path):
                self._fh.write("\n")  # after a line cut short: it stays unreadable alone
        line = {"index": index, "id": image_id, "prediction": pred.to_json()}
        # exact values (NaN kept): the next run scores the same prediction again; sealed, so
        # that a line edited by hand is never trusted (.seal)
        self._fh.write(dumps_exact_line(sealed(line)) + "\n")
        self._fh.flush()

    def close(self) -> None:
        """Close the file (it stays for the next run)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def _ends_with_newline(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            fh.seek(-1, os.SEEK_END)
            return fh.read(1) == b"\n"
    except OSError:
        return True


def read_partial(path: Path, header: Mapping[str, Any],
                 ids: Sequence[str]) -> dict[int, Prediction] | None:
    """The results kept in ``path`` when its header is ``header``: image index ->
    prediction (``None``: no file, or one of another dataset, submission, options or
    sandbox; such a file is removed).

    Parameters
    ----------
    path : Path
        A team's ``partial-results.jsonl``.
    header : mapping
        The fingerprints expected.
    ids : sequence of str
        The dataset's image ids, by index.
    """
    try:  # never a blocking open of a FIFO someone put there
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the kept results ({exc.strerror or exc}): "
                         "remove it to grade this team from the start") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise ValueError(f"{path}: not a regular file (kept results are one): remove it "
                         "to grade this team from the start")
    with os.fdopen(fd, "rb") as fh:
        lines = fh.read(MAX_PARTIAL_BYTES + 1).decode("utf-8", "replace").splitlines()
    try:
        first = json.loads(lines[0]) if lines else None
    except ValueError:
        first = None
    if not intact(first) or {k: v for k, v in first.items() if k != SEAL} != {
            "schema": PARTIAL_SCHEMA, **header}:
        path.unlink(missing_ok=True)  # stale or edited: never trusted again
        return None
    kept: dict[int, Prediction] = {}
    for text in lines[1:]:
        try:
            line = json.loads(text)
            if not intact(line):
                continue  # edited by hand, or cut short: that image runs again
            index = line["index"]
            if (isinstance(index, int) and not isinstance(index, bool)
                    and 0 <= index < len(ids) and line["id"] == ids[index]):
                kept[index] = Prediction.from_json(line["prediction"])
        except (ValueError, TypeError, KeyError, AttributeError):
            continue  # a line cut short, or not one of ours: that image runs again
    return kept
