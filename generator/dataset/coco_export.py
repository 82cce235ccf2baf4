"""``coco.json`` of a set of any size: the scenes' COCO parts wait in a temporary file while
the set renders, and the file is written from there as a stream, so ``generate``'s memory does
not grow with ``--count``. The bytes are those of
:func:`arenabench.generator.dataset.dataset_writer.coco_from_gts` written whole.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from arenabench.jsonstream import Streamed, dumps_exact_line, write_json_stream


class CocoParts:
    """The scenes' :func:`~arenabench.generator.dataset.dataset_writer.coco_parts`, by scene id, in
    an
    unnamed temporary file (gone when this object is)."""

    def __init__(self) -> None:
        self._file = tempfile.TemporaryFile(prefix="arenabench-coco-")
        self._where: dict[str, tuple[int, int]] = {}
        self._end = 0

    def __contains__(self, sid: object) -> bool:
        return sid in self._where

    def add(self, sid: str, part: dict[str, Any]) -> None:
        """Keep scene ``sid``'s part."""
        data = dumps_exact_line(part).encode("utf-8")
        os.pwrite(self._file.fileno(), data, self._end)
        self._where[sid] = (self._end, len(data))
        self._end += len(data)

    def keep(self, res: dict[str, Any]) -> dict[str, Any]:
        """A rendering task's result with its ``coco`` part moved here."""
        if "coco" in res:
            self.add(res["id"], res.pop("coco"))
        return res

    def get(self, sid: str) -> dict[str, Any]:
        """Scene ``sid``'s part."""
        offset, size = self._where[sid]
        return json.loads(os.pread(self._file.fileno(), size, offset))


def coco_document_stream(parts: Callable[[], Iterator[dict[str, Any]]],
                         info: dict[str, Any], categories: list[dict[str, Any]]
                         ) -> dict[str, Any]:
    """The COCO document with its ``images`` and ``annotations`` as
    :class:`~arenabench.jsonstream.Streamed` lists (``parts()`` is called once for each)."""

    def annotations() -> Iterator[dict[str, Any]]:
        n = 0
        for part in parts():
            for ann in part["annotations"]:
                n += 1
                yield {"id": n, **ann}

    return {"info": info, "images": Streamed(p["image"] for p in parts()),
            "annotations": Streamed(annotations()), "categories": categories}


def write_coco(path: str | os.PathLike[str], parts: Callable[[], Iterator[dict[str, Any]]],
               info: dict[str, Any], categories: list[dict[str, Any]]) -> Path:
    """Write ``coco.json`` from the scenes' parts in order (atomically)."""
    return write_json_stream(path, coco_document_stream(parts, info, categories))
