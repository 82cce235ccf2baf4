"""Run a sweep: points -> tasks -> workers (inline, local process pool or Dask) -> summaries.

Seeds (common random numbers): scene ``i`` of every point is scene ``i`` of the sweep seed,
``make_sample(preset, seed=seed, index=i, overrides=set | point)``. The generator draws every
scalar parameter with one uniform draw whether or not it is overridden, so two points show the
same base scenes (same boxes, camera, light, degradation noise) with only the varied
parameters changed: curves are smooth and differences between points are not sampling noise.
``independent_scenes=True`` gives point ``p`` the indices ``p * per_point + i`` instead.
Random points come from ``default_rng(SeedSequence([seed, 2]))``.

Results never depend on the executor or the number of workers: every task is a pure
function of its description, and results are sorted by (point, scene) before aggregation.

A stop signal (:class:`arenabench.interrupts.Interrupted`, raised inside
:func:`arenabench.interrupts.stop_on_signals`) stops the workers (local processes are ended,
Dask futures cancelled) and :func:`run_sweep` returns what finished, marked incomplete.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import closing
from dataclasses import replace
from typing import Any

import numpy as np

from arenabench.eval.scoring.metrics import summarize
from arenabench.eval.scoring.phase_summary import phase_summary
from arenabench.eval.scoring.results import ImageResult
from arenabench.generator.parameters.params import PARAMETERS
from arenabench.generator.parameters.presets import resolve
from arenabench.interrupts import Interrupted, signal_name
from arenabench.local_pool import local_map
from arenabench.workers import check_workers, usable_cores

from .breakdown import axis_curve, breakdown_value
from .grid import grid_points, random_points
from .records import PointSummary, SweepResult, SweepSpec, SweepTask


def sweep_points(spec: SweepSpec) -> list[dict[str, Any]]:
    """The sweep's points: the grid, or ``spec.random`` random points."""
    if spec.random is None:
        return grid_points(spec.axes)
    rng = np.random.default_rng(np.random.SeedSequence([int(spec.seed), 2]))
    return random_points(spec.axes, n=spec.random, rng=rng)


def sweep_tasks(spec: SweepSpec, points: list[dict[str, Any]]) -> list[SweepTask]:
    """One task per (point, scene), point-major.

    Raises
    ------
    ValueError
        When a point's parameters do not resolve against the preset (checked for every
        point, before anything runs).
    """
    tasks = []
    for p, params in enumerate(points):
        overrides = {**spec.overrides, **params}
        resolve(spec.preset, overrides)
        for i in range(spec.per_point):
            index = p * spec.per_point + i if spec.independent_scenes else i
            tasks.append(SweepTask(
                point=p, scene=i, index=index, preset=spec.preset, seed=int(spec.seed),
                overrides=overrides, pipelines=spec.pipelines, tolerance=spec.tolerance,
                area_reference=spec.area_reference, keep=spec.keep, phases=spec.phases,
            ))
    return tasks


#: Batches per worker a local sweep aims at (more balance the load at the end, fewer reuse more).
BATCHES_PER_WORKER = 8


def post_render_only(spec: SweepSpec) -> bool:
    """Whether every axis of ``spec`` is a post-render parameter
    (:attr:`arenabench.generator.parameters.params.Param.post_render`: noise, blur, JPEG, ...):
    then scene
    ``i`` renders to the same pixels and ground truth at every point."""
    return all(PARAMETERS[axis.key].post_render for axis in spec.axes)


def sweep_batches(tasks: list[SweepTask], workers: int, *,
                  by_scene: bool = False) -> list[tuple[SweepTask, ...]]:
    """The tasks cut into batches for ``workers`` local processes, each run by one worker.

    A batch holds at most ``len(tasks) / (workers * BATCHES_PER_WORKER)`` tasks (at least
    one), so the last batches still spread over the workers. With ``by_scene``
    (:func:`post_render_only`), a batch holds points of one scene index, in point order: its
    worker renders the base scene and computes its ground truth once
    (:meth:`arenabench.generator.rendering.render.Renderer.render` keeps its last output; with
    ``independent_scenes`` every task is its own scene). Otherwise batches follow the points,
    and consecutive scenes of a point keep sharing what the renderer reuses (the ``eyrc``
    twin's static layer).
    """
    size = max(1, len(tasks) // (max(1, workers) * BATCHES_PER_WORKER))
    if not by_scene:
        return [tuple(tasks[k:k + size]) for k in range(0, len(tasks), size)]
    groups: dict[int, list[SweepTask]] = {}
    for task in tasks:
        groups.setdefault(task.index, []).append(task)
    return [tuple(group[k:k + size]) for group in groups.values()
            for k in range(0, len(group), size)]


def _local(tasks: list[SweepTask], workers: int, *,
           by_scene: bool) -> Iterator[dict[str, Any]]:
    """The tasks' batches (:func:`sweep_batches`) in a local pool
    (:func:`arenabench.local_pool.local_map`), or, with one worker, their tasks one by one in
    this process."""
    from .task import init_sweep_worker, run_batch, run_task

    batches = sweep_batches(tasks, workers, by_scene=by_scene)
    if workers == 1:
        yield from local_map(run_task, [task for batch in batches for task in batch], workers=1)
        return
    with closing(local_map(run_batch, batches, workers=workers,
                           initializer=init_sweep_worker)) as done:
        for outputs in done:
            yield from outputs


def _dask(tasks: list[SweepTask], scheduler: Any) -> Iterator[dict[str, Any]]:
    from arenabench.cluster import cluster_map

    from .task import run_task

    for _, out in cluster_map(run_task, tasks, scheduler):
        yield out


def execute(
    tasks: list[SweepTask],
    *,
    workers: int | None = None,
    scheduler: Any = None,
    by_scene: bool = False,
) -> Iterator[dict[str, Any]]:
    """Run tasks, yielding each task's result dict as it completes (any order).

    Parameters
    ----------
    tasks : list of SweepTask
    workers : int, optional, keyword-only
        Local processes (default: the machine's cores; 1 runs in this process).
    scheduler : str or distributed.Client, optional, keyword-only
        ``tcp://HOST:PORT`` of a Dask scheduler (or a connected client): the tasks run on
        that cluster instead.
    by_scene : bool, keyword-only
        Run the points of each scene one after another in one local worker
        (:func:`sweep_batches`; true when :func:`post_render_only`). Results never depend on it.
    """
    if workers is not None:
        check_workers(workers)
    if scheduler is not None:
        return _dask(tasks, scheduler)
    n = min(workers or usable_cores(), max(1, len(tasks)))
    return _local(tasks, n, by_scene=by_scene)


def aggregate(
    spec: SweepSpec, points: list[dict[str, Any]], outputs: list[dict[str, Any]]
) -> tuple[tuple[PointSummary, ...], tuple[dict[str, Any], ...], dict[str, dict[str, Any]]]:
    """Summaries per point and pipeline, sorted per-image rows and breakdown points."""
    outputs = sorted(outputs, key=lambda o: (o["point"], o["scene"]))
    order = {p.name: k for k, p in enumerate(spec.pipelines)}
    rows = tuple(sorted((r for o in outputs for r in o["results"]),
                        key=lambda r: (r["point"], r["scene"], order[r["pipeline"]])))
    skipped = [0] * len(points)
    for o in outputs:
        if o["error"] is not None:
            skipped[o["point"]] += 1
    by_pipe: dict[str, dict[int, list[ImageResult]]] = {p.name: {} for p in spec.pipelines}
    for r in rows:
        by_pipe[r["pipeline"]].setdefault(r["point"], []).append(ImageResult.from_dict(r))
    summaries = []
    for p, params in enumerate(points):
        for pipe in spec.pipelines:
            rs = by_pipe[pipe.name].get(p, [])
            summaries.append(PointSummary(
                index=p, params=params, pipeline=pipe.name, skipped=skipped[p],
                summary=replace(summarize([r.score for r in rs], [r.prediction for r in rs]),
                                **phase_summary(rs)),
            ))
    breakdown: dict[str, dict[str, Any]] = {}
    for pipe in spec.pipelines:
        breakdown[pipe.name] = {
            axis.key: breakdown_value(
                axis_curve(axis, axes=spec.axes, points=points, results=by_pipe[pipe.name],
                           random=spec.random is not None, mode=spec.breakdown_mode),
                threshold=spec.threshold,
            )
            for axis in spec.axes
        }
    return tuple(summaries), rows, breakdown


def _points_done(outputs: list[dict[str, Any]], n_points: int, per_point: int) -> int:
    """How many points have all their scenes done."""
    done = [0] * n_points
    for o in outputs:
        done[o["point"]] += 1
    return sum(1 for d in done if d == per_point)


def run_sweep(
    spec: SweepSpec,
    *,
    workers: int | None = None,
    scheduler: Any = None,
    progress: bool = False,
    on_output: Callable[[dict[str, Any]], None] | None = None,
) -> SweepResult:
    """Run a whole sweep in memory and aggregate it.

    Parameters
    ----------
    spec : SweepSpec
    workers : int, optional, keyword-only
        Local processes (default: cores; 1 = in this process).
    scheduler : str or distributed.Client, optional, keyword-only
        Run on an existing Dask cluster instead.
    progress : bool, keyword-only
        Progress over samples on stderr (:mod:`arenabench.progress`: a bar on a terminal,
        a few plain lines otherwise).
    on_output : callable, optional, keyword-only
        Called with each task's raw result as it arrives (e.g. to write kept images).

    Returns
    -------
    SweepResult
        Of every task; or, stopped by a signal (:class:`arenabench.interrupts.Interrupted`),
        of the tasks done by then, with ``complete`` false.
    """
    from arenabench.progress import progress as progress_bar

    start = time.perf_counter()
    points = sweep_points(spec)
    tasks = sweep_tasks(spec, points)
    outputs: list[dict[str, Any]] = []
    timings: dict[str, list[float]] = {}
    interrupted: int | None = None
    with progress_bar(len(tasks), desc="sweep", enabled=progress) as bar:
        results = execute(tasks, workers=workers, scheduler=scheduler,
                          by_scene=post_render_only(spec))
        try:
            for out in results:
                if on_output is not None:
                    on_output(out)
                for k, v in out.get("timings_ms", {}).items():
                    timings.setdefault(k, []).append(v)
                outputs.append({k: v for k, v in out.items() if k not in ("image", "gt")})
                bar.update(1)
        except Interrupted as exc:
            interrupted = exc.signum
        finally:
            results.close()  # stops the workers if the loop did not finish
    summaries, rows, breakdown = aggregate(spec, points, outputs)
    seconds = time.perf_counter() - start
    run = {
        "executor": "dask" if scheduler is not None else (
            "inline" if min(workers or usable_cores(), len(tasks)) <= 1 else "process"),
        "workers": workers or (None if scheduler is not None else usable_cores()),
        "samples": len(tasks),
        "skipped": sum(1 for o in outputs if o["error"] is not None),
        "seconds": round(seconds, 3),
        "samples_per_s": round(len(outputs) / seconds, 3) if seconds > 0 else None,
        "median_ms": {k: round(float(np.median(v)), 3) for k, v in sorted(timings.items())},
        "complete": interrupted is None,
        "samples_done": len(outputs),
        "points_done": _points_done(outputs, len(points), spec.per_point),
    }
    if interrupted is not None:
        run["interrupted"] = signal_name(interrupted)
    return SweepResult(spec=spec, points=tuple(points), summaries=summaries, images=rows,
                       breakdown=breakdown, run=run)
