"""Checking a big set's files on several processes
(:func:`arenabench.eval.datasets.reader.load_dataset` with ``workers``; by default for
manifests larger than :data:`PARALLEL_ABOVE_BYTES`).

The main process reads the manifest in order (JSON lines, fields, duplicate ids), as the
one-process reader does; the entries are then checked (paths, hashes, damage, GT schema) in
chunks on a process pool, and the outcomes merged in manifest order, so the error raised is
the one the one-process reader raises first, and the dataset is the same.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arenabench.local_pool import local_executor

from .entries import DatasetError, checked_entry, gt_facts

#: Manifests larger than this (about 20,000 entries of the generator's ~250-byte lines) are
#: checked on several processes by default.
PARALLEL_ABOVE_BYTES = 5_000_000
#: Most processes a check uses by default.
MAX_CHECK_WORKERS = 4
#: Entries per unit of work.
CHUNK = 2_000


@dataclass(frozen=True)
class Chunk:
    """Entries to check: ``(manifest line number, entry)`` pairs and the settings."""

    items: tuple[tuple[int, dict[str, Any]], ...]
    manifest: str
    base: str
    shown: str
    verify: bool
    area_keys: tuple[str, ...]


def check_chunk(chunk: Chunk) -> list[tuple[str, Any]]:
    """Each entry's outcome, in order, up to the first error: ``("ok", gt_facts)``
    (:func:`~.entries.gt_facts`), ``("damaged", why)`` or
    ``("error", message)`` (then nothing more)."""
    base, shown = Path(chunk.base), Path(chunk.shown)
    dirs: dict[str, Path] = {}
    out: list[tuple[str, Any]] = []
    for lineno, entry in chunk.items:
        try:
            gt = checked_entry(entry, f"{chunk.manifest}:{lineno}", base=base, shown=shown,
                                verify=chunk.verify, dirs=dirs)
        except DatasetError as exc:
            out.append(("error", str(exc)))
            return out
        if isinstance(gt, str):
            out.append(("damaged", gt))
        else:
            out.append(("ok", gt_facts(gt, chunk.area_keys)))
    return out


def check_manifest(entries: Iterator[tuple[int, dict[str, Any]]],
                   accept: Callable[[dict[str, Any], str, Any], None], *, manifest: Path,
                   base: Path, shown: Path, verify: bool, area_keys: tuple[str, ...],
                   workers: int) -> None:
    """Check the manifest's ``entries`` on ``workers`` spawned processes, a window of chunks
    at a time, and give each outcome to ``accept(entry, "ok" | "damaged", value)`` in
    manifest order; the first error found (a file's, or the manifest's own when every entry
    before it is fine) is raised as a :class:`~.entries.DatasetError`."""
    def chunk(items: list[tuple[int, dict[str, Any]]]) -> Chunk:
        return Chunk(items=tuple(items), manifest=str(manifest), base=str(base),
                     shown=str(shown), verify=verify, area_keys=area_keys)

    manifest_error: DatasetError | None = None
    with local_executor(workers) as pool:
        while manifest_error is None:
            window: list[tuple[int, dict[str, Any]]] = []
            try:
                for item in entries:
                    window.append(item)
                    if len(window) >= CHUNK * workers * 2:
                        break
            except DatasetError as exc:  # raised once the entries before it are checked
                manifest_error = exc
            if not window:
                break
            futures = [pool.submit(check_chunk, chunk(window[i:i + CHUNK]))
                       for i in range(0, len(window), CHUNK)]
            try:
                for n, fut in enumerate(futures):
                    for (_, entry), (outcome, value) in zip(window[n * CHUNK:], fut.result(),
                                                            strict=False):
                        if outcome == "error":
                            raise DatasetError(value)
                        accept(entry, outcome, value)
            finally:
                for fut in futures:
                    fut.cancel()
            if len(window) < CHUNK * workers * 2:
                break
    if manifest_error is not None:
        raise manifest_error
