"""Writing datasets to disk: images, GT files, manifest, dataset.json and coco.json.

Layout of ``DIR``::

    images/NNNNNN.png   gt/NNNNNN.json   manifest.jsonl   dataset.json   coco.json

(``images/NNNNNN.jpg`` when the preset's ``output.format`` is ``jpeg``, as ``eyrc``'s is.)

Every file is written atomically. ``dataset.json`` is written first (``"complete": false``)
with the run's arguments, so a re-run can tell an interrupted run of the same arguments
(resumed: scenes whose image and GT exist are skipped) from a different one (refused; a
larger ``count`` with otherwise equal arguments extends the set, since scenes are
independent by index, and gives the same files as generating the larger count at once); the
manifest and ``coco.json`` are written last, in id order, and ``dataset.json`` is rewritten
with ``"complete": true``. Output is byte-identical for the same arguments whatever the
number of workers (one spawned process per worker, one renderer each).

On a Dask cluster (``scheduler=``) the workers render and encode, and this process writes the
files they send back, so the output folder needs no shared file system.

Interrupted (SIGINT/SIGTERM inside :func:`arenabench.interrupts.stop_on_signals`), a run stops
its workers, writes ``manifest.jsonl`` for the scenes finished so far and ``dataset.json``
with ``"complete": false`` and ``"finished"``, and returns; running it again resumes and ends
with the same files as an uninterrupted run.
"""

from __future__ import annotations

import contextlib
import json
import os
import shlex
import shutil
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from shapely.geometry import Polygon, box

from arenabench import __version__
from arenabench.fileio import (
    LOCK_FILE,
    FolderLockedError,
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    dumps_json_line,
    is_temp_name,
    lock_folder,
    remove_temp_files,
    rounded,
    sha256_bytes,
    sha256_file,
)
from arenabench.generator.assets import texture_store
from arenabench.generator.dataset.coco_export import CocoParts, write_coco
from arenabench.generator.dataset.make import (
    GENERATOR_VERSION,
    ImageFormat,
    make_sample,
    scene_id,
    worker_gl_info,
    worker_renderer,
)
from arenabench.generator.model.scene import RenderSpec
from arenabench.generator.parameters.param_values import format_value
from arenabench.generator.parameters.params import Range, Value
from arenabench.generator.parameters.preset_files import RESERVED_KEYS, ResolvedPreset, texture_refs
from arenabench.generator.parameters.presets import builtin_preset, resolve
from arenabench.generator.rendering.edges import EDGE_RESOLVES, edge_model
from arenabench.gtrecord import GroundTruth
from arenabench.imageio import (
    DEFAULT_JPEG_SUBSAMPLING,
    IMAGE_EXTENSIONS,
    PNG_COMPRESSION,
    jpeg_subsampling_problem,
)
from arenabench.interrupts import (
    Interrupted,
    signal_name,
    worker_task,
)
from arenabench.jsonstream import atomic_text_writer
from arenabench.limits import MAX_DATASET_SCENES, MAX_WORKERS, check_at_most
from arenabench.local_pool import local_map
from arenabench.seeds import check_seed
from arenabench.workers import check_workers

#: dataset.json schema id.
DATASET_SCHEMA = "arenabench.dataset/1"


class GenerateError(ValueError):
    """The output directory cannot be used for this run (the message says why)."""


@dataclass(frozen=True)
class DatasetArgs:
    """The arguments that define a dataset's content.

    ``preset`` is given as a built-in preset's name or a preset file's
    :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`, and kept as the latter.
    """

    preset: ResolvedPreset
    count: int
    seed: int
    overrides: dict[str, Value] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.preset, ResolvedPreset):
            object.__setattr__(self, "preset", builtin_preset(str(self.preset)))
        if int(self.count) != self.count or self.count < 0:
            raise ValueError(f"count must be an integer >= 0, got {self.count!r}")
        check_at_most(int(self.count), MAX_DATASET_SCENES, "count")
        check_seed(self.seed)
        image_format, _, subsampling = self.output
        if image_format == "jpeg" and (problem := jpeg_subsampling_problem(subsampling)):
            raise ValueError(f"output.jpeg_subsampling: {problem}")

    @property
    def output(self) -> tuple[str, int, str]:
        """``(output.format, output.jpeg_quality, output.jpeg_subsampling)`` of the preset
        with the overrides."""
        params = resolve(self.preset, self.overrides)
        return (str(params["output.format"]), int(params["output.jpeg_quality"]),
                str(params["output.jpeg_subsampling"]))

    @property
    def image_ext(self) -> str:
        """File extension of the images (``png`` or ``jpg``)."""
        return IMAGE_EXTENSIONS[self.output[0]]

    @property
    def textures(self) -> list[str]:
        """References of the texture images the set uses (``textures/<sha256>.png``): the
        preset's and the overrides' (:mod:`arenabench.generator.assets.texture_store`)."""
        return sorted({*texture_refs(self.preset.params),
                       *texture_refs(resolve(self.preset, self.overrides))})

    def to_dict(self) -> dict[str, Any]:
        """JSON form stored under ``dataset.json["args"]``."""
        return {
            "preset": self.preset.name, "count": int(self.count), "seed": int(self.seed),
            "overrides": {k: format_value(v) for k, v in sorted(self.overrides.items())},
            "generator_version": GENERATOR_VERSION,
        }


@dataclass
class DatasetResult:
    """What :func:`generate_dataset` did.

    Attributes
    ----------
    out : Path
        The dataset directory.
    rendered, skipped : int
        Scenes rendered now / found already on disk.
    count : int
        Scenes of the dataset.
    interrupted : int or None
        The signal that stopped the run (then only ``finished`` scenes are on disk).
    finished : int
        Scenes on disk when the run ended (``count`` unless interrupted).
    seconds : float
        Wall time.
    timings_ms : dict
        Median per-image ms of ``sample``, ``render``, ``gt``, ``encode``, ``write`` (rendered
        scenes only; empty when nothing was rendered).
    task_cpu_ms : float
        Mean CPU ms per rendered scene in the process that rendered it (all its threads:
        render, GT, encode, write), each renderer's first scene left out, without process
        start-up and finishing the set (0 when nothing was rendered): comparable with a warm
        renderer's in-memory CPU per image.
    """

    out: Path
    rendered: int
    skipped: int
    seconds: float
    timings_ms: dict[str, float] = field(default_factory=dict)
    count: int = 0
    interrupted: int | None = None
    finished: int = 0
    task_cpu_ms: float = 0.0

    @property
    def complete(self) -> bool:
        """Whether every scene is on disk with the manifest and ``coco.json``."""
        return self.interrupted is None

    def summary(self) -> str:
        """One line for the CLI."""
        if self.interrupted is not None:
            return (f"interrupted by {signal_name(self.interrupted)}: {self.finished} of "
                    f"{self.count} images written to {self.out}; run the same command again "
                    "to resume")
        if not self.rendered:
            return f"{self.out}: already complete: {self.skipped} images"
        rate = self.rendered / self.seconds if self.seconds > 0 and self.rendered else 0.0
        parts = [f"{self.rendered} rendered", f"{self.skipped} already present",
                 f"{self.seconds:.1f} s", f"{rate:.1f} images/s"]
        if self.timings_ms:
            parts.append("median ms/image " + ", ".join(
                f"{k} {v:.1f}" for k, v in self.timings_ms.items()))
        return f"{self.out}: " + "; ".join(parts)


# ----------------------------------------------------------------------------- workers

@dataclass(frozen=True)
class RenderTask:
    """One scene to render, sent to a worker (picklable).

    Attributes
    ----------
    args : dict
        :meth:`DatasetArgs.to_dict` of the run.
    seed, index : int
        Run seed and scene index.
    out : str
        Dataset directory (local workers write the files there).
    image_format : str
        ``output.format`` (``png`` or ``jpeg``).
    jpeg_quality : int
        ``output.jpeg_quality``.
    jpeg_subsampling : str
        ``output.jpeg_subsampling``.
    preset : ResolvedPreset
        The preset (a preset file's parameters travel with the task); ``None``: the built-in
        preset ``args["preset"]``.
    textures : tuple of (str, bytes)
        The texture images the scene needs, ``(reference, bytes)``: only in a cluster's
        tasks (local workers find them in this machine's texture cache).
    """

    args: dict[str, Any]
    seed: int
    index: int
    out: str
    image_format: str = "png"
    jpeg_quality: int = 95
    jpeg_subsampling: str = DEFAULT_JPEG_SUBSAMPLING
    preset: ResolvedPreset | None = None
    textures: tuple[tuple[str, bytes], ...] = ()

    @property
    def image_ext(self) -> str:
        """File extension of the image."""
        return IMAGE_EXTENSIONS[self.image_format]

    @property
    def output(self) -> ImageFormat:
        """How the image is encoded."""
        return ImageFormat(self.image_format, self.jpeg_quality, self.jpeg_subsampling)


def _render(task: RenderTask):
    preset = task.preset if task.preset is not None else task.args["preset"]
    sample = make_sample(preset, seed=task.seed, index=task.index,
                         overrides=_parse_stored(task.args["overrides"]),
                         renderer=worker_renderer())
    if sample.output != task.output:  # pragma: no cover - the task is made from the preset
        raise RuntimeError(f"scene {task.index}: encoded as {sample.output}, the set as "
                           f"{task.output}")
    return sample


def image_file(sid: str, ext: str) -> str:
    """Path of scene ``sid``'s image relative to the dataset (``images/000042.png``)."""
    return f"images/{sid}.{ext}"


def render_task(task: RenderTask) -> dict[str, Any]:
    """A local worker's unit: render, encode and write one scene's image and GT.

    Returns
    -------
    dict
        ``id``, the timings in ms (``sample``, ``render``, ``gt``, ``encode``, ``write``),
        ``cpu`` (CPU ms of the whole task, all threads), ``worker`` (:func:`_worker_key`),
        ``gl`` (the worker's OpenGL strings), ``image_sha256``, ``gt_sha256`` and ``coco``
        (:func:`coco_parts`), which finishing the set uses instead of reading the files.
    """
    with worker_task():
        c0 = time.process_time()
        out = Path(task.out)
        sample = _render(task)
        t1 = time.perf_counter()
        image = sample.image_bytes
        t2 = time.perf_counter()
        gt_bytes = sample.record.to_json().encode("utf-8")
        atomic_write_bytes(out / image_file(sample.id, task.image_ext), image)
        atomic_write_bytes(out / "gt" / f"{sample.id}.json", gt_bytes)
        t3 = time.perf_counter()
        return {"id": sample.id, **sample.timings_ms, "encode": (t2 - t1) * 1000,
                "write": (t3 - t2) * 1000, "gl": worker_gl_info(),
                "image_sha256": sha256_bytes(image), "gt_sha256": sha256_bytes(gt_bytes),
                "coco": coco_parts(sample.record), "cpu": (time.process_time() - c0) * 1000,
                "worker": _worker_key()}


def _worker_key() -> str:
    """The rendering process and thread (one renderer each)."""
    return f"{os.getpid()}:{threading.get_ident()}"


def _warm_task_cpu_ms(results: list[dict[str, Any]]) -> float:
    """Mean ``cpu`` of the tasks, leaving out each renderer's first (its OpenGL set-up and
    first draw), or of all of them when no renderer did more than one."""
    seen: set[str] = set()
    warm = []
    for res in results:
        if res["worker"] in seen:
            warm.append(res["cpu"])
        seen.add(res["worker"])
    cpu = warm or [res["cpu"] for res in results]
    return float(np.mean(cpu)) if cpu else 0.0


def render_on_cluster(task: RenderTask) -> dict[str, Any]:
    """A Dask worker's unit: render and encode as :func:`render_task`, but return the bytes
    (``image_bytes``, ``image_ext``, ``gt_text``) for the client to write
    (:func:`write_rendered`).

    The renderer is created on first use, one per worker thread (an OpenGL context is current
    in one thread only; :func:`arenabench.generator.dataset.make.worker_renderer`), and reused. The
    task's texture images go into the worker's texture cache first (it may be on another
    machine).
    """
    c0 = time.process_time()
    for ref, data in task.textures:
        texture_store.add_bytes(ref, data)
    sample = _render(task)
    t1 = time.perf_counter()
    image = sample.image_bytes
    t2 = time.perf_counter()
    return {**sample.timings_ms, "id": sample.id, "image_bytes": image,
            "image_ext": task.image_ext,
            "gt_text": sample.record.to_json(), "encode": (t2 - t1) * 1000,
            "gl": worker_gl_info(), "coco": coco_parts(sample.record),
            "cpu": (time.process_time() - c0) * 1000, "worker": _worker_key()}


def write_rendered(out: Path, res: dict[str, Any]) -> dict[str, Any]:
    """Write the files of a scene rendered on a cluster; returns the same record as
    :func:`render_task` (without the bytes)."""
    c0 = time.process_time()
    gt_bytes = res["gt_text"].encode("utf-8")
    t2 = time.perf_counter()
    atomic_write_bytes(out / image_file(res["id"], res["image_ext"]), res["image_bytes"])
    atomic_write_bytes(out / "gt" / f"{res['id']}.json", gt_bytes)
    t3 = time.perf_counter()
    return {**{k: v for k, v in res.items() if k not in ("image_bytes", "image_ext", "gt_text")},
            "write": (t3 - t2) * 1000, "image_sha256": sha256_bytes(res["image_bytes"]),
            "gt_sha256": sha256_bytes(gt_bytes),
            "cpu": res["cpu"] + (time.process_time() - c0) * 1000}


def _parse_stored(overrides: dict[str, str]) -> dict[str, Value]:
    from arenabench.generator.parameters.param_values import parse_override

    return dict(parse_override(f"{k}={v}") for k, v in overrides.items())


# ----------------------------------------------------------------------------- checks

def _check_existing(out: Path, args: DatasetArgs) -> dict[str, Any] | None:
    """The existing dataset.json when ``out`` holds a run of the same arguments, else None.

    Raises
    ------
    GenerateError
        When ``out`` holds something else (the message names the differing argument).
    """
    meta_path = out / "dataset.json"
    if not out.exists():
        return None
    if meta_path.exists() and not meta_path.is_file():  # a FIFO would block the read
        raise GenerateError(f"{meta_path} is not a regular file: refusing to use {out}")
    if not meta_path.exists():
        if any(p.name != LOCK_FILE and not is_temp_name(p.name) for p in out.iterdir()):
            raise GenerateError(f"{out} is not empty and holds no dataset.json: refusing to "
                               "write a dataset into it")
        return None
    try:
        meta = json.loads(meta_path.read_text())
        old = meta["args"]
        if not isinstance(old, dict):
            raise TypeError("args is not an object")
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        why = "nested too deeply" if isinstance(exc, RecursionError) else exc
        raise GenerateError(f"{meta_path} is unreadable ({why}): refusing to overwrite") from None
    new = args.to_dict()
    for key in ("preset", "count", "seed", "overrides", "generator_version"):
        if key == "count" and isinstance(old.get(key), int) and new[key] > old[key]:
            continue  # extending a set: scenes are independent by index
        if key == "count" and isinstance(old.get(key), int) and new[key] < old[key]:
            raise GenerateError(
                f"{out} holds {old[key]} scenes and --count {new[key]} is smaller: a set can "
                "grow (same seed, preset and --set) but not shrink (use another --out)"
            )
        if old.get(key) != new[key]:
            name = {"overrides": "--set"}.get(key, f"--{key}")
            raise GenerateError(
                f"{out} was generated with different arguments: {name} was "
                f"{old.get(key)!r}, now {new[key]!r} (use another --out)"
            )
    _check_same_preset(out, meta, args.preset)
    return meta


def _parameters(definition: Any) -> dict[str, Any]:
    """The parameter sections of a preset file's document (``dataset.json``'s
    ``preset_definition``)."""
    if not isinstance(definition, dict):
        return {}
    return {k: v for k, v in definition.items() if k not in RESERVED_KEYS}


def _check_same_preset(out: Path, meta: dict[str, Any], preset: ResolvedPreset) -> None:
    """Refuse to add to a set made from a preset of the same name but other parameters (a
    set made before ``preset_definition`` was recorded is checked by name only)."""
    if "preset_definition" not in meta:
        return
    old, new = _parameters(meta["preset_definition"]), _parameters(preset.document())
    if old == new:
        return
    for section in sorted(set(old) | set(new)):
        was, now = old.get(section) or {}, new.get(section) or {}
        for key in sorted(set(was) | set(now)):
            if was.get(key) != now.get(key):
                raise GenerateError(
                    f"{out} was generated from another preset {preset.name!r}: "
                    f"{section}.{key} was {was.get(key)!r}, now {now.get(key)!r} (use another "
                    "--out; the set's own preset is --preset "
                    f"{out / 'dataset.json'})")
    raise GenerateError(f"{out} was generated from another preset {preset.name!r} (use "
                        "another --out)")  # pragma: no cover - differing sections are keys


def _present(out: Path, sid: str, ext: str) -> bool:
    return (out / image_file(sid, ext)).is_file() and (out / "gt" / f"{sid}.json").is_file()


# ----------------------------------------------------------------------------- outputs

def coco_from_gts(gts: list[GroundTruth]) -> dict[str, Any]:
    """COCO instances for a list of GT records (obstacles: category 1, markers: category 2).

    Polygons are the image-space polygons (convex hull of each box's projected vertices,
    marker quadrilaterals) shifted by +0.5 px to COCO's pixel-corner convention and clipped
    to the image; ``area`` is the clipped polygon's area and ``bbox`` its bounds.
    """
    return _coco_document([coco_parts(gt) for gt in gts])


def coco_parts(gt: GroundTruth) -> dict[str, Any]:
    """One scene's share of :func:`coco_from_gts`, floats rounded: ``image`` (its ``images``
    entry) and ``annotations`` (without ``id``, which numbers them across the set).

    Computed where the scene is rendered, so finishing a set neither reads nor parses its GT
    files again.
    """
    image_id = int(gt.index)
    w, h = gt.image_size
    frame = box(0.0, 0.0, float(w), float(h))
    polys = [(1, ob.image_polygon_px) for ob in gt.obstacles]
    polys += [(2, m.corners_px) for m in gt.markers]
    annotations = []
    for category, pts in polys:
        if len(pts) < 3:
            continue
        poly = Polygon(np.asarray(pts) + 0.5).intersection(frame)
        if poly.is_empty or poly.area <= 0 or poly.geom_type != "Polygon":
            continue
        coords = np.asarray(poly.exterior.coords)[:-1]
        x0, y0, x1, y1 = poly.bounds
        annotations.append({
            "image_id": image_id, "category_id": category,
            "segmentation": [coords.reshape(-1).tolist()], "area": poly.area,
            "bbox": [x0, y0, x1 - x0, y1 - y0], "iscrowd": 0,
        })
    return rounded({"image": {"id": image_id, "file_name": gt.image, "width": w, "height": h},
                    "annotations": annotations})


def _coco_document(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """The COCO file of the scenes' :func:`coco_parts`, in order (annotations numbered 1..)."""
    annotations = []
    for part in parts:
        for ann in part["annotations"]:
            annotations.append({"id": len(annotations) + 1, **ann})
    return {"info": dict(COCO_INFO), "images": [part["image"] for part in parts],
            "annotations": annotations, "categories": [dict(c) for c in COCO_CATEGORIES]}


#: ``info`` and ``categories`` of every ``coco.json``.
COCO_INFO: dict[str, Any] = {"description": "arenabench synthetic arena scenes", "version": "1"}
COCO_CATEGORIES: list[dict[str, Any]] = [
    {"id": 1, "name": "obstacle", "supercategory": "object"},
    {"id": 2, "name": "marker", "supercategory": "object"},
]


def _versions(gl: dict[str, str] | None) -> dict[str, str]:
    from arenabench import glplatform

    glplatform.configure()  # before OpenGL is first imported in this process
    import pyrender

    out = {"arenabench": __version__, "opencv": cv2.__version__, "numpy": np.__version__,
           "pyrender": getattr(pyrender, "__version__", "unknown"),
           "python": sys.version.split()[0]}
    out.update(gl or {})
    return out


def manifest_line(sid: str, ext: str, image_sha256: str, gt_sha256: str) -> str:
    """One ``manifest.jsonl`` line (the dataset writer's and ``arenabench render``'s)."""
    return dumps_json_line({
        "id": sid, "image": image_file(sid, ext), "gt": f"gt/{sid}.json",
        "image_sha256": image_sha256, "gt_sha256": gt_sha256,
    })


def _finish(out: Path, args: DatasetArgs, gl: dict[str, str] | None,
            results: list[dict[str, Any]] | None = None,
            parts: CocoParts | None = None) -> None:
    """Write the manifest, ``coco.json`` and the complete ``dataset.json``: the hashes and
    COCO parts of the scenes rendered now come from ``results`` and ``parts`` (or the
    results' own ``coco``); only scenes of an earlier run are read (and hashed) again. Both
    files are written as streams (:mod:`arenabench.generator.dataset.coco_export`)."""
    known = {r["id"]: r for r in results or ()}
    parts = parts if parts is not None else CocoParts()
    ext = args.image_ext
    with atomic_text_writer(out / "manifest.jsonl") as manifest:
        for i in range(args.count):
            sid = scene_id(i)
            res = known.get(sid)
            if res is None:
                gt_path, img_path = out / "gt" / f"{sid}.json", out / image_file(sid, ext)
                gt_bytes = gt_path.read_bytes()
                res = {"coco": coco_parts(GroundTruth.from_dict(json.loads(gt_bytes))),
                       "image_sha256": sha256_file(img_path),
                       "gt_sha256": sha256_bytes(gt_bytes)}
            if "coco" in res:
                parts.add(sid, res["coco"])
            manifest.write(manifest_line(sid, ext, res["image_sha256"], res["gt_sha256"]))
    write_coco(out / "coco.json", lambda: (parts.get(scene_id(i)) for i in range(args.count)),
               COCO_INFO, COCO_CATEGORIES)
    _write_meta(out, args, complete=True, gl=gl)


def _finish_partial(out: Path, args: DatasetArgs, results: list[dict[str, Any]]) -> int:
    """After an interrupt: the manifest of the scenes on disk; returns how many there are.

    Hashes come from this run's results, then from the manifest of an earlier interrupted
    run; only scenes in neither (at most one per worker stopped mid-write) are read again.
    """
    known = {r["id"]: (r["image_sha256"], r["gt_sha256"]) for r in results}
    old = out / "manifest.jsonl"
    if old.is_file():
        for line in old.read_text(encoding="utf-8").splitlines():
            try:
                entry = json.loads(line)
                known.setdefault(entry["id"], (entry["image_sha256"], entry["gt_sha256"]))
            except (ValueError, KeyError, TypeError):
                continue
    lines = []
    ext = args.image_ext
    for i in range(args.count):
        sid = scene_id(i)
        if not _present(out, sid, ext):
            continue
        if sid not in known:
            known[sid] = (sha256_file(out / image_file(sid, ext)),
                          sha256_file(out / "gt" / f"{sid}.json"))
        lines.append(manifest_line(sid, ext, *known[sid]))
    atomic_write_text(out / "manifest.jsonl", "".join(lines))
    _write_meta(out, args, complete=False, finished=len(lines))
    return len(lines)


def _image_format_meta(image_format: str, jpeg_quality: int,
                       jpeg_subsampling: str) -> dict[str, Any]:
    """How the images are encoded, for ``dataset.json["render"]``."""
    if image_format == "jpeg":
        return {"image_format": "jpeg", "jpeg_quality": int(jpeg_quality),
                "jpeg_chroma": ":".join(("4", *jpeg_subsampling[1:]))}
    return {"image_format": "png", "png_compression": PNG_COMPRESSION}


def _edges_meta(params: dict[str, Value]) -> str:
    """How the obstacles' edges are drawn, for ``dataset.json["render"]["edges"]``."""
    samples, how = params["render.edge_samples"], params["render.edge_resolve"]
    if isinstance(samples, Range):
        return (f"render.edge_samples drawn per scene in {samples} (each GT's params), "
                f"{EDGE_RESOLVES[how]}")
    return edge_model(RenderSpec(edge_samples=samples, edge_resolve=how))


def _write_meta(out: Path, args: DatasetArgs, *, complete: bool,
                gl: dict[str, str] | None = None, finished: int | None = None) -> None:
    params = resolve(args.preset, args.overrides)
    meta = {
        "schema": DATASET_SCHEMA, "args": args.to_dict(), "preset": args.preset.name,
        "overrides": args.to_dict()["overrides"], "seed": int(args.seed),
        "count": int(args.count), "complete": complete,
        "params": {k: format_value(v) for k, v in sorted(params.items())},
        "preset_definition": args.preset.document(),
        "versions": _versions(gl) if complete else {},
        "render": {"mode": "flat, Lambertian shading baked", "edges": _edges_meta(params),
                   **_image_format_meta(*args.output)},
        "files": {"images": "images/", "gt": "gt/", "manifest": "manifest.jsonl",
                  "coco": "coco.json",
                  **({"textures": args.textures} if args.textures else {})},
    }
    if finished is not None:  # an interrupted run: the manifest lists these scenes only
        meta["finished"] = int(finished)
    atomic_write_json(out / "dataset.json", meta)


# ----------------------------------------------------------------------------- driver

def generate_dataset(
    out: str | os.PathLike[str],
    *,
    preset: str | ResolvedPreset,
    count: int,
    seed: int,
    overrides: dict[str, Value] | None = None,
    workers: int = 1,
    scheduler: Any = None,
    progress: bool = True,
) -> DatasetResult:
    """Render ``count`` scenes of ``preset`` into ``out`` (resuming an interrupted run).

    Parameters
    ----------
    out : path-like
        Dataset directory (created).
    preset : str or ResolvedPreset, keyword-only
        A built-in preset's name, or a preset file's
        :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`
        (:func:`~arenabench.generator.parameters.presets.resolve_preset`).
    count, seed : int, keyword-only
        Number of scenes, run seed.
    overrides : dict, keyword-only
        Parsed ``--set`` values.
    workers : int, keyword-only
        Rendering processes (1 = this process).
    scheduler : str or distributed.Client, optional, keyword-only
        ``tcp://HOST:PORT`` of a Dask scheduler (or a connected client): the cluster's
        workers render and send back the encoded files, which are written here (workers need
        no access to ``out``); ``workers`` is then ignored. The files are the same bytes as a
        local run's.
    progress : bool, keyword-only
        Show progress on stderr (:mod:`arenabench.progress`: a bar on a terminal, a few
        plain lines otherwise).

    Returns
    -------
    DatasetResult
        With ``interrupted`` set when a stop signal (see :mod:`arenabench.interrupts`) ended
        the run early.

    Raises
    ------
    GenerateError
        When ``out`` holds a dataset made with other arguments, or unrelated files, or
        another run is writing into it (an exclusive lock on ``out`` for the whole run;
        the message names the holder's pid, host and command).
    ValueError
        For invalid arguments.
    """
    check_at_most(check_workers(workers), MAX_WORKERS, "workers")
    args = DatasetArgs(preset=preset, count=int(count), seed=int(seed),
                       overrides=dict(overrides or {}))  # refuse bad arguments before creating out
    check_first_scene(args)
    client = None
    if scheduler is not None:  # reach the cluster before writing anything
        from arenabench.cluster import connect

        client = connect(scheduler)
    made = not Path(out).exists()
    if client is None and made:
        from arenabench.generator.dataset.gl_check import require_offscreen_gl

        require_offscreen_gl()  # OffscreenGLError: one line, before out is created
    try:
        with lock_folder(out, command=shlex.join(sys.argv)[:300]):
            if client is None and not made:  # after the lock: a run holding it is named at once
                from arenabench.generator.dataset.gl_check import require_offscreen_gl

                require_offscreen_gl()
            return _generate_locked(out, args, workers=workers, client=client,
                                    progress=progress)
    except FolderLockedError as exc:
        raise GenerateError(f"{exc}; wait for it to finish or use another --out") from None
    except ValueError:  # a scene's values fail: _generate_locked left the folder as it was
        if made:
            with contextlib.suppress(OSError):
                Path(out).rmdir()  # only when empty
        raise
    finally:
        if client is not None and client is not scheduler:
            client.close()


def check_first_scene(args: DatasetArgs) -> None:
    """Draw scene 0 of a run and compute its ground truth (no rendering): values that are
    valid one by one but fail together (an unknown ArUco dictionary, a marker id outside it,
    boxes that do not fit, markers out of view) are refused before anything is written.

    Raises
    ------
    ValueError
        :class:`~arenabench.generator.model.sampler.SamplingError` or the scene's own refusal,
        naming the parameter.
    """
    if args.count < 1:
        return
    from arenabench.generator.model.sampler import sample_scene
    from arenabench.generator.truth.groundtruth import compute_ground_truth

    sampled = sample_scene(args.preset, seed=args.seed, index=0, overrides=args.overrides)
    compute_ground_truth(sampled.scene)


def _generate_locked(out: str | os.PathLike[str], args: DatasetArgs, *, workers: int,
                     client: Any, progress: bool) -> DatasetResult:
    """:func:`generate_dataset` of ``args`` while holding the lock on ``out`` (``client``: a
    connected Dask client to render on, or None)."""
    root = Path(out)
    start = time.perf_counter()
    meta = _check_existing(root, args)
    # ours (same arguments) or empty: files a killed run was writing are garbage
    _remove_temp_files(root)
    todo = [i for i in range(args.count) if not _present(root, scene_id(i), args.image_ext)]
    skipped = args.count - len(todo)
    if meta is not None and meta.get("complete") and not todo:
        return DatasetResult(root, 0, skipped, time.perf_counter() - start, count=args.count,
                             finished=args.count)
    old_meta = (root / "dataset.json").read_bytes() if meta is not None else None
    try:
        return _render_all(root, args, todo, skipped, meta, start, workers=workers,
                           client=client, progress=progress)
    except ValueError:  # a scene's values fail at render time: undo what this run began
        if old_meta is None:  # a new set: leave nothing
            for name in ("images", "gt", texture_store.TEXTURES_FOLDER):
                shutil.rmtree(root / name, ignore_errors=True)
            for name in ("dataset.json", "manifest.jsonl", "coco.json"):
                (root / name).unlink(missing_ok=True)
        else:  # resumed or extended: the set as it was (scenes finished are kept)
            _remove_temp_files(root)
            atomic_write_bytes(root / "dataset.json", old_meta)
        raise


def _remove_temp_files(root: Path) -> None:
    """Remove the half-written files of the set's writers (this process holds the lock, and
    its workers have ended)."""
    for folder in (root, root / "images", root / "gt", root / texture_store.TEXTURES_FOLDER):
        remove_temp_files(folder)


def _render_all(root: Path, args: DatasetArgs, todo: list[int], skipped: int,
                meta: dict[str, Any] | None, start: float, *, workers: int, client: Any,
                progress: bool) -> DatasetResult:
    """Render the scenes ``todo`` of ``args`` into ``root`` and finish the set."""
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "gt").mkdir(parents=True, exist_ok=True)
    for ref in args.textures:  # the set needs no file outside it (docs/architecture.md)
        texture_store.export_texture(ref, root)
    if meta is None or meta["args"].get("count") != args.count:
        _write_meta(root, args, complete=False)
    stored = args.to_dict()
    image_format, jpeg_quality, jpeg_subsampling = args.output
    textures = tuple((ref, texture_store.texture_bytes(ref)) for ref in args.textures
                     ) if client is not None else ()
    tasks = [RenderTask(args=stored, seed=args.seed, index=i, out=str(root),
                        image_format=image_format, jpeg_quality=jpeg_quality,
                        jpeg_subsampling=jpeg_subsampling, preset=args.preset,
                        textures=textures) for i in todo]
    results: list[dict[str, Any]] = []
    parts = CocoParts()  # the scenes' COCO parts wait on disk, not in results
    bar = _progress(len(tasks), progress)
    try:
        if client is not None and tasks:
            from arenabench.cluster import cluster_map

            for _, res in cluster_map(render_on_cluster, tasks, client):
                results.append(parts.keep(write_rendered(root, res)))
                bar.update(1)
        else:
            with contextlib.closing(local_map(render_task, tasks, workers=workers)) as done:
                for res in done:
                    results.append(parts.keep(res))
                    bar.update(1)
    except Interrupted as exc:
        bar.close()
        # the workers have ended; one that did not unwind in its grace time was killed and
        # may have left the file it was writing
        _remove_temp_files(root)
        finished = _finish_partial(root, args, results)
        return DatasetResult(root, len(results), skipped, time.perf_counter() - start,
                             count=args.count, interrupted=exc.signum, finished=finished)
    finally:
        bar.close()
    gl = results[0]["gl"] if results else (meta or {}).get("versions") or None
    if gl is None:
        gl = worker_gl_info()
    gl = {k: v for k, v in gl.items() if k.startswith("gl_")}
    _finish(root, args, gl, results, parts)
    timings = {}
    if results:
        for key in ("sample", "render", "gt", "encode", "write"):
            timings[key] = float(np.median([r[key] for r in results]))
    return DatasetResult(root, len(results), skipped, time.perf_counter() - start, timings,
                         count=args.count, finished=args.count,
                         task_cpu_ms=_warm_task_cpu_ms(results))


def _progress(total: int, enabled: bool):
    from arenabench.progress import progress

    return progress(total, desc="generate", enabled=enabled)
