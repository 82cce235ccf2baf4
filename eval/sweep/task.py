"""The sweep's work unit, run in a worker: render one scene in memory, run every pipeline on it,
score each answer, return small dicts.

Worker state (one renderer per thread, one adapter per pipeline and process) lives in
:mod:`arenabench.workers` and is created on first use, so the same :func:`run_task` serves
local spawned processes and Dask workers. The renderer is per thread (an OpenGL context is
current in one thread only); Dask workers should
still run one thread each (``--nthreads 1``) since renders are CPU- or GPU-bound anyway.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

from arenabench import workers
from arenabench.eval.datasets.reader import DatasetItem
from arenabench.eval.runs import owned_dir_prefix
from arenabench.eval.scoring.results import Prediction
from arenabench.imageio import decode_image
from arenabench.interrupts import worker_task

from ..scoring.metrics import score_sample
from .records import PipelineSpec, SweepTask


def init_sweep_worker(lp_threads: int | None = None, parent_pid: int | None = None) -> None:
    """Process-pool initializer: :func:`arenabench.workers.init_worker`, then create the
    renderer (so the first task does not pay for it)."""
    from arenabench.generator.dataset.make import worker_renderer

    workers.init_worker(lp_threads, parent_pid)
    worker_renderer()


def _pipeline(spec: PipelineSpec) -> Any:
    return workers.process_state(("sweep-pipeline", spec), spec.build)


def image_name(point: int, scene: int) -> str:
    """File stem of a kept image and its GT: ``p0003_s000012``."""
    return f"p{int(point):04d}_s{int(scene):06d}"


def _predict(spec: PipelineSpec, bgr: Any, image: list[bytes], tmp: list[str],
             sample: Any) -> Prediction:
    pipe = _pipeline(spec)
    if spec.in_memory and hasattr(pipe, "run_image"):
        return pipe.run_image(bgr)
    # external commands read a file: write the image once per sample, only now
    name = f"image.{sample.output.ext}"
    if not tmp:
        tmp.append(tempfile.mkdtemp(prefix=owned_dir_prefix("arenabench-sweep-")))
        if not image:
            image.append(sample.image_bytes)
        Path(tmp[0], name).write_bytes(image[0])
    return pipe.run(Path(tmp[0], name))


def _check_phases(task: SweepTask, gt: Any, results: list[Any], *, renderer: Any) -> None:
    """The phase check of each failing pipeline result, in place (the worker's renderer)."""
    from arenabench.eval.phase_check import SceneSource, check_phases
    from arenabench.generator.parameters.presets import resolve_preset

    source = SceneSource(resolve_preset(task.preset), dict(task.overrides))
    for k, (spec, result) in enumerate(zip(task.pipelines, results, strict=True)):
        if not result.passed:
            pipe = _pipeline(spec)
            results[k] = check_phases([result], [gt], pipe.run, phases=task.phases,
                                      tolerance=task.tolerance,
                                      area_reference=task.area_reference,
                                      renderer=renderer, source=source,
                                      stop=getattr(pipe, "stop", None))[0]


def run_task(task: SweepTask) -> dict[str, Any]:
    """Render, run every pipeline and score one (point, scene).

    In a local worker process, a SIGTERM ends the task (and its commands) and the process.

    Parameters
    ----------
    task : SweepTask

    Returns
    -------
    dict
        ``{"point", "scene", "index", "error", "results", "image", "image_ext", "gt",
        "timings_ms"}``:
        ``results`` holds one ``ImageResult.to_dict()`` per pipeline (plus ``pipeline``,
        ``point``, ``scene``, ``index``); ``error`` is the reason when the scene could not be
        generated (then ``results`` is empty); ``image`` (the file's bytes, PNG or JPEG as the
        preset's ``output.format`` says, ``image_ext`` its extension) and ``gt`` are set only
        when the image is kept (``keep="all"``, or ``"failures"`` and some pipeline failed).
    """
    with worker_task():
        return _run_task(task)


def run_batch(batch: tuple[SweepTask, ...]) -> list[dict[str, Any]]:
    """:func:`run_task` on each task of a batch
    (:func:`arenabench.eval.sweep.execution.sweep_batches`), in order."""
    return [run_task(task) for task in batch]


def _run_task(task: SweepTask) -> dict[str, Any]:
    from arenabench.generator.dataset.make import make_sample, worker_renderer
    from arenabench.generator.model.sampler import SamplingError

    out: dict[str, Any] = {
        "point": task.point, "scene": task.scene, "index": task.index, "error": None,
        "results": [], "image": None, "image_ext": None, "gt": None, "timings_ms": {},
    }
    try:
        sample = make_sample(task.preset, seed=task.seed, index=task.index,
                             overrides=task.overrides, renderer=worker_renderer())
    except SamplingError as exc:
        out["error"] = f"SamplingError: {exc}"
        return out
    out["timings_ms"] = dict(sample.timings_ms)
    bgr = sample.bgr
    image: list[bytes] = []
    if sample.output.image_format != "png":  # pipelines see the file `generate` would write
        image.append(sample.image_bytes)
        bgr = decode_image(image[0])
    ext = sample.output.ext
    gt = sample.record
    params = gt.params or {}
    flat = {k: float(v) for k, v in params.items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)}
    name = image_name(task.point, task.scene)
    scored = DatasetItem(id=name, image_path=Path("images", f"{name}.{ext}"),
                          gt_path=Path("gt", f"{name}.json"), gt=gt, params=flat)
    tmp: list[str] = []
    any_failed = False
    try:
        for spec in task.pipelines:
            pred = _predict(spec, bgr, image, tmp, sample)
            result = score_sample(scored, pred, tolerance=task.tolerance,
                                  area_reference=task.area_reference)
            any_failed |= not result.passed
            out["results"].append(result)
    finally:
        if tmp:
            shutil.rmtree(tmp[0], ignore_errors=True)
    if task.phases and any_failed:
        _check_phases(task, gt, out["results"], renderer=worker_renderer())
    keep = task.keep == "all" or (task.keep == "failures" and any_failed)
    rows = []
    for spec, result in zip(task.pipelines, out["results"], strict=True):
        if not keep:
            result = replace(result, image="")
        rows.append({**result.to_dict(), "pipeline": spec.name, "point": task.point,
                     "scene": task.scene, "index": task.index})
    out["results"] = rows
    if keep:
        out["image"] = sample.image_bytes
        out["image_ext"] = ext
        out["gt"] = gt.to_dict()
    return out
