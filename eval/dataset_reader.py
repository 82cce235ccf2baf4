"""Read a dataset written by the generator: ``manifest.jsonl`` plus ``gt/*.json`` (schema
``arenabench.gt/1``), validated with one-line errors that name the file and the field."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from arenabench.fileio import sha256_bytes, sha256_file
from arenabench.gtrecord import AREA_REFERENCES as AREA_REFERENCES  # declared there
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE as DEFAULT_AREA_REFERENCE
from arenabench.gtrecord import GroundTruth
from arenabench.imageio import image_file_problem
from arenabench.schemas import gt_problem

from .results import Truth


class DatasetError(ValueError):
    """A dataset is missing or malformed; the message names the file and field."""


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

    def truth(self, *, area_reference: str = "visible") -> Truth:
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
            raise _fail(self.gt_path, f"field 'area.{key}' is missing (written by an older "
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
    samples: tuple[DatasetItem, ...]
    #: (manifest id, why) of the damaged images left out (``load_dataset(skip_damaged=True)``)
    skipped: tuple[tuple[str, str], ...] = ()

    @property
    def name(self) -> str:
        """Folder name of the dataset."""
        return self.root.name

    def __len__(self) -> int:
        return len(self.samples)


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


def _is_sha256(value: Any) -> bool:
    return (
        isinstance(value, str) and len(value) == 64
        and all(c in "0123456789abcdef" for c in value)
    )


def _fail(path: Path, what: str) -> DatasetError:
    return DatasetError(f"{path}: {what}")


def validate_gt(gt: Any, path: Path) -> None:
    """Check a parsed GT record against the ``arenabench.gt/1`` JSON Schema (shipped in
    :mod:`arenabench.schemas`) and that every number in it is finite.

    Raises
    ------
    DatasetError
        One line naming ``path``, the field and the problem, e.g.
        ``gt/000003.json: area.visible_px: nan is not a finite number``.
    """
    problem = gt_problem(gt)
    if problem is not None:
        raise _fail(path, problem)


def load_dataset(
    root: str | Path, *, limit: int | None = None, verify: bool = True,
    skip_damaged: bool = False,
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

    A manifest path that leaves the dataset folder (absolute, ``..``, or a symbolic link out
    of it) is a :class:`DatasetError`: a dataset is a closed folder.

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
    manifest = base / "manifest.jsonl"
    if not base.is_dir():
        raise DatasetError(f"{base}: dataset folder does not exist")
    if manifest.exists() and not manifest.is_file():
        raise DatasetError(f"{manifest}: not a regular file")
    if not manifest.is_file():
        raise DatasetError(f"{manifest}: missing (is {base} a dataset written by the generator?)")
    samples: list[DatasetItem] = []
    skipped: list[tuple[str, str]] = []
    seen: set[str] = set()
    for lineno, line in enumerate(manifest.read_text(encoding="utf-8").splitlines(), 1):
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
        if entry["id"] in seen:
            raise DatasetError(f"{where}: duplicate id {entry['id']!r}")
        seen.add(entry["id"])
        if verify:
            for key in ("image_sha256", "gt_sha256"):
                if not _is_sha256(entry.get(key)):
                    raise DatasetError(
                        f"{where}: field {key!r} missing or not a SHA-256 hex digest "
                        "(--no-verify skips the check)"
                    )
        for key in ("image", "gt"):
            rel = entry[key]
            inside = not os.path.isabs(rel) and (base / rel).resolve().is_relative_to(base)
            if not inside:
                raise DatasetError(f"{where}: {key} path {rel!r} leaves the dataset folder "
                                   f"{shown} (a dataset is a closed folder)")
        image_path, gt_path = base / entry["image"], base / entry["gt"]
        shown_image, shown_gt = shown / entry["image"], shown / entry["gt"]
        for what, path, shown_path in (("image", image_path, shown_image),
                                       ("ground-truth", gt_path, shown_gt)):
            if not path.is_file():
                why = "is not a regular file" if path.exists() else "does not exist"
                raise DatasetError(f"{where}: {what} file {shown_path} {why}")
        try:
            gt_bytes = gt_path.read_bytes()
        except OSError as exc:
            raise _fail(shown_gt, f"cannot read ({exc.strerror or exc})") from None
        if verify and sha256_bytes(gt_bytes) != entry["gt_sha256"]:
            raise _fail(shown_gt, "content does not match gt_sha256 in manifest.jsonl "
                        "(corrupt or replaced; --no-verify skips the check)")
        if verify:
            try:
                digest = sha256_file(image_path)
            except OSError as exc:
                raise _fail(shown_image, f"cannot read ({exc.strerror or exc})") from None
            if digest != entry["image_sha256"]:
                raise _fail(shown_image, "content does not match image_sha256 in manifest.jsonl "
                            "(truncated, corrupt or replaced; --no-verify skips the check)")
        damage = image_file_problem(image_path)
        if damage is not None:
            if not skip_damaged:
                raise DatasetError(f"dataset damaged: {shown_image}: {damage} (--skip-damaged "
                                   "scores the other images)")
            skipped.append((entry["id"], damage))
            continue
        try:
            gt = json.loads(gt_bytes.decode("utf-8"))
        except UnicodeDecodeError:
            raise _fail(shown_gt, "not UTF-8 text") from None
        except json.JSONDecodeError as exc:
            raise _fail(shown_gt, f"not JSON ({exc.msg} at line {exc.lineno})") from None
        except RecursionError:
            raise _fail(shown_gt, "not JSON (nested too deeply)") from None
        validate_gt(gt, shown_gt)
        record = GroundTruth.from_dict(gt)
        flat = (
            {k: float(v) for k, v in record.params.items() if isinstance(v, (int, float))}
            if record.params is not None
            else flatten_numeric(record.scene or {})
        )
        samples.append(DatasetItem(id=entry["id"], image_path=image_path, gt_path=gt_path,
                                   gt=record, params=flat))
        if limit is not None and len(samples) >= limit:
            break
    if not samples:
        more = f" ({len(skipped)} damaged images left out)" if skipped else ""
        raise DatasetError(f"{manifest}: no entries{more}")
    return Dataset(root=base, samples=tuple(samples), skipped=tuple(skipped))
