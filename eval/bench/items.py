"""``arenabench bench``: throughput of generation and scoring on this machine, in one run.

Eight measurements (see :func:`run_bench`), each on the same ``eyrc`` scenes at the camera's
size (1000 x 1000):

1. ``generate_disk_ips``: :func:`arenabench.generator.dataset.dataset_writer.generate_dataset` end
to end
   (spawned workers, PNG + GT JSON, manifest and COCO file), as ``arenabench generate`` runs;
2. ``generate_memory_ips``: render + GT in memory (:func:`make_sample`), no files;
   ``disk_vs_memory_cpu``: CPU per image of (1)'s rendering tasks (render, GT, encode, write;
   ``details.generate_disk.task_cpu_ms_per_image``) over (2)'s, both with a warm renderer
   (the start-up of (1)'s processes and finishing its set are
   ``details.generate_disk.startup_and_finish_cpu_ms_per_image``);
3. ``naive_ips``: the naive baseline, to disk: a new pyrender renderer and scene per image,
   pyrender's default (lit, 4x MSAA) shading under a directional light, GT, PNG at OpenCV's
   default settings;
4. ``encode_floor_ips``: PNG encode + write of already-rendered images, as the writer does;
5. ``pipeline_ips``: the reference pipeline over the image files of (1), decode and scoring
   included; ``pipeline_eval_ips``: the same through :func:`arenabench.eval.evaluation.evaluate`
   (as ``arenabench eval`` runs it: its process pool's start-up included);
6. ``sweep_ips``: a streaming sweep in memory (render, degrade, detect, score) through
   :func:`arenabench.eval.sweep.run_sweep`, varying ``SWEEP_AXIS``, its start-up included
   (a post-render axis: each worker renders a scene once for all its points, as any such
   sweep does);
7. ``worker_peak_rss_mb`` / ``worker_rss_growth_mb``: peak resident memory of a rendering
   worker and its growth over ``rss_renders`` consecutive renders;
8. ``sandbox_overhead_ms``: what bubblewrap adds to one external run
   (:class:`~arenabench.eval.runs.pipeline.CommandPipeline`, a trivial shell command writing
   ``obstacles.txt``): median wall time per run with ``--sandbox bwrap`` minus with
   ``--sandbox none`` (``sandbox_runs`` runs each, interleaved, one at a time; 0 with
   ``details.sandbox.bwrap`` false where bubblewrap does not work).
9. ``script_*``: an external Python script per image (:data:`SCRIPT_PATH`, a competition-style
   ``map.py``: markers, warp, threshold, count), CPU ms per image (every process of the
   harness included): ``script_inprocess_cpu_ms`` runs it with :mod:`runpy` in one process
   (OpenCV imported once), ``script_cold_cpu_ms`` as ``--cmd "{python} map.py --image
   {image}" --no-warm`` (a new interpreter per image), ``script_warm_cpu_ms`` the same
   through the command's warm interpreter (server start and end included);
   ``script_warm_vs_inprocess`` and ``script_cold_vs_inprocess`` are the ratios
   (``script_runs`` images, one at a time, sandbox ``auto``); ``details.script`` splits the
   warm figure into the server's start and end with one run and the CPU per later image.
10. ``markerless_*_ms``: CPU ms of the reference pipeline (:func:`arenabench.detect`) giving
    up on a 1000 x 1000 image without markers: only boxes, Gaussian noise, blank (median of
    ``markerless_runs`` runs each).
11. ``bigset_*``: a synthetic set of ``bigset_entries`` manifest entries (tiny images, real
    GT files; :mod:`arenabench.eval.bench.bigset`) loaded, scored with a do-nothing pipeline
    and reported in a fresh process: ``bigset_load_s_per_10k`` (CPU s of loading and
    checking every file), ``bigset_eval_s_per_10k`` (all of it), ``bigset_peak_rss_mb`` and
    ``bigset_rss_mb_per_10k`` (what 10,000 more entries add to the peak).
12. ``twin_example_s`` / ``twin_example_peak_mb``: ``arenabench twin`` on the published
    example without a texture (:mod:`arenabench.eval.bench.twin_cost`), wall seconds and the
    command's peak resident memory (not with ``--quick``).

Items 2, 4 and 5 run on ``workers`` spawned processes that are started and warmed up
(one renderer each) before the clock starts; item 3 on started processes (modules imported)
that build a renderer per image; items 1, 5b and 6 include their own start-up, as their
commands do; item 7 runs in a process of its own. Figures are throughputs of the whole pool
(images or scenes per second).
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from arenabench.generator.parameters.presets import DEFAULT_PRESET
from arenabench.interrupts import deferred_stops
from arenabench.local_pool import local_pool
from arenabench.workers import init_worker, llvmpipe_threads, usable_cores

#: bench.json schema id.
BENCH_SCHEMA = "arenabench.bench/1"

#: (key, comparison, value, what): the project's targets for a 2-core machine without a GPU.
TARGETS: tuple[tuple[str, str, float, str], ...] = (
    ("generate_disk_ips", ">=", 40.0, "images/s"),
    ("disk_vs_naive", ">=", 3.0, "x"),
    ("disk_vs_memory_cpu", "<=", 1.3, "x"),
    ("pipeline_ips", ">=", 100.0, "images/s"),
    ("sweep_ips", ">=", 40.0, "scenes/s"),
    ("worker_peak_rss_mb", "<=", 400.0, "MB"),
    ("worker_rss_growth_mb", "<", 20.0, "MB"),
    ("sandbox_overhead_ms", "<=", 50.0, "ms"),
    ("script_warm_vs_inprocess", "<=", 1.5, "x"),
    ("markerless_boxes_ms", "<=", 50.0, "ms"),
    ("markerless_noise_ms", "<=", 50.0, "ms"),
    ("bigset_load_s_per_10k", "<=", 3.0, "CPU s"),
    ("bigset_rss_mb_per_10k", "<=", 100.0, "MB"),
    ("twin_example_s", "<=", 180.0, "s"),
    ("twin_example_peak_mb", "<=", 1536.0, "MB"),
)

#: The streaming sweep's varied parameter (item 6): Gaussian sensor noise, off to strong.
SWEEP_AXIS = "degrade.noise_sigma=0:6:2"

#: Keys every bench.json holds (figures are positive numbers).
FIGURE_KEYS: tuple[str, ...] = (
    "generate_disk_ips", "generate_memory_ips", "naive_ips", "encode_floor_ips",
    "pipeline_ips", "sweep_ips", "worker_peak_rss_mb", "worker_rss_growth_mb",
    "pipeline_eval_ips", "disk_vs_naive", "disk_vs_floor", "sandbox_overhead_ms",
    "script_inprocess_cpu_ms", "script_cold_cpu_ms", "script_warm_cpu_ms",
    "script_warm_vs_inprocess", "script_cold_vs_inprocess",
    "markerless_boxes_ms", "markerless_noise_ms", "markerless_blank_ms",
    "disk_vs_memory_cpu",
    "bigset_load_s_per_10k", "bigset_eval_s_per_10k", "bigset_peak_rss_mb",
)  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class BenchConfig:
    """What :func:`run_bench` measures and how much.

    Parameters
    ----------
    count : int
        Scenes of items 1, 2, 5 (and the images item 4 encodes, at most 200 per worker).
    sweep_count : int
        Scenes of the streaming sweep (item 6).
    naive_count : int
        Scenes of the naive baseline (item 3; slow, so fewer).
    rss_renders : int
        Consecutive renders of the memory measurement (item 7).
    sandbox_runs : int
        External runs per sandbox mode (item 8).
    script_runs : int
        Images of each way of running the external script (item 9; at most ``count``).
    markerless_runs : int
        Runs of the reference pipeline on each image without markers (item 10).
    bigset_entries : int
        Manifest entries of the synthetic big set (item 11; and a set of half as many).
    workers : int or None
        Processes; default: the usable cores.
    twin : bool
        Measure item 12 (a twin of the published example without a texture, about two
        minutes; ``quick`` leaves it out).
    preset : str
        Scene preset.
    seed : int
        Run seed.
    """

    count: int = 400
    sweep_count: int = 300
    naive_count: int = 40
    rss_renders: int = 2000
    sandbox_runs: int = 40
    script_runs: int = 60
    markerless_runs: int = 5
    bigset_entries: int = 10_000
    workers: int | None = None
    preset: str = DEFAULT_PRESET
    seed: int = 0
    twin: bool = True

    def __post_init__(self) -> None:
        for name in ("count", "sweep_count", "naive_count", "rss_renders", "sandbox_runs",
                     "script_runs", "markerless_runs", "bigset_entries"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if self.workers is not None and (
            isinstance(self.workers, bool) or not isinstance(self.workers, int)
            or self.workers < 1
        ):
            raise ValueError(f"workers must be an integer >= 1 or None, got {self.workers!r}")

    @classmethod
    def quick(cls, *, workers: int | None = None) -> BenchConfig:
        """A tiny configuration (seconds): every figure, none of them meaningful."""
        return cls(count=6, sweep_count=6, naive_count=2, rss_renders=20, sandbox_runs=3,
                   script_runs=3, markerless_runs=1, bigset_entries=400, workers=workers,
                   twin=False)


@dataclass
class BenchResult:
    """Figures of one run (``figures``), per-item details and the machine's description."""

    figures: dict[str, float]
    details: dict[str, Any] = field(default_factory=dict)
    machine: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """The content of ``bench.json`` (figures at the top level)."""
        return {
            "schema": BENCH_SCHEMA,
            **{k: float(v) for k, v in self.figures.items()},
            "cores": self.machine.get("cores"),
            "versions": self.machine.get("versions", {}),
            "machine": self.machine,
            "targets": [
                {"key": k, "op": op, "value": v, "unit": unit,
                 "met": target_met(self.figures.get(k), op, v)}
                for k, op, v, unit in TARGETS
            ],
            "details": self.details,
            "config": self.config,
            "seconds": self.seconds,
        }


def target_met(value: float | None, op: str, target: float) -> bool | None:
    """Whether ``value op target`` holds (None when there is no value)."""
    if value is None:
        return None
    return {">=": value >= target, "<=": value <= target, "<": value < target}[op]


# ----------------------------------------------------------------------------- workers

@dataclass(frozen=True)
class SceneTask:
    """Scene ``index`` of ``preset`` with run ``seed`` (one unit of a bench pool)."""

    preset: str
    seed: int
    index: int


@dataclass(frozen=True)
class ImageTask:
    """An image file and its GT file to run the reference pipeline on and score."""

    image: str
    gt: str


@dataclass(frozen=True)
class FloorTask:
    """Scenes to render, then encode and write into ``out`` (the timed part)."""

    preset: str
    seed: int
    indices: tuple[int, ...]
    out: str


@dataclass(frozen=True)
class NaiveTask:
    """One scene of the naive baseline, written into ``out``."""

    preset: str
    seed: int
    index: int
    out: str


@dataclass(frozen=True)
class RssTask:
    """``renders`` consecutive renders of ``preset`` in one worker."""

    preset: str
    seed: int
    renders: int


def _renderer():
    from arenabench.generator.dataset.make import worker_renderer

    return worker_renderer()


def _warm(task: SceneTask) -> int:
    """Create this worker's renderer and render one scene (not timed)."""
    from arenabench.generator.dataset.make import make_sample

    make_sample(task.preset, seed=task.seed, index=task.index, renderer=_renderer())
    return os.getpid()


def _memory_one(task: SceneTask) -> float:
    """Render one scene and compute its GT; returns the CPU seconds it took (all threads)."""
    from arenabench.generator.dataset.make import make_sample

    c0 = time.process_time()
    make_sample(task.preset, seed=task.seed, index=task.index, renderer=_renderer())
    return time.process_time() - c0


def _pipeline_one(task: ImageTask) -> tuple[bool, float]:
    """Load one image file (decode included), run the reference pipeline, score it.

    Returns whether it passed and the CPU seconds it took.
    """
    from arenabench.eval.datasets.reader import DatasetItem
    from arenabench.eval.scoring.answers import prediction_from_result
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.imageio import load_image
    from arenabench.pipeline import detect

    c0 = time.process_time()
    t0 = time.perf_counter()
    det = detect(load_image(task.image))
    pred = prediction_from_result(det, latency_ms=(time.perf_counter() - t0) * 1e3)
    gt = json.loads(Path(task.gt).read_text())
    truth = DatasetItem(id=gt["id"], image_path=Path(), gt_path=Path(), gt=gt).truth()
    return bool(score_image(truth, pred).passed), time.process_time() - c0


def _floor_chunk(task: FloorTask) -> tuple[int, float, float]:
    """Render the scenes (not timed), then time their PNG encode + atomic write."""
    import cv2

    from arenabench.fileio import atomic_write_bytes
    from arenabench.generator.dataset.make import make_sample
    from arenabench.imageio import encode_png

    preset, seed, indices, out = task.preset, task.seed, task.indices, task.out
    images = [make_sample(preset, seed=seed, index=i, renderer=_renderer()).rgb
              for i in indices]
    c0, t0 = time.process_time(), time.perf_counter()
    for i, rgb in zip(indices, images, strict=True):
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)  # as the dataset writer does
        atomic_write_bytes(Path(out) / f"{i:06d}.png", encode_png(bgr))
    return len(indices), time.perf_counter() - t0, time.process_time() - c0


def _naive_one(task: NaiveTask) -> int:
    """The naive baseline: a new renderer and scene per image, pyrender's lit default."""
    import cv2

    from arenabench.fileio import atomic_write_text, dumps_json
    from arenabench.generator.model.sampler import sample_scene
    from arenabench.generator.rendering.render import NaiveRenderer
    from arenabench.generator.truth.groundtruth import compute_ground_truth

    preset, seed, index, out = task.preset, task.seed, task.index, task.out
    scene = sample_scene(preset, seed=seed, index=index).scene
    with NaiveRenderer() as renderer:
        rgb = renderer.render(scene).rgb
    gt = compute_ground_truth(scene)
    cv2.imwrite(str(Path(out) / f"{index:06d}.png"), np.ascontiguousarray(rgb[:, :, ::-1]))
    atomic_write_text(Path(out) / f"{index:06d}.json", dumps_json(gt))
    return index


def _import_pyrender(_: int) -> int:
    from arenabench.generator.rendering import pyrender_compat, render  # noqa: F401

    return os.getpid()


def _vm_status() -> dict[str, float]:
    """VmRSS and VmHWM of this process in MB (from /proc/self/status)."""
    out: dict[str, float] = {}
    try:
        text = Path("/proc/self/status").read_text()
    except OSError:  # pragma: no cover - not Linux
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        return {"VmRSS": peak, "VmHWM": peak}
    for line in text.splitlines():
        key, _, rest = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            out[key] = float(rest.split()[0]) / 1024.0
    return out


def _rss_run(task: RssTask) -> dict[str, float]:
    """Render ``n`` consecutive scenes in this worker; RSS after warm-up, after, and peak."""
    from arenabench.generator.model.sampler import sample_scene

    preset, seed, n = task.preset, task.seed, task.renders
    renderer = _renderer()
    warm = min(20, max(1, n // 10))
    for i in range(warm):
        renderer.render(sample_scene(preset, seed=seed, index=i).scene)
    before = _vm_status()
    t0 = time.perf_counter()
    for i in range(n):
        renderer.render(sample_scene(preset, seed=seed, index=warm + i).scene)
    seconds = time.perf_counter() - t0
    after = _vm_status()
    return {"rss_after_warmup_mb": before["VmRSS"], "rss_after_mb": after["VmRSS"],
            "peak_rss_mb": after["VmHWM"], "renders": float(n), "seconds": seconds}


# ----------------------------------------------------------------------------- driver

def _pool(workers: int) -> AbstractContextManager[Any]:
    """The workers of a timed measure (:func:`arenabench.local_pool.local_pool`), initialised
    with their llvmpipe threads only."""
    return local_pool(workers, initializer=init_worker, initargs=(llvmpipe_threads(workers),))


def _timed_map(pool, func: Callable, tasks: list, workers: int) -> tuple[float, list]:
    t0 = time.perf_counter()
    out = pool.map(func, tasks, chunksize=max(1, len(tasks) // (8 * workers)))
    return time.perf_counter() - t0, out


def _cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and of its finished, waited-for children."""
    import resource

    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        r = resource.getrusage(who)
        total += r.ru_utime + r.ru_stime
    return total


def _warm_pool(pool, workers: int, cfg: BenchConfig) -> None:
    # one task per worker at a time: each worker builds its renderer before timing starts
    pool.map(_warm, [SceneTask(cfg.preset, cfg.seed, i) for i in range(2 * workers)],
             chunksize=1)


def _machine(gl: dict[str, str]) -> dict[str, Any]:
    import cv2
    import pyrender

    from arenabench import __version__

    return {
        "cores": usable_cores(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "versions": {
            "arenabench": __version__, "python": sys.version.split()[0],
            "numpy": np.__version__, "opencv": cv2.__version__,
            "pyrender": getattr(pyrender, "__version__", "unknown"), **gl,
        },
    }


def run_bench(
    config: BenchConfig | None = None,
    *,
    workdir: str | os.PathLike[str] | None = None,
    on_item: Callable[[str, float], None] | None = None,
) -> BenchResult:
    """Run the eight measurements (see the module docstring).

    Parameters
    ----------
    config : BenchConfig, optional
        Sizes and workers (default ``BenchConfig()``: about 2 minutes on 2 cores).
    workdir : path-like, keyword-only
        Scratch folder for the generated files (a temporary one, removed, by default).
    on_item : callable, keyword-only
        Called with ``(item key, seconds)`` after each measurement (progress output).

    Returns
    -------
    BenchResult
    """
    cfg = config or BenchConfig()
    workers = cfg.workers or usable_cores()
    notify = on_item or (lambda key, sec: None)
    start = time.perf_counter()
    figures: dict[str, float] = {}
    details: dict[str, Any] = {"workers": workers, "load_avg_start": _load_avg()}
    scratch: Path | None = None
    try:
        with deferred_stops():  # a stop lands before the folder is made or after it is named
            scratch = Path(tempfile.mkdtemp(prefix="arenabench-bench-", dir=workdir))
        from arenabench.generator.dataset.dataset_writer import DatasetArgs, generate_dataset

        ext = DatasetArgs(preset=cfg.preset, count=cfg.count, seed=cfg.seed).image_ext

        # 1. generation to disk, as `arenabench generate --workers N` runs it
        c0, t0 = _cpu_seconds(), time.perf_counter()
        result = generate_dataset(scratch / "dataset", preset=cfg.preset, count=cfg.count,
                                  seed=cfg.seed, workers=workers, progress=False)
        sec = time.perf_counter() - t0
        figures["generate_disk_ips"] = cfg.count / sec
        disk_cpu = _per(_cpu_seconds() - c0, cfg.count)
        details["generate_disk"] = {"images": cfg.count, "seconds": sec,
                                    "cpu_ms_per_image": disk_cpu,
                                    "task_cpu_ms_per_image": result.task_cpu_ms,
                                    "startup_and_finish_cpu_ms_per_image":
                                        disk_cpu - result.task_cpu_ms,
                                    "median_ms_per_image": result.timings_ms}
        notify("generate_disk_ips", sec)

        tasks = [SceneTask(cfg.preset, cfg.seed, i) for i in range(cfg.count)]
        with _pool(workers) as pool:
            _warm_pool(pool, workers, cfg)
            # 2. generation in memory
            sec, cpu = _timed_map(pool, _memory_one, tasks, workers)
            figures["generate_memory_ips"] = cfg.count / sec
            details["generate_memory"] = {"images": cfg.count, "seconds": sec,
                                          "cpu_ms_per_image": _per(sum(cpu), cfg.count)}
            notify("generate_memory_ips", sec)

            # 4. the floor: encode + write of rendered images
            floor_dir = scratch / "floor"
            floor_dir.mkdir()
            per = min(200, max(1, cfg.count // workers))
            chunks = [FloorTask(cfg.preset, cfg.seed, tuple(range(w * per, (w + 1) * per)),
                                str(floor_dir))
                      for w in range(workers)]
            done = pool.map(_floor_chunk, chunks, chunksize=1)
            n_floor = sum(d[0] for d in done)
            figures["encode_floor_ips"] = float(sum(n / s for n, s, _ in done))
            details["encode_floor"] = {"images": n_floor,
                                       "seconds_per_worker": [d[1] for d in done],
                                       "cpu_ms_per_image": _per(sum(d[2] for d in done),
                                                                n_floor)}
            notify("encode_floor_ips", max(d[1] for d in done))

            # 5. the reference pipeline from the image files of (1), decode included
            data = scratch / "dataset"
            files = [ImageTask(str(data / "images" / f"{i:06d}.{ext}"),
                               str(data / "gt" / f"{i:06d}.json"))
                     for i in range(cfg.count)]
            t0 = time.perf_counter()
            outs = pool.map(_pipeline_one, files,
                            chunksize=max(1, len(files) // (8 * workers)))
            sec = time.perf_counter() - t0
            figures["pipeline_ips"] = cfg.count / sec
            details["pipeline"] = {"images": cfg.count, "seconds": sec,
                                   "cpu_ms_per_image": _per(sum(c for _, c in outs), cfg.count),
                                   "pass_rate": float(np.mean([p for p, _ in outs])),
                                   "how": "load_image + detect + score_image, warm workers"}
            notify("pipeline_ips", sec)

            gl_info = pool.apply(_gl_info)
        # (leaving the block closes and joins the pool: the workers exit on their own)

        # 3. the naive baseline (own processes: pyrender's clean-up ends their EGL display)
        naive_dir = scratch / "naive"
        naive_dir.mkdir()
        c0 = _cpu_seconds()
        with _pool(workers) as pool:
            pool.map(_import_pyrender, range(workers), chunksize=1)  # start, import
            naive_tasks = [NaiveTask(cfg.preset, cfg.seed, i, str(naive_dir))
                           for i in range(cfg.naive_count)]
            sec, _ = _timed_map(pool, _naive_one, naive_tasks, workers)
        figures["naive_ips"] = cfg.naive_count / sec
        details["naive"] = {"images": cfg.naive_count, "seconds": sec,
                            "cpu_ms_per_image_with_startup":
                                _per(_cpu_seconds() - c0, cfg.naive_count)}
        notify("naive_ips", sec)

        # 5b. the same through `arenabench eval`'s runner, its start-up included
        from arenabench.eval.evaluation import evaluate

        c0, t0 = _cpu_seconds(), time.perf_counter()
        report = evaluate("reference", scratch / "dataset", workers=workers,
                          executor="process")
        sec = time.perf_counter() - t0
        figures["pipeline_eval_ips"] = cfg.count / sec
        details["pipeline"]["eval_runner"] = {
            "images": cfg.count, "seconds": sec,
            "cpu_ms_per_image": _per(_cpu_seconds() - c0, cfg.count),
            "pass_rate": report.summary.pass_rate, "executor": "process"}
        notify("pipeline_eval_runner", sec)

        # 6. streaming sweep through the sweep runner (render, degrade, detect, score)
        from arenabench.eval.sweep import PipelineSpec, SweepSpec, parse_vary, run_sweep

        axis = parse_vary(SWEEP_AXIS)
        per_point = max(1, -(-cfg.sweep_count // len(axis.values)))
        spec = SweepSpec(preset=cfg.preset, axes=(axis,), per_point=per_point, seed=cfg.seed + 1,
                         pipelines=(PipelineSpec("pipeline", "reference"),))
        c0, t0 = _cpu_seconds(), time.perf_counter()
        sweep = run_sweep(spec, workers=workers)
        sec = time.perf_counter() - t0
        scenes = per_point * len(axis.values)
        figures["sweep_ips"] = scenes / sec
        details["sweep"] = {
            "scenes": scenes, "seconds": sec, "vary": SWEEP_AXIS,
            "cpu_ms_per_scene": _per(_cpu_seconds() - c0, scenes),
            "how": "arenabench.eval.sweep.run_sweep, its process pool's start-up included; "
                   "a post-render axis, so each scene is rendered once for all its points",
            "pass_rate": {str(p.params): p.summary.pass_rate for p in sweep.summaries},
            "median_ms": sweep.run.get("median_ms", {}),
        }
        notify("sweep_ips", sec)

        # 7. memory of one rendering worker over rss_renders consecutive renders
        with _pool(1) as pool:
            rss = pool.apply(_rss_run, (RssTask(cfg.preset, cfg.seed, cfg.rss_renders),))
        figures["worker_peak_rss_mb"] = rss["peak_rss_mb"]
        figures["worker_rss_growth_mb"] = max(0.0, rss["rss_after_mb"]
                                              - rss["rss_after_warmup_mb"])
        details["rss"] = rss
        notify("worker_rss_growth_mb", rss["seconds"])

        # 8. what bubblewrap adds to an external run
        t0 = time.perf_counter()
        figures["sandbox_overhead_ms"], details["sandbox"] = _sandbox_overhead(
            scratch / "dataset" / "images" / f"000000.{ext}", cfg.sandbox_runs)
        notify("sandbox_overhead_ms", time.perf_counter() - t0)

        # 9. an external Python script per image: in one process, cold, warm
        t0 = time.perf_counter()
        images = sorted((scratch / "dataset" / "images").iterdir())[: cfg.script_runs]
        script_figures, details["script"] = script_per_image(images)
        figures.update(script_figures)
        notify("script_warm_vs_inprocess", time.perf_counter() - t0)

        # 10. the reference pipeline giving up on images without markers
        t0 = time.perf_counter()
        marker_figures, details["markerless"] = markerless_ms(cfg.markerless_runs)
        figures.update(marker_figures)
        notify("markerless_boxes_ms", time.perf_counter() - t0)

        # 11. big sets: load and score a synthetic set, per 10,000 entries
        t0 = time.perf_counter()
        from .bigset import big_set_figures

        bigset_figures, details["bigset"] = big_set_figures(cfg.bigset_entries, scratch)
        figures.update(bigset_figures)
        notify("bigset_load_s_per_10k", time.perf_counter() - t0)

        # 12. a twin of the published example without a texture: time and peak memory
        if cfg.twin:
            t0 = time.perf_counter()
            from .twin_cost import twin_cost

            twin_figures, details["twin"] = twin_cost(scratch)
            figures.update(twin_figures)
            notify("twin_example_s", time.perf_counter() - t0)
    finally:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
    details["load_avg_end"] = _load_avg()
    figures["disk_vs_naive"] = figures["generate_disk_ips"] / figures["naive_ips"]
    figures["disk_vs_floor"] = figures["generate_disk_ips"] / figures["encode_floor_ips"]
    figures["disk_vs_memory_cpu"] = (details["generate_disk"]["task_cpu_ms_per_image"]
                                     / details["generate_memory"]["cpu_ms_per_image"])
    return BenchResult(figures=figures, details=details, machine=_machine(gl_info),
                       config=asdict(cfg) | {"workers": workers},
                       seconds=time.perf_counter() - start)


#: Item 8's trivial external command: a shell writing a well-formed obstacles.txt.
SANDBOX_COMMAND = "sh -c 'printf \"Aruco ID: []\\nObstacles: 0\\nArea: 0\\n\" > obstacles.txt'"


def _sandbox_overhead(image: Path, runs: int) -> tuple[float, dict[str, Any]]:
    """Median wall ms per external run with and without bubblewrap (item 8)."""
    from arenabench.eval.runs import CommandPipeline, RunSettings, bwrap_problem

    problem = bwrap_problem()
    modes = ("none",) if problem else ("none", "bwrap")
    pipes = {m: CommandPipeline(SANDBOX_COMMAND, settings=RunSettings(sandbox=m)) for m in modes}
    times: dict[str, list[float]] = {m: [] for m in modes}
    for i in range(runs + 1):
        for m in modes:
            t0 = time.perf_counter()
            pred = pipes[m].run(image)
            if pred.status != "ok":
                raise RuntimeError(f"bench: the trivial command failed ({m}): {pred.message}")
            if i:  # the first round warms up
                times[m].append((time.perf_counter() - t0) * 1000.0)
    median = {m: float(np.median(v)) for m, v in times.items()}
    detail: dict[str, Any] = {"runs": runs, "command": SANDBOX_COMMAND,
                              "median_ms_per_run": median, "bwrap": problem is None}
    if problem:
        detail["bwrap_problem"] = problem
        return 0.0, detail
    return max(0.0, median["bwrap"] - median["none"]), detail


#: Item 9's script: a competition-style map.py (numpy and OpenCV only).
SCRIPT_PATH = Path(__file__).with_name("map_script.py")


def script_per_image(images: list[Path]) -> tuple[dict[str, float], dict[str, Any]]:
    """Item 9: CPU (and wall) ms per image of :data:`SCRIPT_PATH` run in this process with
    :mod:`runpy`, as a cold command and through its warm interpreter (one image at a time).

    Returns
    -------
    (figures, details)
        ``script_*`` figures; details hold wall ms per image and the answers' agreement.
    """
    import runpy

    from arenabench.eval.runs import CommandPipeline, RunSettings

    if not images:
        raise ValueError("bench: item 9 needs at least one image")
    cmd = f"{{python}} {SCRIPT_PATH} --image {{image}}"
    cpu: dict[str, float] = {}
    wall: dict[str, float] = {}
    answers: dict[str, list[tuple]] = {}
    old_cwd, old_argv = os.getcwd(), sys.argv
    work: Path | None = None
    try:
        with deferred_stops():  # as above
            work = Path(tempfile.mkdtemp(prefix="arenabench-bench-script-"))
        os.chdir(work)
        for i in range(len(images) + 1):  # the first run warms up (imports)
            if i == 1:
                c0, t0 = _cpu_seconds(), time.perf_counter()
            sys.argv = [str(SCRIPT_PATH), "--image", str(images[max(0, i - 1)])]
            try:
                runpy.run_path(str(SCRIPT_PATH), run_name="__main__")
            except SystemExit:
                pass
        cpu["inprocess"], wall["inprocess"] = _cpu_seconds() - c0, time.perf_counter() - t0
    finally:
        os.chdir(old_cwd)
        sys.argv = old_argv
        if work is not None:
            shutil.rmtree(work, ignore_errors=True)
    for name, warm in (("cold", False), ("warm", True)):
        c0, t0 = _cpu_seconds(), time.perf_counter()
        pipe = CommandPipeline(cmd, settings=RunSettings(warm=warm))
        preds = [pipe.run(image) for image in images]
        pipe.close()  # the warm server ends (and is waited for): its CPU time is counted
        cpu[name], wall[name] = _cpu_seconds() - c0, time.perf_counter() - t0
        answers[name] = [(p.status, p.count, p.area) for p in preds]
    # the warm server's start and end alone (with one run): what the warm figure spends once
    c0 = _cpu_seconds()
    with CommandPipeline(cmd, settings=RunSettings(warm=True)) as pipe:  # its own context
        pipe.run(images[0])
    once = 1000.0 * (_cpu_seconds() - c0)
    n = len(images)
    per = {k: 1000.0 * v / n for k, v in cpu.items()}
    figures = {
        "script_inprocess_cpu_ms": per["inprocess"], "script_cold_cpu_ms": per["cold"],
        "script_warm_cpu_ms": per["warm"],
        "script_warm_vs_inprocess": per["warm"] / per["inprocess"],
        "script_cold_vs_inprocess": per["cold"] / per["inprocess"],
    }  # fmt: skip
    details = {"images": n, "command": cmd, "cpu_ms_per_image": per,
               "wall_ms_per_image": {k: 1000.0 * v / n for k, v in wall.items()},
               "warm_start_and_one_run_cpu_ms": once,
               "warm_cpu_ms_per_image_after_start": (1000.0 * cpu["warm"] - once) / max(1, n - 1),
               "warm_equals_cold": answers["warm"] == answers["cold"],
               "ok": sum(a[0] == "ok" for a in answers["warm"])}
    return figures, details


def markerless_images(seed: int = 0) -> dict[str, np.ndarray]:
    """Item 10's 1000 x 1000 images without markers: twelve dark boxes on a light floor,
    uniform noise, blank white."""
    import cv2

    rng = np.random.default_rng(seed)
    boxes = np.full((1000, 1000, 3), 200, np.uint8)
    for _ in range(12):
        x, y = (int(v) for v in rng.integers(50, 880, 2))
        cv2.rectangle(boxes, (x, y), (x + 60, y + 80), (40, 40, 40), -1)
    return {"boxes": boxes, "noise": rng.integers(0, 256, (1000, 1000, 3), dtype=np.uint8),
            "blank": np.full((1000, 1000, 3), 255, np.uint8)}


def markerless_ms(runs: int) -> tuple[dict[str, float], dict[str, Any]]:
    """Item 10: median CPU ms of :func:`arenabench.detect` per image without markers."""
    from arenabench.pipeline.detection import detect

    figures: dict[str, float] = {}
    passes: dict[str, int] = {}
    for name, image in markerless_images().items():
        detect(image)  # warm-up (detector objects)
        times = []
        for _ in range(runs):
            c0 = time.process_time()
            result = detect(image)
            times.append((time.process_time() - c0) * 1000.0)
        if result.status == "ok":
            raise RuntimeError(f"bench: markers found in the {name} image")
        figures[f"markerless_{name}_ms"] = float(np.median(times))
        passes[name] = int(result.details.get("marker_passes", 0))
    return figures, {"runs": runs, "marker_passes": passes}


def _per(seconds: float, n: int) -> float:
    return 1000.0 * seconds / max(1, n)


def _load_avg() -> list[float]:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:  # pragma: no cover - not available
        return []


def _gl_info() -> dict[str, str]:
    return _renderer().gl_info()
