"""Run a pipeline over a dataset in parallel and score every image.

External commands run on a thread pool (the work happens in subprocesses). In-process
pipelines run on a thread pool by default (OpenCV releases the GIL in its heavy calls); a
spawn-based process pool is available with ``executor="process"`` for pipelines named by a
string spec (``"reference"``, ``"pkg.module:function"``), which each worker re-imports.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import (
    Executor,
    Future,
    ThreadPoolExecutor,
)
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from arenabench.eval.datasets.reader import AREA_REFERENCES, Dataset, DatasetItem, load_dataset
from arenabench.eval.datasets.result_store import ResultStore
from arenabench.eval.scoring.breakdown import breakdown, rank_causes, systematic_errors
from arenabench.eval.scoring.metrics import DEFAULT_TOLERANCE, score_sample, summarize
from arenabench.eval.scoring.results import HarnessError, ImageResult, Prediction, Report
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE
from arenabench.interrupts import checkpoint, deferred_stops, first_done
from arenabench.local_pool import local_executor
from arenabench.workers import process_state, usable_cores

from .pipelines import Pipeline, make_pipeline


class EvaluationInterrupted(Exception):
    """SIGINT/SIGTERM stopped :func:`evaluate` (inside
    :func:`arenabench.interrupts.stop_on_signals`): running pipelines were stopped.

    Attributes
    ----------
    report : Report
        The images finished before the signal (``complete=False``, ``n_done``).
    signum, exit_code : int
        The signal and ``128 + signum``.
    """

    def __init__(self, report: Report, signum: int) -> None:
        from arenabench.interrupts import exit_code

        self.report = report
        self.signum = signum
        self.exit_code = exit_code(signum)
        super().__init__(f"interrupted after {report.images_done} images")

class EvaluationFailed(Exception):
    """The harness could not run an image (:class:`~arenabench.eval.scoring.results.HarnessError`):
    :func:`evaluate` stopped every run; nothing of that image was scored.

    Attributes
    ----------
    report : Report
        The images finished before (``complete=False``, ``n_done``).
    error : HarnessError
        What failed.
    """

    def __init__(self, report: Report, error: HarnessError) -> None:
        self.report = report
        self.error = error
        super().__init__(f"the harness could not run an image: {error}")


EXECUTORS: tuple[str, ...] = ("thread", "process")
#: Images submitted ahead per worker (the rest wait in the dataset, not in memory).
IN_FLIGHT_PER_WORKER = 4


@dataclass(frozen=True)
class PipelineRun:
    """One image for a process-pool worker: run the pipeline named ``spec`` on it.

    Attributes
    ----------
    spec : str
        ``"reference"``, ``"seed"`` or ``"pkg.module:function"`` (re-imported by the worker).
    image_path : str
        The image file.
    """

    spec: str
    image_path: str


def _worker_pipeline(spec: str) -> Pipeline:
    """This process's pipeline for ``spec`` (built on first use)."""
    return process_state(("eval-pipeline", spec), lambda: make_pipeline(spec))


def run_in_worker(task: PipelineRun) -> Prediction:
    """A process-pool worker's unit: run the pipeline on one image."""
    return _worker_pipeline(task.spec).run(Path(task.image_path))


def build_report(
    results: Sequence[ImageResult],
    *,
    pipeline: str,
    dataset: str,
    area_reference: str = DEFAULT_AREA_REFERENCE,
    tolerance: float = DEFAULT_TOLERANCE,
    complete: bool = True,
    n_total: int | None = None,
    images: Sequence[ImageResult] | None = None,
    manifest_sha256: str | None = None,
) -> Report:
    """Summary, breakdown and ranked causes of scored images, as a :class:`Report`
    (``complete=False``: a run stopped early, ``n_done`` is then the number of images given, of
    ``n_total``). Phase-check results on the images (``ImageResult.phase``) fill the summary's
    phase keys. ``images``: the full per-image results when ``results`` are compact ones
    (:func:`arenabench.eval.datasets.result_store.compact_result`, same order). ``manifest_sha256``:
    the dataset's (:meth:`~arenabench.eval.datasets.reader.Dataset.manifest_sha256`)."""
    from arenabench.eval.scoring.phase_summary import phase_summary

    summary = summarize([r.score for r in results], [r.prediction for r in results])
    return Report(
        complete=complete,
        n_done=len(results),
        n_total=None if complete else n_total,
        pipeline=pipeline,
        dataset=dataset,
        area_reference=area_reference,
        tolerance=tolerance,
        summary=replace(summary, **phase_summary(results)),
        images=tuple(results) if images is None else images,
        breakdown=breakdown(results),
        causes=tuple(rank_causes(results)),
        systematic=tuple(systematic_errors(results, tolerance=tolerance)),
        manifest_sha256=manifest_sha256,
    )


def evaluate(
    pipeline: str | Callable[[Any], Any] | Pipeline,
    dataset: str | os.PathLike[str] | Dataset,
    *,
    workers: int | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    area_reference: str = DEFAULT_AREA_REFERENCE,
    executor: str = "thread",
    progress: bool = False,
    limit: int | None = None,
    phases: int = 0,
    isolate: bool = False,
    timeout_s: float | None = None,
    spill: bool | None = None,
    open_from: Any = None,
) -> Report:
    """Run ``pipeline`` on every image of ``dataset`` and score it.

    Parameters
    ----------
    pipeline : str, callable or Pipeline
        ``"reference"``, ``"seed"``, ``"pkg.module:function"``, a function taking a BGR image,
        or a pipeline object (e.g. :class:`~arenabench.eval.runs.pipeline.CommandPipeline`).
    dataset : path-like or Dataset
        Dataset folder written by the generator, or a loaded dataset.
    workers : int, optional
        Parallel workers (default: the machine's cores).
    tolerance : float
        Largest passing ``|area_rel_err|``.
    area_reference : {"visible", "footprint", "contour"}
        Which GT area the prediction is compared with (``area.visible_px``,
        ``area.footprint_px`` or ``area.contour_px``).
    executor : {"thread", "process"}
        Pool for in-process pipelines; external commands always use threads.
    progress : bool
        Show progress on stderr (:mod:`arenabench.progress`: a bar on a terminal, a few
        plain lines otherwise).
    limit : int, optional
        Evaluate only the first ``limit`` images.
    phases : int
        Phase check (:mod:`arenabench.eval.phase_check`): re-render each failing image's
        scene at this many sub-pixel offsets and re-run the pipeline on each; 0 = off.
    isolate : bool
        Run a ``"pkg.module:function"`` pipeline in killable child processes
        (:class:`~arenabench.eval.runs.isolated.IsolatedCallablePipeline`, whatever ``executor``;
        what ``arenabench eval`` does): ``sys.exit``, ``os._exit``, ``KeyboardInterrupt`` or
        an endless loop in it fail that image only. The children are started with ``spawn``:
        a script calling this needs the ``if __name__ == "__main__":`` guard.
    timeout_s : float, optional
        With ``isolate``: seconds one image may take (default: the ``--timeout`` default of
        external commands).
    spill : bool, optional
        Keep the per-image results in a temporary file rather than in memory
        (:class:`~arenabench.eval.datasets.result_store.ResultStore`; default: for runs of more than
        :data:`~arenabench.eval.datasets.result_store.SPILL_ABOVE` images). The report is the same
        either way; its ``images`` are then read back from the file when used.
    open_from : ResolvedPreset, optional
        The preset whose ``[open]`` table the phase check varies (default: the one the set's
        ``dataset.json`` records). ``arenabench check`` passes the preset it was given: a
        cached set made from the same parameters records the ``[open]`` table of its day.

    Returns
    -------
    Report
        Per-image results in dataset order, summary and breakdown.

    Raises
    ------
    EvaluationInterrupted
        When :class:`arenabench.interrupts.Interrupted` arrives while images run: running
        external commands are killed (their processes and directories removed), queued
        images dropped; the exception holds the partial report.
    EvaluationFailed
        When the harness could not run an image
        (:class:`~arenabench.eval.scoring.results.HarnessError`): the runs are stopped the same way,
        and nothing of that image is scored; the exception holds the partial report.
    """
    from arenabench.interrupts import Interrupted

    _check_options(workers=workers, area_reference=area_reference, executor=executor,
                   tolerance=tolerance)
    data = dataset if isinstance(dataset, Dataset) else load_dataset(dataset, limit=limit)
    samples = data.samples[:limit] if limit else data.samples
    # a missing reference area is a data error, found before any work
    data.check_area_reference(area_reference, limit=limit)
    # from here on a stop gives the report of what finished (possibly no image: empty)
    store = ResultStore(len(samples), spill=spill)
    interrupted: Interrupted | None = None
    failed: HarnessError | None = None
    pipe: Pipeline | None = None
    try:
        pipe = _made_pipeline(pipeline, isolate=isolate, timeout_s=timeout_s)
        n_workers = min(workers or usable_cores(), max(1, len(samples)))
        pool, submit = _pool(pipe, pipeline, executor=executor, n_workers=n_workers)
        from arenabench.progress import progress as progress_bar

        def stop_runs() -> None:
            pipe.stop()
            pool.shutdown(wait=True, cancel_futures=True)

        with (
            pool,
            progress_bar(len(samples), desc=f"eval {pipe.name}", enabled=progress) as bar,
        ):
            try:
                _run_all(samples, submit, store, window=IN_FLIGHT_PER_WORKER * n_workers,
                         on_image=lambda: bar.update(1), tolerance=tolerance,
                         area_reference=area_reference, stop_runs=stop_runs,
                         killable=not pipe.in_process)
            except Interrupted as exc:
                interrupted = exc
            except HarnessError as exc:  # the runs are stopped: never scored as the pipeline's
                failed = exc
        if (phases and interrupted is None and failed is None
                and not all(r.passed for r in store.compact())):
            store, interrupted, failed = _phase_checked(
                store, data, pipe, phases=phases, tolerance=tolerance,
                area_reference=area_reference, workers=n_workers, progress=progress,
                open_from=open_from)
    except Interrupted as exc:  # while setting up: nothing ran
        interrupted = exc
    except HarnessError as exc:
        failed = exc
    finally:  # a command's warm servers and an isolated function's processes end here
        if pipe is not None:
            # a stop arriving now cuts no server's end short; after the last image (and its
            # phase check) it changes nothing: the report is whole, and the command's exit
            # status says it was stopped (arenabench.cli.run)
            _held(pipe.close)
    report: Report | None = None

    def build() -> None:
        nonlocal report
        report = build_report(
            store.compact(),
            images=store.images(),
            pipeline=pipe.name if pipe is not None else _pipeline_name(pipeline),
            dataset=str(data.root),
            area_reference=area_reference,
            tolerance=tolerance,
            complete=interrupted is None and failed is None,
            n_total=len(samples),
            manifest_sha256=data.manifest_sha256(),
        )

    _held(build)  # a stop while the report is built: the report still comes whole
    assert report is not None
    if interrupted is not None:
        raise EvaluationInterrupted(report, interrupted.signum)
    if failed is not None:
        raise EvaluationFailed(report, failed)
    return report


def _check_options(*, workers: int | None, area_reference: str, executor: str,
                   tolerance: float) -> None:
    """Raise ``ValueError`` naming the first of :func:`evaluate`'s options that is wrong."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers!r}")
    if area_reference not in AREA_REFERENCES:
        raise ValueError(
            f"area_reference must be one of {sorted(AREA_REFERENCES)}, got {area_reference!r}"
        )
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {executor!r}")
    if not tolerance >= 0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance!r}")


def _made_pipeline(pipeline: str | Callable[[Any], Any] | Pipeline, *, isolate: bool,
                   timeout_s: float | None) -> Pipeline:
    """The pipeline :func:`evaluate` runs: a team's function (``"pkg.module:function"``)
    with ``isolate`` in killable child processes, tried once first."""
    if not (isolate and isinstance(pipeline, str) and ":" in pipeline):
        return make_pipeline(pipeline)
    from arenabench.eval.runs import IsolatedCallablePipeline
    from arenabench.limits import DEFAULT_TIMEOUT_S

    isolated = IsolatedCallablePipeline(
        pipeline, timeout_s=DEFAULT_TIMEOUT_S if timeout_s is None else timeout_s)
    problem = isolated.trial()  # no pipeline at all (os:system): refused before
    if problem:
        isolated.close()
        raise ValueError(problem)
    return isolated


def _pool(pipe: Pipeline, pipeline: Any, *, executor: str,
          n_workers: int) -> tuple[Executor, Callable[[Any], Future]]:
    """The pool the images run in and how one image is submitted to it."""
    if executor == "process" and pipe.in_process and isinstance(pipeline, str):
        pool = local_executor(n_workers, initializer=_worker_pipeline, initargs=(pipeline,))
        return pool, lambda s: pool.submit(
            run_in_worker, PipelineRun(spec=pipeline, image_path=str(s.image_path)))
    run = pipe.run
    threads = ThreadPoolExecutor(max_workers=pipe.threads(n_workers),
                                 thread_name_prefix="arenabench-eval")
    return threads, lambda s: threads.submit(run, s.image_path)


def _phase_checked(store: ResultStore, data: Dataset, pipe: Pipeline, **options: Any):
    """``store`` with the failures phase-checked (:func:`_check_phases`); with the stop or
    the harness failure that came meanwhile (the images stay scored, their check not)."""
    from arenabench.interrupts import Interrupted

    interrupted = failed = None
    results = list(store.images())
    try:
        results = _check_phases(results, data, pipe, **options)
    except Interrupted as exc:  # the images are scored; their phase check is not
        interrupted = exc
    except HarnessError as exc:
        failed = exc
    checked = ResultStore(len(results), spill=store.spilled)
    for i, r in enumerate(results):
        checked.add(i, r)
    return checked, interrupted, failed


def _held(fn: Callable[[], Any] | None) -> Any:
    """Call ``fn`` with a stop signal held back until it returns; the
    :class:`~arenabench.interrupts.Interrupted` that arrived meanwhile (``None``: none)."""
    from arenabench.interrupts import Interrupted

    if not callable(fn):
        return None
    try:
        with deferred_stops():
            fn()
    except Interrupted as exc:
        return exc
    return None


def _pipeline_name(pipeline: Any) -> str:
    """A pipeline's name in reports before its adapter exists (a run stopped while it was
    being made)."""
    if isinstance(pipeline, str):
        return pipeline
    return str(getattr(pipeline, "name", None) or getattr(pipeline, "__name__", None)
               or type(pipeline).__name__)


def empty_report(*, pipeline: str, dataset: str, area_reference: str = DEFAULT_AREA_REFERENCE,
                 tolerance: float = DEFAULT_TOLERANCE, n_total: int | None = None) -> Report:
    """The report of a run stopped before any image finished (``complete=False``, no image):
    what a stop while the dataset is read or the pipeline is made leaves, so that a stopped
    command still writes its (empty) partial reports. ``n_total``: the images to run, when
    known."""
    return build_report([], pipeline=pipeline, dataset=dataset, area_reference=area_reference,
                        tolerance=tolerance, complete=False, n_total=n_total)


def _check_phases(results: list[ImageResult], data: Dataset, pipe: Pipeline,
                  *, phases: int, tolerance: float, area_reference: str, workers: int,
                  progress: bool, open_from: Any = None) -> list[ImageResult]:
    """The phase check of a run's failing images (docs/phase-check.md)."""
    from arenabench.eval.phase_check import check_phases, checked, dataset_scene_source
    from arenabench.progress import progress as progress_bar

    failing = sum(1 for r in results if checked(r))
    if not failing:
        return results
    by_id = data.items_by_id(r.id for r in results)
    source = dataset_scene_source(data.root, None if data.meta is None else data.meta.doc)
    if (source is not None and open_from is not None  # the preset's [open] of today
            and source.preset.params == open_from.params):
        source = replace(source, preset=replace(source.preset, open=dict(open_from.open)))
    with progress_bar(failing, desc=f"phase check {pipe.name}", enabled=progress) as bar:
        return check_phases(results, [by_id[r.id].gt for r in results], pipe.run,
                            phases=phases, tolerance=tolerance, area_reference=area_reference,
                            workers=workers, source=source, on_image=lambda: bar.update(1),
                            stop=pipe.stop)


def _run_all(samples: Iterable[DatasetItem], submit: Callable[[DatasetItem], Future],
             store: ResultStore, *, window: int, on_image: Callable[[], None],
             tolerance: float, area_reference: str, stop_runs: Callable[[], None],
             killable: bool) -> None:
    """Run every sample through ``submit`` with at most ``window`` images in flight, and
    score each as it finishes into ``store`` (a pipeline that raises is a crash).

    On a stop (:class:`~arenabench.interrupts.Interrupted`): the images already finished are
    scored, ``stop_runs()`` kills the running ones (``killable``) and waits for them, the
    images that finished meanwhile are scored too (when runs are killed, not the crashes:
    a killed run reads as one), and the stop is raised again."""
    pending: dict[Future, tuple[int, DatasetItem]] = {}
    queue = iter(enumerate(samples))

    def take(fut: Future) -> None:
        i, sample = pending.pop(fut)
        with deferred_stops():  # a finished image is scored and kept, whatever the signal
            try:
                pred = fut.result()
            except HarnessError:  # the harness's failure: never scored
                raise
            except Exception as exc:  # the harness never dies from a bad pipeline
                pred = Prediction(status="crash", message=f"{type(exc).__name__}: {exc}")
            store.add(i, score_sample(sample, pred, tolerance=tolerance,
                                      area_reference=area_reference))
        on_image()

    def refill() -> None:
        while len(pending) < window:
            nxt = next(queue, None)
            if nxt is None:
                return
            pending[submit(nxt[1])] = nxt

    try:
        refill()
        while pending:
            checkpoint()  # a stop signal a library swallowed
            done = first_done(pending)
            for fut in done:
                take(fut)
            refill()
    except BaseException:
        def keep(fut: Future) -> None:
            try:
                take(fut)
            except HarnessError:  # another image the harness failed: the first is raised
                pass

        with deferred_stops():  # a second stop does not cut this short
            for fut in [f for f in pending if f.done()]:  # finished before the stop
                keep(fut)
            stop_runs()
            for fut in [f for f in pending if f.done() and not f.cancelled()]:
                if killable and fut.exception() is None and fut.result().status == "crash":
                    continue  # perhaps the stop's own kill: not a result of the pipeline
                keep(fut)
        raise


def score(
    pipeline: str | Callable[[Any], Any] | Pipeline,
    dataset: str | os.PathLike[str] | Dataset,
    **options: Any,
):
    """Evaluate and return only the :class:`~arenabench.eval.scoring.results.Summary`.

    For test suites: ``assert score(my_pipeline, dataset).pass_rate >= 0.95``. ``options``
    are those of :func:`evaluate`.
    """
    return evaluate(pipeline, dataset, **options).summary
