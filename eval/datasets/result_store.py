"""Where a run keeps its per-image results: in memory for a normal set, in an unnamed
temporary file for a big one, so that a run's memory does not grow with its set.

:class:`ResultStore` takes each scored image as it finishes (in any order) and gives back

- :meth:`ResultStore.images`: every result in dataset order, as a sequence
  (:class:`StoredResults` reads them back from the file, one at a time, when the run spilled
  them; report writers go through them once per file they write);
- :meth:`ResultStore.compact`: the same results without what only the per-image report
  lines need (output tails, messages, drawn polygons; parameters packed in
  :class:`ParamRow`), which the summary, the breakdown and the ranked causes are computed
  from.

A stored result is its ``report.json`` entry (:meth:`ImageResult.to_dict`, numbers exactly
as they were: NaN kept), so writing ``report.json`` from the file gives the bytes the
in-memory report would (:meth:`StoredResults.dicts`).
"""

from __future__ import annotations

import json
import os
import tempfile
from array import array
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from typing import Any, overload

from arenabench.eval.scoring.results import ImageResult, Prediction, RunImage
from arenabench.jsonstream import dumps_exact_line

#: Runs of more images than this keep their results in a temporary file.
SPILL_ABOVE = 2000
#: Key of a stored entry holding its run images' thumbnails (``Prediction.run_images``),
#: which ``report.json`` never holds: :meth:`StoredResults.dicts` leaves it out.
RUN_IMAGES_KEY = "_run_images"


def _result(d: dict[str, Any]) -> ImageResult:
    """The :class:`ImageResult` of a stored entry, its run images included."""
    stored = d.get(RUN_IMAGES_KEY)
    result = ImageResult.from_dict(d)
    if not stored:
        return result
    pred = replace(result.prediction,
                   run_images=tuple(RunImage.from_json(i) for i in stored))
    return replace(result, prediction=pred)


#: Parameter names -> their positions, shared by every :class:`ParamRow` with those names.
_KEY_INDEXES: dict[tuple[str, ...], dict[str, int]] = {}


class ParamRow(Mapping[str, float]):
    """A read-only ``{name: value}`` of one image's scene parameters, packed: the names are
    shared by every image with the same parameters, the values are one ``array('d')``."""

    __slots__ = ("_index", "_values")

    def __init__(self, params: Mapping[str, float]) -> None:
        keys = tuple(params)
        index = _KEY_INDEXES.get(keys)
        if index is None:
            index = _KEY_INDEXES.setdefault(keys, {k: i for i, k in enumerate(keys)})
        self._index = index
        self._values = array("d", params.values())

    def __getitem__(self, key: str) -> float:
        return self._values[self._index[key]]

    def __contains__(self, key: object) -> bool:
        return key in self._index

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)


def compact_result(result: ImageResult) -> ImageResult:
    """``result`` with only what the summary, breakdown and causes use."""
    p = result.prediction
    pred = Prediction(status=p.status, count=p.count, area=p.area, marker_ids=p.marker_ids,
                      latency_ms=p.latency_ms)
    return replace(result, image="", prediction=pred, params=ParamRow(result.params))


class ResultStore:
    """Per-image results of a run of ``n`` images (see the module docstring).

    Parameters
    ----------
    n : int
        Images in the run (results are placed by their index in the dataset).
    spill : bool, optional
        Keep the results in a temporary file (default: when ``n > SPILL_ABOVE``).
    """

    def __init__(self, n: int, *, spill: bool | None = None) -> None:
        self._spill = n > SPILL_ABOVE if spill is None else spill
        self._full: list[ImageResult | None] = [] if self._spill else [None] * n
        self._compact: list[ImageResult | None] = [None] * n if self._spill else []
        self._file = tempfile.TemporaryFile(prefix="arenabench-results-") if self._spill \
            else None
        self._offsets = array("q", [-1]) * n if self._spill else array("q")
        self._lengths = array("q", [0]) * n if self._spill else array("q")
        self._end = 0

    @property
    def spilled(self) -> bool:
        """Whether the results are kept in a file."""
        return self._spill

    def add(self, index: int, result: ImageResult) -> None:
        """Keep the result of image ``index``."""
        if not self._spill:
            self._full[index] = result
            return
        assert self._file is not None
        entry = result.to_dict()
        if result.prediction.run_images:  # kept beside the entry, never in report.json
            entry[RUN_IMAGES_KEY] = [i.to_json() for i in result.prediction.run_images]
        line = dumps_exact_line(entry).encode("utf-8")
        os.pwrite(self._file.fileno(), line, self._end)
        self._offsets[index], self._lengths[index] = self._end, len(line)
        self._end += len(line)
        self._compact[index] = compact_result(result)

    def images(self) -> Sequence[ImageResult]:
        """Every image's result so far, in dataset order."""
        if not self._spill:
            return tuple(r for r in self._full if r is not None)
        assert self._file is not None
        done = array("q", (i for i, off in enumerate(self._offsets) if off >= 0))
        return StoredResults(self._file, self._offsets, self._lengths, done)

    def compact(self) -> list[ImageResult]:
        """Every image's result so far, in dataset order, without the per-image details
        (:func:`compact_result`; the full results of a run kept in memory)."""
        rows = self._full if not self._spill else self._compact
        return [r for r in rows if r is not None]


class StoredResults(Sequence[ImageResult]):
    """Results kept in a file by :class:`ResultStore`, read back on demand (the file lives
    as long as this object or its store)."""

    def __init__(self, file: Any, offsets: array, lengths: array, order: array) -> None:
        self._file, self._offsets, self._lengths, self._order = file, offsets, lengths, order

    def __len__(self) -> int:
        return len(self._order)

    def _dict(self, i: int) -> dict[str, Any]:
        data = os.pread(self._file.fileno(), self._lengths[i], self._offsets[i])
        return json.loads(data)

    @overload
    def __getitem__(self, index: int) -> ImageResult: ...

    @overload
    def __getitem__(self, index: slice) -> tuple[ImageResult, ...]: ...

    def __getitem__(self, index: int | slice) -> ImageResult | tuple[ImageResult, ...]:
        if isinstance(index, slice):
            return tuple(_result(self._dict(i)) for i in self._order[index])
        return _result(self._dict(self._order[index]))

    def __iter__(self) -> Iterator[ImageResult]:
        for i in self._order:
            yield _result(self._dict(i))

    def dicts(self) -> Iterator[dict[str, Any]]:
        """The results' ``report.json`` entries, in order."""
        for i in self._order:
            d = self._dict(i)
            d.pop(RUN_IMAGES_KEY, None)
            yield d

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sequence) or len(other) != len(self):
            return False
        return all(a == b for a, b in zip(self, other, strict=True))

    __hash__ = None  # type: ignore[assignment]

    def __reduce__(self) -> tuple[Any, ...]:  # pickled as a plain tuple
        return (tuple, (tuple(self),))
