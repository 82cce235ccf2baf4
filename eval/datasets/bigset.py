"""Synthetic big datasets for scale tests and ``arenabench bench``: N manifest entries with
tiny images and real ground truth, written in seconds.

Every entry is valid by the dataset format (docs/formats.md): its GT file is a real
``arenabench.gt/1`` record (one of ``templates`` scenes of a preset, computed analytically:
nothing is rendered) with the entry's own ``id``, ``index`` and ``image``, and the manifest
carries the SHA-256 of every file. The images are one 8 x 8 PNG, hard-linked under each
entry's name (copied where the file system cannot link), so 100,000 entries take about
1.3 GB of GT files and one image's worth of image data.

A trivial pipeline for such a set is :func:`fixed_answer`
(``arenabench.eval.datasets.bigset:fixed_answer``): it answers the same for every image, so
the report's counts are known from the GT alone.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from arenabench.fileio import dumps_json, sha256_bytes
from arenabench.generator.parameters.presets import DEFAULT_PRESET

#: What :func:`fixed_answer` reports for every image.
FIXED_COUNT = 2
FIXED_AREA = 10000.0
_ID, _IMAGE, _INDEX = "@@id@@", "@@image@@", 987654321987
#: Hard links per image file (ext4 allows 65,000 per inode).
_LINKS_PER_FILE = 50_000


def fixed_answer(image: Any) -> dict[str, Any]:
    """A do-nothing pipeline: the same answer (:data:`FIXED_COUNT`, :data:`FIXED_AREA`)
    whatever the image."""
    return {"count": FIXED_COUNT, "area": FIXED_AREA}


def _passes(record: dict[str, Any]) -> bool:
    """Whether :func:`fixed_answer` passes on a GT record (visible area, default tolerance)."""
    from arenabench.competition import DEFAULT_TOLERANCE

    area = record["area"]["visible_px"]
    return record["count"] == FIXED_COUNT and abs(FIXED_AREA - area) <= DEFAULT_TOLERANCE * area


@dataclass(frozen=True)
class BigSet:
    """A synthetic dataset on disk.

    Attributes
    ----------
    root : pathlib.Path
        The dataset folder.
    count : int
        Manifest entries.
    passes : int
        Images :func:`fixed_answer` passes (at the default tolerance, visible area).
    """

    root: Path
    count: int
    passes: int


def template_records(n: int, *, preset: str = DEFAULT_PRESET,
                     seed: int = 0) -> list[dict[str, Any]]:
    """GT records (JSON form) of scenes ``0 .. n-1`` of ``preset``, computed without rendering."""
    from arenabench.fileio import rounded
    from arenabench.generator.dataset.make import ground_truth_record, scene_id
    from arenabench.generator.model.sampler import sample_scene

    out = []
    for i in range(n):
        sampled = sample_scene(preset, seed=seed, index=i)
        out.append(ground_truth_record(sampled.scene, sid=scene_id(i), preset=preset, seed=seed,
                                       index=i, params=rounded(sampled.params)).to_dict())
    return out


def tiny_png() -> bytes:
    """An 8 x 8 grey PNG."""
    ok, buf = cv2.imencode(".png", np.full((8, 8, 3), 128, np.uint8))
    assert ok
    return buf.tobytes()


def write_big_set(out: str | os.PathLike[str], count: int, *, templates: int = 16,
                  preset: str = DEFAULT_PRESET, seed: int = 0) -> BigSet:
    """Write a synthetic dataset of ``count`` entries into the new folder ``out``.

    Parameters
    ----------
    out : path-like
        Folder to create (must not exist).
    count : int
        Manifest entries (ids ``000000`` ...).
    templates, preset, seed : keyword-only
        Scene ``i`` uses the GT of template scene ``i % templates`` of ``preset``.

    Returns
    -------
    BigSet
    """
    from arenabench.generator.dataset.dataset_writer import image_file, manifest_line
    from arenabench.generator.dataset.make import scene_id

    if count < 1:
        raise ValueError(f"count must be >= 1, got {count!r}")
    root = Path(out)
    root.mkdir(parents=True)
    (root / "images").mkdir()
    (root / "gt").mkdir()
    records = template_records(min(templates, count), preset=preset, seed=seed)
    # the first template passes: its answer becomes the fixed one's
    records[0]["count"] = FIXED_COUNT
    records[0]["area"] = dict(records[0]["area"], visible_px=FIXED_AREA)
    passing = [_passes(r) for r in records]
    # each template serialised once; an entry's id, index and image are put in the text
    texts = [dumps_json(dict(r, id=_ID, index=_INDEX, image=_IMAGE)) for r in records]
    png = tiny_png()
    image_sha = sha256_bytes(png)
    source: Path | None = None
    lines: list[str] = []
    passes = 0
    with open(root / "manifest.jsonl", "w", encoding="utf-8") as manifest:
        for i in range(count):
            sid = scene_id(i)
            k = i % len(records)
            passes += passing[k]
            image = image_file(sid, "png")
            gt_bytes = (texts[k].replace(f'"{_ID}"', f'"{sid}"', 1)
                        .replace(str(_INDEX), str(i), 1)
                        .replace(f'"{_IMAGE}"', f'"{image}"', 1).encode("utf-8"))
            (root / "gt" / f"{sid}.json").write_bytes(gt_bytes)
            if source is None or i % _LINKS_PER_FILE == 0:
                source = root / image
                source.write_bytes(png)
            else:
                try:
                    os.link(source, root / image)
                except OSError:
                    (root / image).write_bytes(png)
            lines.append(manifest_line(sid, "png", image_sha, sha256_bytes(gt_bytes)))
            if len(lines) >= 4096:
                manifest.write("".join(lines))
                lines.clear()
        manifest.write("".join(lines))
    return BigSet(root=root, count=count, passes=passes)

