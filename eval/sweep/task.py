"""The sweep's work unit, run in a worker: render one scene in memory, run every pipeline on it,
score each answer, return small dicts.

Worker state (one renderer, one adapter per pipeline) lives in this module and is created on
first use, so the same :func:`run_task` serves local spawned processes and Dask workers. The
renderer is per thread (an OpenGL context is current in one thread only); Dask workers should
still run one thread each (``--nthreads 1``) since renders are CPU- or GPU-bound anyway.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

from arenabench.interrupts import init_worker_process, worker_task

from ..dataset import Sample as ScoredSample
from ..records import Prediction
from ..runner import _result as score_result
from .records import PipelineSpec, SweepTask

_LOCAL = threading.local()
_PIPELINES: dict[PipelineSpec, Any] = {}
_PIPELINES_LOCK = threading.Lock()


def init_worker(lp_threads: int | None = None, parent_pid: int | None = None) -> None:
    """Process-pool initializer: cap llvmpipe's threads, pick the GL platform, create the
    renderer (so the first task does not pay for it).

    Parameters
    ----------
    lp_threads : int, optional
        ``LP_NUM_THREADS`` for Mesa llvmpipe (unless already set).
    parent_pid : int, optional
        The parent's pid: the worker then stops with its parent and on SIGTERM
        (:func:`arenabench.interrupts.init_worker_process`).
    """
    if parent_pid is not None:
        init_worker_process(parent_pid=parent_pid)
    if lp_threads and "LP_NUM_THREADS" not in os.environ:
        os.environ["LP_NUM_THREADS"] = str(int(lp_threads))
    worker_renderer()


def worker_renderer() -> Any:
    """This thread's :class:`~arenabench.generator.render.Renderer`, created on first use."""
    renderer = getattr(_LOCAL, "renderer", None)
    if renderer is None:
        from arenabench import glplatform

        glplatform.configure()
        from arenabench.generator.render import Renderer

        renderer = Renderer()
        _LOCAL.renderer = renderer
    return renderer


def _pipeline(spec: PipelineSpec) -> Any:
    with _PIPELINES_LOCK:
        if spec not in _PIPELINES:
            _PIPELINES[spec] = spec.build()
        return _PIPELINES[spec]


def _encode_png(bgr: Any) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:  # pragma: no cover - OpenCV failure
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def image_name(point: int, scene: int) -> str:
    """File stem of a kept image and its GT: ``p0003_s000012``."""
    return f"p{int(point):04d}_s{int(scene):06d}"


def _predict(spec: PipelineSpec, bgr: Any, png: list[bytes], tmp: list[str]) -> Prediction:
    pipe = _pipeline(spec)
    if spec.in_memory and hasattr(pipe, "run_image"):
        return pipe.run_image(bgr)
    # external commands read a file: write the image once per sample, only now
    if not tmp:
        tmp.append(tempfile.mkdtemp(prefix="arenabench-sweep-"))
        if not png:
            png.append(_encode_png(bgr))
        Path(tmp[0], "image.png").write_bytes(png[0])
    return pipe.run(Path(tmp[0], "image.png"))


def run_task(task: SweepTask) -> dict[str, Any]:
    """Render, run every pipeline and score one (point, scene).

    In a local worker process, a SIGTERM ends the task (and its commands) and the process.

    Parameters
    ----------
    task : SweepTask

    Returns
    -------
    dict
        ``{"point", "scene", "index", "error", "results", "png", "gt", "timings_ms"}``:
        ``results`` holds one ``ImageResult.to_dict()`` per pipeline (plus ``pipeline``,
        ``point``, ``scene``, ``index``); ``error`` is the reason when the scene could not be
        generated (then ``results`` is empty); ``png``/``gt`` are set only when the image is
        kept (``keep="all"``, or ``"failures"`` and some pipeline failed).
    """
    with worker_task():
        return _run_task(task)


def _run_task(task: SweepTask) -> dict[str, Any]:
    from arenabench.generator.sample import make_sample
    from arenabench.generator.sampler import SamplingError

    out: dict[str, Any] = {
        "point": task.point, "scene": task.scene, "index": task.index, "error": None,
        "results": [], "png": None, "gt": None, "timings_ms": {},
    }
    try:
        sample = make_sample(task.preset, seed=task.seed, index=task.index,
                             overrides=task.overrides, renderer=worker_renderer())
    except SamplingError as exc:
        out["error"] = f"SamplingError: {exc}"
        return out
    out["timings_ms"] = dict(sample.timings_ms)
    bgr = sample.bgr
    gt = sample.gt
    params = gt.get("params", {})
    flat = {k: float(v) for k, v in params.items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)}
    name = image_name(task.point, task.scene)
    scored = ScoredSample(id=name, image_path=Path("images", f"{name}.png"),
                          gt_path=Path("gt", f"{name}.json"), gt=gt, params=flat)
    png: list[bytes] = []
    tmp: list[str] = []
    any_failed = False
    try:
        for spec in task.pipelines:
            pred = _predict(spec, bgr, png, tmp)
            result = score_result(scored, pred, tolerance=task.tolerance,
                                  area_reference=task.area_reference)
            any_failed |= not result.passed
            out["results"].append(result)
    finally:
        if tmp:
            shutil.rmtree(tmp[0], ignore_errors=True)
    keep = task.keep == "all" or (task.keep == "failures" and any_failed)
    rows = []
    for spec, result in zip(task.pipelines, out["results"], strict=True):
        if not keep:
            result = replace(result, image="")
        rows.append({**result.to_dict(), "pipeline": spec.name, "point": task.point,
                     "scene": task.scene, "index": task.index})
    out["results"] = rows
    if keep:
        out["png"] = png[0] if png else _encode_png(bgr)
        out["gt"] = gt
    return out
