"""Worker processes and their state, in one place.

Every pool that renders or runs pipelines (``generate``, ``bench``, ``sweep``, ``eval
--executor process``) starts its spawned workers with :func:`init_worker`: it sets up signal
handling (:func:`arenabench.interrupts.init_worker_process`) and caps Mesa llvmpipe's
threads (``LP_NUM_THREADS``, :func:`llvmpipe_threads`) so that ``workers`` processes share
the cores instead of each starting one thread per core.

State a worker keeps between tasks (a renderer, a built pipeline, a loaded dataset) lives in
one registry, created on first use by key: :func:`process_state` holds one value per process
(shared by its threads), :func:`thread_state` one per thread (an OpenGL context is current in
one thread only, so a Dask worker running several threads needs one renderer each). The same
task function thus serves this process, a spawned pool and a Dask worker.

Task arguments sent to pools are frozen dataclasses (picklable records), never bare tuples.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Hashable
from typing import Any, TypeVar

T = TypeVar("T")

#: Environment variable read by Mesa llvmpipe for its rasteriser thread count.
LLVMPIPE_THREADS_ENV = "LP_NUM_THREADS"

_PROCESS: dict[Hashable, Any] = {}
_PROCESS_LOCK = threading.RLock()
_THREAD = threading.local()


def usable_cores() -> int:
    """Number of CPU cores this process may run on (its affinity mask; the default worker
    count of every pool)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def check_workers(workers: Any) -> int:
    """``workers`` as an ``int``: the rule of every pool's worker count.

    Raises
    ------
    ValueError
        When ``workers`` is not an integer >= 1.
    """
    if int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    return int(workers)


def llvmpipe_threads(workers: int) -> int:
    """llvmpipe threads per worker when ``workers`` processes share the usable cores.

    Raises
    ------
    ValueError
        When ``workers`` is not an integer >= 1.
    """
    return max(1, usable_cores() // check_workers(workers))


def init_worker(lp_threads: int | None = None, parent_pid: int | None = None) -> None:
    """Process-pool initializer shared by every pool.

    Parameters
    ----------
    lp_threads : int, optional
        ``LP_NUM_THREADS`` for Mesa llvmpipe, set unless the environment already has it
        (``None``: left alone).
    parent_pid : int, optional
        The parent's pid: the worker then stops with its parent, ignores SIGINT and unwinds
        its task on SIGTERM (:func:`arenabench.interrupts.init_worker_process`).
    """
    if parent_pid is not None:
        from arenabench.interrupts import init_worker_process

        init_worker_process(parent_pid=parent_pid)
    if lp_threads and LLVMPIPE_THREADS_ENV not in os.environ:
        os.environ[LLVMPIPE_THREADS_ENV] = str(int(lp_threads))
    # The last of multiprocessing's exit hooks in this worker: once its tasks are done and
    # their results sent, it exits without tearing the interpreter down (GL context, modules:
    # about 0.4 s), so that a pool's close() + join() returns at once. Only in a process that
    # multiprocessing started: anywhere else it would turn the process's exit status into 0.
    import multiprocessing.util

    if multiprocessing.parent_process() is not None:
        multiprocessing.util.Finalize(None, _exit_now, exitpriority=-100)


def _exit_now() -> None:
    import sys

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    os._exit(0)


def process_state(key: Hashable, factory: Callable[[], T]) -> T:
    """This process's value for ``key``, made by ``factory()`` on first use (under a lock,
    so threads share one value).

    Parameters
    ----------
    key : hashable
        Names the state, e.g. ``("pipeline", spec)``.
    factory : callable
        Makes the value; called once per process and key.
    """
    with _PROCESS_LOCK:
        if key not in _PROCESS:
            _PROCESS[key] = factory()
        return _PROCESS[key]


def thread_state(key: Hashable, factory: Callable[[], T]) -> T:
    """This thread's value for ``key``, made by ``factory()`` on first use in the thread.

    Parameters
    ----------
    key : hashable
        Names the state, e.g. ``"renderer"``.
    factory : callable
        Makes the value; called once per thread and key.
    """
    values: dict[Hashable, Any] | None = getattr(_THREAD, "values", None)
    if values is None:
        values = _THREAD.values = {}
    if key not in values:
        values[key] = factory()
    return values[key]
