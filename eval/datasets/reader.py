"""Read a dataset written by the generator: ``manifest.jsonl`` plus ``gt/*.json`` (schema
``arenabench.gt/1``), validated with one-line errors that name the file and the field."""

from __future__ import annotations

import io
import json
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, overload

from arenabench.eval.scoring.results import Truth
from arenabench.fileio import open_regular, read_regular, sha256_bytes, sha256_file
from arenabench.gtrecord import AREA_REFERENCES as AREA_REFERENCES  # declared there
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE as DEFAULT_AREA_REFERENCE
from arenabench.gtrecord import GroundTruth
from arenabench.limits import MAX_DATASET_META_BYTES, MAX_IMAGE_ID_CHARS
from arenabench.workers import usable_cores

from .check import MAX_CHECK_WORKERS, PARALLEL_ABOVE_BYTES, check_manifest
from .entries import DatasetError as DatasetError  # the readers' error, declared there
from .entries import checked_entry, gt_facts, os_problem, path_error
from .entries import validate_gt as validate_gt


@dataclass(frozen=True)
class DatasetItem:
    """One image of a dataset with its ground truth.

    Parameters
    ----------
    id : str
        Image id (``"000042"``).
    image_path : pathlib.Path
        Absolute path of the image.
    gt_path : pathlib.Path
        Absolute path of the GT JSON.
    gt : GroundTruth
        The ground truth (a mapping in the GT file's JSON form is converted with
        :meth:`GroundTruth.from_dict`).
    params : dict
        Flat scalar scene parameters with dotted keys (GT ``params``, or the numeric leaves
        of ``scene`` when ``params`` is absent).
    """

    id: str
    image_path: Path
    gt_path: Path
    gt: GroundTruth
    params: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.gt, GroundTruth):
            object.__setattr__(self, "gt", GroundTruth.from_dict(self.gt))

    def truth(self, *, area_reference: str = DEFAULT_AREA_REFERENCE) -> Truth:
        """Ground truth to score against (area per ``area_reference``)."""
        if area_reference not in AREA_REFERENCES:
            raise ValueError(
                f"area_reference must be one of {sorted(AREA_REFERENCES)}, got {area_reference!r}"
            )
        key = AREA_REFERENCES[area_reference]
        area = getattr(self.gt.area, key, None)
        if area is None:
            area = self.gt.area.extra.get(key)
        if area is None:
            raise path_error(self.gt_path, f"field 'area.{key}' is missing (written by an older "
                                      f"generator?): regenerate the dataset to score against "
                                      f"--area-reference {area_reference}")
        return Truth(
            count=int(self.gt.count),
            area=float(area),
            # "visible" (in view and not occluded) when the GT has it, else "in_view"
            marker_ids=tuple(int(m.id) for m in self.gt.markers or () if m.expected),
        )


@dataclass(frozen=True)
class Dataset:
    """A validated dataset."""

    root: Path
    #: The images in manifest order: a tuple, or (from :func:`load_dataset`) a
    #: :class:`DatasetSamples` that reads each image's GT file when the item is taken.
    samples: Sequence[DatasetItem]
    #: (manifest id, why) of the damaged images left out (``load_dataset(skip_damaged=True)``)
    skipped: tuple[tuple[str, str], ...] = ()
    #: What :func:`load_dataset` learnt of every GT while validating it (``None``: look at
    #: the samples).
    facts: DatasetFacts | None = None
    #: ``dataset.json`` as :func:`load_dataset` read it (``None``: not read; see
    #: :func:`read_dataset_meta`).
    meta: DatasetMeta | None = None

    @property
    def name(self) -> str:
        """Folder name of the dataset."""
        return self.root.name

    def __len__(self) -> int:
        return len(self.samples)

    def presets(self) -> list[str]:
        """The GT files' preset names, sorted, once each (``""`` for a GT without one)."""
        if self.facts is not None:
            return list(self.facts.presets)
        return sorted({s.gt.preset or "" for s in self.samples})

    def check_area_reference(self, area_reference: str, *, limit: int | None = None) -> None:
        """Raise the :class:`DatasetError` of the first image (of the first ``limit``) whose
        GT lacks the area of ``area_reference`` (a data error, found before any image runs)."""
        if self.facts is None:
            for s in self.samples[:limit]:
                s.truth(area_reference=area_reference)
            return
        first = self.facts.lacking.get(AREA_REFERENCES[area_reference])
        if first is not None and (limit is None or first < limit):
            self.samples[first].truth(area_reference=area_reference)

    def manifest_sha256(self) -> str | None:
        """SHA-256 of the dataset's ``manifest.jsonl`` (it names every image and GT file with
        its SHA-256, so equal digests mean the same set); ``None`` when the dataset has no
        manifest file (one made in memory)."""
        import stat

        path = self.root / "manifest.jsonl"
        try:
            if not stat.S_ISREG(os.stat(path).st_mode):
                return None
        except OSError:
            return None
        return sha256_file(path)

    def image_paths(self) -> list[Path]:
        """The image files in order (no GT file read)."""
        if isinstance(self.samples, DatasetSamples):
            return self.samples.image_paths
        return [s.image_path for s in self.samples]

    def items_by_id(self, ids: Iterable[str]) -> dict[str, DatasetItem]:
        """The items of ``ids`` (those in the set), reading only their GT files."""
        wanted = set(ids)
        order = self.samples.ids if isinstance(self.samples, DatasetSamples) else None
        if order is None:
            return {s.id: s for s in self.samples if s.id in wanted}
        return {sid: self.samples[i] for i, sid in enumerate(order) if sid in wanted}


@dataclass(frozen=True)
class DatasetFacts:
    """Facts of a whole dataset gathered by :func:`load_dataset` while it validates each GT.

    Attributes
    ----------
    presets : tuple of str
        Preset names of the GT files, sorted, once each.
    lacking : dict
        GT area key (``contour_px``, ...) -> index of the first image whose GT lacks it.
    weakest_seed : tuple or None
        ``(index, seed)`` of the image whose GT records the weakest ``seed``: the first one
        that is not an integer (``None`` for a GT without one) if any, else the smallest
        (the first of equals); ``None`` for a set without images. ``grade`` judges it
        (:func:`arenabench.eval.grade.preflight.check_dataset_seed`).
    """

    presets: tuple[str, ...]
    lacking: dict[str, int]
    weakest_seed: tuple[int, Any] | None = None


@dataclass(frozen=True)
class DatasetMeta:
    """A dataset's ``dataset.json`` (written by ``arenabench generate``).

    Attributes
    ----------
    path : pathlib.Path
        The file, as the user named the dataset (for messages).
    doc : Any
        Its parsed JSON (``None`` when there is none to read: see ``problem``).
    problem : str or None
        Why it could not be read (``"missing"``, ``"not JSON (...)"``, ...), or ``None``.
    """

    path: Path
    doc: Any = None
    problem: str | None = None


def read_dataset_meta(root: str | Path) -> DatasetMeta:
    """Read ``ROOT/dataset.json``, never blocking on it.

    A missing, unreadable, too large (:data:`arenabench.limits.MAX_DATASET_META_BYTES`) or
    garbled file is a :class:`DatasetMeta` with a ``problem``: a set needs none to be scored.

    Raises
    ------
    DatasetError
        When it exists and is not a regular file (a FIFO would block a reader for ever).
    """
    from arenabench.fileio import NotRegularFileError

    path = Path(root) / "dataset.json"
    try:
        data = read_regular(path, limit=MAX_DATASET_META_BYTES)
    except NotRegularFileError as exc:
        raise DatasetError(f"{path}: {exc.strerror}") from None
    except FileNotFoundError:
        return DatasetMeta(path, problem="missing")
    except OSError as exc:
        return DatasetMeta(path, problem=f"cannot read ({exc.strerror or exc})")
    try:
        return DatasetMeta(path, doc=json.loads(data.decode("utf-8")))
    except UnicodeDecodeError:
        return DatasetMeta(path, problem="not UTF-8 text")
    except json.JSONDecodeError as exc:
        return DatasetMeta(path, problem=f"not JSON ({exc.msg} at line {exc.lineno})")
    except (RecursionError, ValueError):  # nested too deeply; an integer of too many digits
        return DatasetMeta(path, problem="not JSON")


#: Sets of at most this many images keep each item once it is built.
KEEP_ITEMS_UP_TO = 2000


class DatasetSamples(Sequence[DatasetItem]):
    """The images of a loaded dataset, in manifest order, holding only their ids and paths:
    an item's GT file is read when the item is taken (and checked against its manifest hash
    again), so a big set takes a few hundred bytes per image. A set of at most
    :data:`KEEP_ITEMS_UP_TO` images keeps each item once built.

    Parameters
    ----------
    base, shown : pathlib.Path
        The dataset folder resolved, and as the user gave it (for messages).
    entries : list of tuple
        ``(id, image, gt, gt_sha256 or None)`` with paths relative to the folder.
    """

    def __init__(self, base: Path, shown: Path,
                 entries: list[tuple[str, str, str, str | None]],
                 cache: list[DatasetItem | None] | None = None) -> None:
        self._base, self._shown, self._entries = base, shown, entries
        # a set of normal size keeps its items once built (a GT parsed once however often
        # the set is gone through, as grade does per team); a big one builds them each time
        if cache is None and len(entries) <= KEEP_ITEMS_UP_TO:
            cache = [None] * len(entries)
        self._cache = cache

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def ids(self) -> list[str]:
        """Image ids in order."""
        return [e[0] for e in self._entries]

    @property
    def image_paths(self) -> list[Path]:
        """Image files in order (no GT file read)."""
        return [self._base / e[1] for e in self._entries]

    def gt_file(self, index: int) -> Path:
        """The GT file of image ``index``, as the user named the dataset (nothing read)."""
        return self._shown / self._entries[index][2]

    @overload
    def __getitem__(self, index: int) -> DatasetItem: ...

    @overload
    def __getitem__(self, index: slice) -> DatasetSamples: ...

    def __getitem__(self, index: int | slice) -> DatasetItem | DatasetSamples:
        if isinstance(index, slice):
            return DatasetSamples(self._base, self._shown, self._entries[index],
                                  None if self._cache is None else self._cache[index])
        if self._cache is None:
            return self._item(self._entries[index])
        item = self._cache[index]
        if item is None:
            item = self._cache[index] = self._item(self._entries[index])
        return item

    def __iter__(self) -> Iterator[DatasetItem]:
        if self._cache is not None:
            for i in range(len(self._entries)):
                yield self[i]
            return
        for entry in self._entries:
            yield self._item(entry)

    def __reduce__(self) -> tuple[Any, ...]:  # a plain tuple of the items elsewhere
        return (tuple, (tuple(self),))

    def _item(self, entry: tuple[str, str, str, str | None]) -> DatasetItem:
        sid, image, gt_rel, digest = entry
        gt_path, shown_gt = self._base / gt_rel, self._shown / gt_rel
        try:
            gt_bytes = read_regular(gt_path)
        except OSError as exc:
            raise path_error(shown_gt, f"cannot read ({exc.strerror or exc})") from None
        if digest is not None and sha256_bytes(gt_bytes) != digest:
            raise path_error(shown_gt, "changed since the dataset was loaded (content does not "
                        "match gt_sha256 in manifest.jsonl)")
        record = GroundTruth.from_dict(json.loads(gt_bytes))
        return DatasetItem(id=sid, image_path=self._base / image, gt_path=gt_path, gt=record,
                           params=_flat_params(record))


def _flat_params(record: GroundTruth) -> dict[str, float]:
    """A GT's flat scalar parameters (see :attr:`DatasetItem.params`)."""
    if record.params is not None:
        return {k: float(v) for k, v in record.params.items() if isinstance(v, (int, float))}
    return flatten_numeric(record.scene or {})


def flatten_numeric(obj: Any, prefix: str = "") -> dict[str, float]:
    """Numeric scalar leaves of nested mappings as ``{"a.b.c": value}`` (booleans as 0/1;
    lists are skipped)."""
    out: dict[str, float] = {}
    if isinstance(obj, dict):
        for key, value in obj.items():
            out.update(flatten_numeric(value, f"{prefix}{key}."))
    elif isinstance(obj, bool):
        out[prefix[:-1]] = float(obj)
    elif isinstance(obj, (int, float)):
        out[prefix[:-1]] = float(obj)
    return out


def load_dataset(
    root: str | Path, *, limit: int | None = None, verify: bool = True,
    skip_damaged: bool = False, workers: int | None = None,
) -> Dataset:
    """Read and validate a dataset folder (:func:`_load_dataset`); a file or folder of it that
    cannot be read, or a symbolic link loop, is a :class:`DatasetError` naming it."""
    try:
        return _load_dataset(root, limit=limit, verify=verify, skip_damaged=skip_damaged,
                             workers=workers)
    except (OSError, RuntimeError) as exc:  # RuntimeError: Path.resolve of a link loop
        where = getattr(exc, "filename", None) or root
        raise DatasetError(f"{where}: {os_problem(exc)}") from None


def _import_textures(base: Path) -> None:
    """Put the set's texture images (``textures/``, arena textures given as image files) into
    this machine's texture cache, so that its GT scenes can be re-rendered (the phase check)
    wherever the set was made (:mod:`arenabench.generator.assets.texture_store`)."""
    folder = base / "textures"
    if not folder.is_dir():
        return
    from arenabench.generator.assets.texture_store import import_folder

    try:
        import_folder(folder)
    except (ValueError, OSError) as exc:
        raise DatasetError(f"dataset damaged: {exc}") from None


def _load_dataset(
    root: str | Path, *, limit: int | None = None, verify: bool = True,
    skip_damaged: bool = False, workers: int | None = None,
) -> Dataset:
    """Read and validate a dataset folder.

    Parameters
    ----------
    root : path-like
        Folder holding ``manifest.jsonl``, ``images/`` and ``gt/``.
    limit : int, optional
        Read only the first ``limit`` manifest entries.
    verify : bool
        Check every image and GT file against the ``image_sha256`` / ``gt_sha256`` of its
        manifest entry (default). A truncated, corrupt or swapped file is a
        :class:`DatasetError` naming it, before any image is scored. The GT bytes are hashed
        as they are parsed (read once); images are hashed in chunks.
    skip_damaged : bool, keyword-only
        An image file that cannot be a whole image (empty, text, a PNG or JPEG cut short:
        :func:`arenabench.imageio.image_file_problem`; also with a matching SHA-256 or
        without ``verify``) is a :class:`DatasetError` ("dataset damaged"); with
        ``skip_damaged`` it is left out and listed in :attr:`Dataset.skipped`.
    workers : int, keyword-only
        Processes that check the files (:mod:`arenabench.eval.datasets.check`; the same
        dataset and the same first error as one; with ``limit``, one). Default: one, or for a
        manifest of more than about 20,000 entries the usable cores, at most 4.

    A manifest path that leaves the dataset folder (absolute, ``..``, or a symbolic link out
    of it) is a :class:`DatasetError`: a dataset is a closed folder.

    Every file is checked here, before any image is scored, but only the ids and paths are
    kept: :attr:`Dataset.samples` is a :class:`DatasetSamples` that reads an image's GT file
    when its item is taken, so memory does not grow with the GT files (docs/big-sets.md).

    Returns
    -------
    Dataset

    Raises
    ------
    DatasetError
        With one line naming the file (and line or field) that is wrong.
    """
    if limit is not None and limit < 1:
        raise ValueError(f"limit must be >= 1, got {limit!r}")
    shown = Path(root)  # paths in messages as the user gave them
    base = shown.resolve()
    manifest = _manifest_of(base)
    meta = read_dataset_meta(shown)
    _import_textures(base)
    entries: list[tuple[str, str, str, str | None]] = []
    skipped: list[tuple[str, str]] = []
    presets: set[str] = set()
    lacking: dict[str, int] = {}
    weakest: list[tuple[int, Any]] = []  # (index, seed) of the weakest seed so far
    area_keys = tuple(sorted(set(AREA_REFERENCES.values())))

    def accept(entry: dict[str, Any], outcome: str, value: Any) -> None:
        """Keep a checked entry (``ok``: its :func:`_gt_facts`), or leave out a damaged
        image."""
        if outcome == "damaged":
            if not skip_damaged:
                raise DatasetError(f"dataset damaged: {shown / entry['image']}: {value} "
                                   "(--skip-damaged scores the other images)")
            skipped.append((entry["id"], value))
            return
        preset, missing, seed = value
        presets.add(preset)
        for key in missing:
            lacking.setdefault(key, len(entries))
        if not weakest or _seed_strength(seed) < _seed_strength(weakest[0][1]):
            weakest[:] = [(len(entries), seed)]
        entries.append((entry["id"], entry["image"], entry["gt"],
                        entry["gt_sha256"] if verify else None))

    workers = _check_workers(manifest, limit=limit, workers=workers)
    try:
        stream = open_regular(manifest)
    except OSError as exc:
        raise DatasetError(f"{manifest}: cannot read ({exc.strerror or exc})") from None
    with io.TextIOWrapper(stream, encoding="utf-8") as fh:  # a line at a time
        if workers > 1:
            check_manifest(_manifest_entries(fh, manifest), accept, manifest=manifest,
                           base=base, shown=shown, verify=verify, area_keys=area_keys,
                           workers=workers)
        else:
            dirs: dict[str, Path] = {}  # resolved folders of the manifest's paths
            for lineno, entry in _manifest_entries(fh, manifest):
                gt = checked_entry(entry, f"{manifest}:{lineno}", base=base, shown=shown,
                                    verify=verify, dirs=dirs)
                if isinstance(gt, str):  # a damaged image
                    accept(entry, "damaged", gt)
                else:
                    accept(entry, "ok", gt_facts(gt, area_keys))
                if limit is not None and len(entries) >= limit:
                    break
    if not entries:
        more = f" ({len(skipped)} damaged images left out)" if skipped else ""
        raise DatasetError(f"{manifest}: no entries{more}")
    return Dataset(root=base, samples=DatasetSamples(base, shown, entries),
                   skipped=tuple(skipped),
                   facts=DatasetFacts(presets=tuple(sorted(presets)), lacking=lacking,
                                      weakest_seed=weakest[0] if weakest else None),
                   meta=meta)


def _manifest_of(base: Path) -> Path:
    """The manifest of dataset folder ``base``, or one line saying why there is none."""
    manifest = base / "manifest.jsonl"
    if not base.is_dir():
        raise DatasetError(f"{base}: dataset folder does not exist")
    if manifest.exists() and not manifest.is_file():
        raise DatasetError(f"{manifest}: not a regular file")
    if not manifest.is_file():
        raise DatasetError(f"{manifest}: missing (is {base} a dataset written by the generator?)")
    return manifest


def _check_workers(manifest: Path, *, limit: int | None, workers: int | None) -> int:
    """Processes that check the files: one with ``limit``; by default one, or for a big
    manifest the usable cores (at most :data:`MAX_CHECK_WORKERS`)."""
    if limit is not None:
        return 1
    if workers is not None:
        return workers
    big = manifest.stat().st_size > PARALLEL_ABOVE_BYTES
    return min(usable_cores(), MAX_CHECK_WORKERS) if big else 1


def _seed_strength(seed: Any) -> tuple[int, int]:
    """Sort key of recorded seeds, weakest first: anything but an integer, then integers by
    size."""
    return (1, seed) if type(seed) is int else (0, 0)


def _manifest_entries(fh: Iterable[str], manifest: Path) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(line number, entry)`` of each manifest line, in order; a line that is not an entry
    (not JSON, not an object, a field missing, a duplicate id) is a :class:`DatasetError`
    when it is reached."""
    seen: set[str] = set()
    for lineno, line in enumerate(_lines(fh), 1):
        if not line.strip():
            continue
        where = f"{manifest}:{lineno}"
        try:
            entry = json.loads(line)
        except json.JSONDecodeError as exc:
            raise DatasetError(f"{where}: not JSON ({exc.msg})") from None
        if not isinstance(entry, dict):
            raise DatasetError(f"{where}: entry must be a JSON object")
        for key in ("id", "image", "gt"):
            if not isinstance(entry.get(key), str):
                raise DatasetError(f"{where}: field {key!r} missing or not a string")
        if not _IMAGE_ID.fullmatch(entry["id"]) or len(entry["id"]) > MAX_IMAGE_ID_CHARS:
            raise DatasetError(
                f"{where}: field 'id' {_quoted(entry['id'])}: an image id is 1 to "
                f"{MAX_IMAGE_ID_CHARS} letters, digits, '.', '_' or '-', not starting with "
                "'.' or '-'")
        for key in ("image", "gt"):
            if not entry[key].isprintable():
                raise DatasetError(f"{where}: field {key!r} {_quoted(entry[key])}: a path "
                                   "holds no newline or other control character")
        if entry["id"] in seen:
            raise DatasetError(f"{where}: duplicate id {entry['id']!r}")
        seen.add(entry["id"])
        yield lineno, entry


#: What an image id may be (and at most :data:`arenabench.limits.MAX_IMAGE_ID_CHARS` long):
#: it names files (``gt/<id>.json``) and rows of every report.
_IMAGE_ID = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]*")


def _quoted(text: str, keep: int = 60) -> str:
    """``repr(text)``, shortened to about ``keep`` characters (one line whatever it holds)."""
    if len(text) <= keep:
        return repr(text)
    return f"{text[:keep - 20]!r}... ({len(text)} characters)"


def _lines(fh: Iterable[str]) -> Iterator[str]:
    """The lines of a text stream as :meth:`str.splitlines` splits the whole text."""
    for raw in fh:
        yield from raw.splitlines()


