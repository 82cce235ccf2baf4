"""Read a dataset written by the generator: ``manifest.jsonl`` plus ``gt/*.json`` (schema
``arenabench.gt/1``), validated with one-line errors that name the file and the field."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .records import Truth

GT_SCHEMA = "arenabench.gt/1"
#: ``--area-reference`` name -> GT ``area`` field. ``contour_px`` is absent from GT files
#: written before generator version 4.
AREA_REFERENCES: dict[str, str] = {
    "visible": "visible_px", "footprint": "footprint_px", "contour": "contour_px",
}


class DatasetError(ValueError):
    """A dataset is missing or malformed; the message names the file and field."""


@dataclass(frozen=True)
class Sample:
    """One image of a dataset with its ground truth.

    Parameters
    ----------
    id : str
        Image id (``"000042"``).
    image_path : pathlib.Path
        Absolute path of the image.
    gt_path : pathlib.Path
        Absolute path of the GT JSON.
    gt : dict
        The parsed GT JSON.
    params : dict
        Flat scalar scene parameters with dotted keys (GT ``params``, or the numeric leaves
        of ``scene`` when ``params`` is absent).
    """

    id: str
    image_path: Path
    gt_path: Path
    gt: dict[str, Any]
    params: dict[str, float] = field(default_factory=dict)

    def truth(self, *, area_reference: str = "visible") -> Truth:
        """Ground truth to score against (area per ``area_reference``)."""
        if area_reference not in AREA_REFERENCES:
            raise ValueError(
                f"area_reference must be one of {sorted(AREA_REFERENCES)}, got {area_reference!r}"
            )
        key = AREA_REFERENCES[area_reference]
        if key not in self.gt["area"]:
            raise _fail(self.gt_path, f"field 'area.{key}' is missing (written by an older "
                                      f"generator?): regenerate the dataset to score against "
                                      f"--area-reference {area_reference}")
        return Truth(
            count=int(self.gt["count"]),
            area=float(self.gt["area"][key]),
            marker_ids=tuple(
                int(m["id"])
                for m in self.gt.get("markers", [])
                # "visible" (in view and not occluded) when the GT has it, else "in_view"
                if m.get("visible", m.get("in_view", True))
            ),
        )


@dataclass(frozen=True)
class Dataset:
    """A validated dataset."""

    root: Path
    samples: tuple[Sample, ...]

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


def _fail(path: Path, what: str) -> DatasetError:
    return DatasetError(f"{path}: {what}")


def _number(gt: dict, path: Path, dotted: str) -> float:
    node: Any = gt
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            raise _fail(path, f"missing field {dotted!r}")
        node = node[part]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        raise _fail(path, f"field {dotted!r} must be a number, got {node!r}")
    return float(node)


def validate_gt(gt: Any, path: Path) -> None:
    """Check the GT fields the harness uses.

    Raises
    ------
    DatasetError
        Naming ``path`` and the first bad field.
    """
    if not isinstance(gt, dict):
        raise _fail(path, "ground truth must be a JSON object")
    if gt.get("schema") != GT_SCHEMA:
        raise _fail(path, f"field 'schema' must be {GT_SCHEMA!r}, got {gt.get('schema')!r}")
    count = _number(gt, path, "count")
    if count < 0 or count != int(count):
        raise _fail(path, f"field 'count' must be a non-negative integer, got {gt['count']!r}")
    optional = ("area.contour_px",) if "contour_px" in (gt.get("area") or {}) else ()
    for key in ("area.visible_px", "area.footprint_px", *optional):
        if _number(gt, path, key) < 0:
            raise _fail(path, f"field {key!r} must be >= 0")
    for key in ("markers", "obstacles"):
        if not isinstance(gt.get(key, []), list):
            raise _fail(path, f"field {key!r} must be a list")
    for i, marker in enumerate(gt.get("markers", [])):
        if not isinstance(marker, dict) or "id" not in marker:
            raise _fail(path, f"field 'markers[{i}].id' is missing")
    if "params" in gt and not isinstance(gt["params"], dict):
        raise _fail(path, "field 'params' must be an object")


def load_dataset(root: str | Path, *, limit: int | None = None) -> Dataset:
    """Read and validate a dataset folder.

    Parameters
    ----------
    root : path-like
        Folder holding ``manifest.jsonl``, ``images/`` and ``gt/``.
    limit : int, optional
        Read only the first ``limit`` manifest entries.

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
    base = Path(root).resolve()
    manifest = base / "manifest.jsonl"
    if not base.is_dir():
        raise DatasetError(f"{base}: dataset folder does not exist")
    if not manifest.is_file():
        raise DatasetError(f"{manifest}: missing (is {base} a dataset written by the generator?)")
    samples: list[Sample] = []
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
        image_path, gt_path = base / entry["image"], base / entry["gt"]
        if not image_path.is_file():
            raise DatasetError(f"{where}: image file {image_path} does not exist")
        if not gt_path.is_file():
            raise DatasetError(f"{where}: ground-truth file {gt_path} does not exist")
        try:
            gt = json.loads(gt_path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise _fail(gt_path, f"not JSON ({exc.msg} at line {exc.lineno})") from None
        validate_gt(gt, gt_path)
        params = gt.get("params")
        flat = (
            {k: float(v) for k, v in params.items() if isinstance(v, (int, float))}
            if isinstance(params, dict)
            else flatten_numeric(gt.get("scene", {}))
        )
        samples.append(
            Sample(id=entry["id"], image_path=image_path, gt_path=gt_path, gt=gt, params=flat)
        )
        if limit is not None and len(samples) >= limit:
            break
    if not samples:
        raise DatasetError(f"{manifest}: no entries")
    return Dataset(root=base, samples=tuple(samples))
