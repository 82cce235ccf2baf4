"""The local process pools: every worker process a command starts on this machine comes from
here.

- :func:`local_map`: ``generate`` (:mod:`arenabench.generator.dataset.dataset_writer`) and ``sweep``
  (:mod:`arenabench.eval.sweep.execution`) map their tasks with it; a Dask cluster
  (``--scheduler``) goes through :func:`arenabench.cluster.cluster_map` instead;
- :func:`local_pool`: the same pool for a caller that maps several times on the same workers
  (``bench``: warm-up, then timed maps);
- :func:`local_executor`: a :class:`~concurrent.futures.ProcessPoolExecutor` for callers that
  submit work as it comes and read the futures (``eval``'s in-process pipelines, ``check``'s
  dataset check, ``grade``'s report writers); :func:`end_executor` ends one at a stop;
- :func:`spawn_context`: the start method of every worker, and of the child processes of
  isolated callables (:mod:`arenabench.eval.runs.isolated`).

Every worker is spawned (:data:`START_METHOD`), never forked: a fork of a process holding an
OpenGL context or threads can deadlock.

The rules of :func:`local_map` and :func:`local_pool`, stated here once:

- spawned workers (no fork of a process holding an OpenGL context or threads), started with
  SIGINT ignored (:func:`arenabench.interrupts.children_ignore_sigint`) and initialised with
  the llvmpipe threads their share of the cores allows and this process's pid
  (:func:`arenabench.workers.init_worker`, or an initializer with the same arguments);
- results come back in completion order, one task at a time (``chunksize=1``);
- before each task run here and after each result from a worker,
  :func:`arenabench.interrupts.checkpoint` raises a stop signal a library swallowed;
- a stop signal (:class:`arenabench.interrupts.Interrupted`), or the caller closing the
  iterator early, ends the pool within a bound (:func:`_end_pool`): its ``terminate()`` (which
  first stops the pool from replacing ended workers, lets idle workers leave on their
  sentinel and sends SIGTERM to the busy ones, which unwind their task), and what has not
  ended after :data:`arenabench.interrupts.WORKER_GRACE_S` gets SIGKILL;
- a task that raises: its exception is re-raised here once the pool has ended the same way
  (:func:`_end_pool`). A plain ``terminate()`` could wait forever: once in a full test run it
  waited 8 minutes joining an idle worker that never got its SIGTERM, blocked on the task
  queue's read lock that ``terminate()`` itself holds. Killing the workers *before*
  ``terminate()`` would not do either (an idle one may hold that lock);
- done: the pool is closed and joined, so the workers exit on their own (no signal to an idle
  worker);
- one worker, or at most one task: everything runs in this process, no pool.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.context
import multiprocessing.pool
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any

from arenabench.interrupts import (
    STOP_POLL_S,
    WORKER_GRACE_S,
    checkpoint,
    children_ignore_sigint,
    stop_workers,
)
from arenabench.workers import check_workers, init_worker, llvmpipe_threads

#: How every local worker process starts (:func:`spawn_context`).
START_METHOD = "spawn"


def spawn_context() -> multiprocessing.context.BaseContext:
    """The :mod:`multiprocessing` context of every local worker (:data:`START_METHOD`)."""
    return multiprocessing.get_context(START_METHOD)


@contextmanager
def local_pool(
    workers: int,
    *,
    initializer: Callable[..., None] = init_worker,
    initargs: tuple[Any, ...] | None = None,
) -> Iterator[multiprocessing.pool.Pool]:
    """A :class:`multiprocessing.pool.Pool` of ``workers`` spawned processes, for the body of
    a ``with`` block.

    The workers start with SIGINT ignored. Leaving the block normally closes the pool and
    joins it (the workers exit on their own); leaving it by an exception (a stop signal, a
    task's error) ends the pool within a bound (:func:`_end_pool`) and re-raises.

    Parameters
    ----------
    workers : int
        Processes, an integer >= 1.
    initializer : callable, keyword-only
        Each worker's initializer (default :func:`arenabench.workers.init_worker`).
    initargs : tuple, keyword-only
        Its arguments; default ``(llvmpipe threads for `workers`, this process's pid)``.

    Raises
    ------
    ValueError
        When ``workers`` is not an integer >= 1.
    """
    workers = check_workers(workers)
    if initargs is None:
        initargs = (llvmpipe_threads(workers), os.getpid())
    with children_ignore_sigint():
        pool = spawn_context().Pool(workers, initializer=initializer, initargs=initargs)
    with pool:
        try:
            yield pool
        except BaseException:  # a task failed, a stop signal, or the caller closed early
            _end_pool(pool)
            raise
        pool.close()
        pool.join()


def local_executor(
    workers: int,
    *,
    initializer: Callable[..., None] | None = None,
    initargs: tuple[Any, ...] = (),
) -> ProcessPoolExecutor:
    """A :class:`~concurrent.futures.ProcessPoolExecutor` of at most ``workers`` spawned
    processes, started as work is submitted. Its owner shuts it down (``with``, or
    :func:`end_executor` at a stop).

    Parameters
    ----------
    workers : int
        Most processes at once, an integer >= 1.
    initializer : callable or None, keyword-only
        Each worker's initializer (none by default).
    initargs : tuple, keyword-only
        Its arguments.

    Raises
    ------
    ValueError
        When ``workers`` is not an integer >= 1.
    """
    return ProcessPoolExecutor(max_workers=check_workers(workers), mp_context=spawn_context(),
                               initializer=initializer, initargs=initargs)


def end_executor(pool: ProcessPoolExecutor, *, grace_s: float = WORKER_GRACE_S) -> None:
    """End ``pool`` at a stop: its queued work is cancelled and its processes ended (SIGTERM
    unwinds a task, SIGKILL after ``grace_s``: :func:`arenabench.interrupts.stop_workers`)."""
    def current() -> dict[int, Any]:
        return dict(getattr(pool, "_processes", None) or {})

    seen = current()
    pool.shutdown(wait=False, cancel_futures=True)
    for _ in range(3):  # a worker the pool started while it was being shut down, too
        seen.update(current())
        stop_workers(grace_s=grace_s, processes=list(seen.values()))
        if current().keys() <= seen.keys():
            break


def local_map(
    func: Callable[[Any], Any],
    items: Iterable[Any],
    *,
    workers: int,
    initializer: Callable[[int | None, int | None], None] = init_worker,
) -> Iterator[Any]:
    """``func(item)`` for every item, in ``workers`` spawned processes, as they finish.

    Parameters
    ----------
    func : callable
        A module-level function (picklable by name).
    items : iterable
        Picklable task records (frozen dataclasses).
    workers : int, keyword-only
        Processes; 1 (or at most one item) runs every task in this process, in order.
    initializer : callable, keyword-only
        Each worker's initializer, called as ``initializer(lp_threads, parent_pid)``
        (default :func:`arenabench.workers.init_worker`).

    Yields
    ------
    object
        ``func``'s results, in completion order.

    Raises
    ------
    ValueError
        When ``workers`` is not an integer >= 1.
    """
    items = list(items)
    if check_workers(workers) == 1 or len(items) <= 1:
        for item in items:
            checkpoint()
            yield func(item)
        return
    with local_pool(workers, initializer=initializer) as pool:
        results = pool.imap_unordered(func, items, chunksize=1)
        while True:
            try:  # in steps, so that a stop signal is acted on at once (STOP_POLL_S)
                result = results.next(timeout=STOP_POLL_S)
            except multiprocessing.TimeoutError:
                continue
            except StopIteration:
                return
            checkpoint()
            yield result


def _end_pool(pool: Any, *, grace_s: float = WORKER_GRACE_S) -> None:
    """End ``pool`` and its workers within about ``2 * grace_s`` seconds.

    ``Pool.terminate()`` runs in a thread of its own: it waits for its workers without a
    timeout, and a busy worker unwinds its task first (a render holds a stop until it ends).
    Workers still running after ``grace_s`` get SIGKILL
    (:func:`arenabench.interrupts.stop_workers`), and the queue locks they held are released
    so that ``terminate()`` can finish (:func:`_free_queue_locks`). Killing workers before
    ``terminate()`` would not do: the pool's worker handler replaces a worker that ended while
    tasks are outstanding, and the replacement waits for a task holding the task queue's
    read lock, which ``terminate()`` then waits for.
    """
    ender = threading.Thread(target=pool.terminate, name="arenabench-pool-end", daemon=True)
    ender.start()
    ender.join(grace_s)
    if ender.is_alive():
        stop_workers(grace_s=0.0)
        _free_queue_locks(pool)
        ender.join(grace_s)


def _free_queue_locks(pool: Any) -> None:
    """Release the locks of ``pool``'s queues that its ended workers held.

    ``Pool.terminate()`` takes the task queue's read lock and the result queue's write lock,
    without a timeout. A worker holds the first while it waits for a task and the second
    while it sends a result; one ended meanwhile never releases it. Call only once every
    worker has ended (:func:`arenabench.interrupts.stop_workers`): a lock still held then
    has no live holder. Uses ``multiprocessing.pool.Pool`` internals (``_inqueue._rlock``,
    ``_outqueue._wlock``: CPython 3.8-3.13); without them, nothing is done.
    """
    if multiprocessing.active_children():  # a worker that outlived SIGKILL: leave its locks
        return
    for queue, name in ((getattr(pool, "_inqueue", None), "_rlock"),
                        (getattr(pool, "_outqueue", None), "_wlock")):
        lock = getattr(queue, name, None)
        if lock is None:
            continue
        lock.acquire(block=False)  # held by an ended worker (or terminate()), or now here
        try:
            lock.release()
        except ValueError:  # released meanwhile by terminate(): nothing to free
            pass
