"""Canonical JSON written as a stream: the bytes of :func:`arenabench.fileio.dumps_json`
without holding the document in memory.

A document whose big lists are :class:`Streamed` (an iterable of items, consumed once) is
written piece by piece; everything else is serialised as :func:`~arenabench.fileio.dumps_json`
does (sorted keys, 2-space indent, NaN and infinities as ``null``, trailing newline), so
``write_json_stream(path, doc)`` and ``atomic_write_json(path, materialised_doc)`` give the
same file. Used for ``report.json`` (one entry per image) and ``coco.json`` (one entry per
image and annotation) of big sets.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from arenabench.fileio import atomic_writer, json_safe

_INDENT = "  "


@dataclass(frozen=True)
class Streamed:
    """A JSON array whose items come from ``items`` (consumed once, in order)."""

    items: Iterable[Any]


def _dumps(obj: Any, depth: int) -> str:
    """``obj`` as :func:`json.dumps` with ``indent=2`` writes it at nesting ``depth``."""
    text = json.dumps(json_safe(obj), indent=2, sort_keys=True, allow_nan=False)
    if depth and "\n" in text:  # JSON strings hold no raw newline: every one is layout
        text = text.replace("\n", "\n" + _INDENT * depth)
    return text


def dumps_exact_line(obj: Any) -> str:
    """One compact JSON line for arenabench's own temporary files (never a file a user
    reads): NaN and infinities are kept as ``NaN`` / ``Infinity`` and NumPy numbers become
    Python ones, so :func:`json.loads` gives back exactly the values written."""
    return json.dumps(obj, sort_keys=True, default=_plain)


def _plain(obj: Any) -> Any:
    """:func:`json.dumps` ``default``: NumPy numbers and arrays as Python ones."""
    if hasattr(obj, "tolist"):
        return obj.tolist()
    raise TypeError(f"Object of type {type(obj).__name__} is not JSON serializable")


def _has_stream(obj: Any) -> bool:
    if isinstance(obj, Streamed):
        return True
    if isinstance(obj, dict):
        return any(_has_stream(v) for v in obj.values())
    return False


def iter_json(obj: Any, depth: int = 0) -> Iterator[str]:
    """Pieces of the canonical JSON text of ``obj`` (without the final newline)."""
    if isinstance(obj, Streamed):
        first = True
        pad = "\n" + _INDENT * (depth + 1)
        for item in obj.items:
            yield ("[" if first else ",") + pad
            yield from iter_json(item, depth + 1)
            first = False
        yield "[]" if first else "\n" + _INDENT * depth + "]"
    elif isinstance(obj, dict) and _has_stream(obj):
        pad = "\n" + _INDENT * (depth + 1)
        keys = sorted(obj)
        if not keys:
            yield "{}"
            return
        for n, key in enumerate(keys):
            yield ("{" if n == 0 else ",") + pad + json.dumps(key) + ": "
            yield from iter_json(obj[key], depth + 1)
        yield "\n" + _INDENT * depth + "}"
    else:
        yield _dumps(obj, depth)


def write_json_stream(path: str | os.PathLike[str], obj: Any) -> Path:
    """Write ``obj`` (with :class:`Streamed` lists anywhere in its mappings) to ``path`` as
    canonical JSON, atomically (a temporary file renamed over ``path``)."""
    with atomic_text_writer(path) as fh:
        write_pieces(fh, iter_json(obj))
        fh.write("\n")
    return Path(path)


def atomic_text_writer(path: str | os.PathLike[str]) -> contextlib.AbstractContextManager[IO[str]]:
    """A UTF-8 text file (no newline translation) written piece by piece and renamed over
    ``path`` when the block ends without an exception (:func:`arenabench.fileio.atomic_writer`)."""
    return atomic_writer(path, text=True)


def write_pieces(fh: IO[str], pieces: Iterable[str], *, chunk_chars: int = 1 << 20) -> None:
    """Write text pieces to ``fh`` in chunks of about ``chunk_chars``."""
    buf: list[str] = []
    size = 0
    for piece in pieces:
        buf.append(piece)
        size += len(piece)
        if size >= chunk_chars:
            fh.write("".join(buf))
            buf.clear()
            size = 0
    fh.write("".join(buf))
