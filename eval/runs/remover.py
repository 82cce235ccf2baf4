"""Removing finished runs' private folders off the run path.

A worker that has read a run's results (``obstacles.txt``, stdout, stderr, the launcher's
result) hands the run's folder to :func:`remove_later` and goes on with its next image; one
daemon thread removes the folders in the order they came. Measured in a warm grade (6 teams x
200 images, 2 workers on 2 cores), removing a folder inline took 1.6 ms median and 3.2 ms mean
of a worker's time, mostly waiting for a core or the GIL, not working (0.6 ms of CPU), and
that worker had no run going meanwhile (docs/warm-interpreter.md, "Run folders removed off the
run path").

Rules:

- at most :data:`MAX_PENDING` folders wait; beyond that the caller removes its folder itself,
  so that the disk a run may fill (``--max-file-size``, per file) stays bounded;
- in a process that :mod:`multiprocessing` started (the workers of ``sweep``, of ``eval
  --executor process``, of a Dask cluster) the caller removes its folder itself: such a
  worker leaves with ``os._exit``, which runs no exit hook;
- :func:`wait_removed` returns when every folder handed over so far is gone;
  :meth:`CommandPipeline.close` (so ``evaluate``), ``grade``'s runs and
  :func:`.warm_client.close_all` call it before they return, and it runs at interpreter exit,
  so nothing is left behind that a caller could see;
- a folder that cannot be removed is left as ``shutil.rmtree(..., ignore_errors=True)``
  leaves it: the next command's sweep (:mod:`.stale_runs`) removes it once this process is
  gone.
"""

from __future__ import annotations

import atexit
import multiprocessing
import os
import shutil
import threading
from collections import deque

#: Folders that may wait for removal at once (beyond this a caller removes its own).
MAX_PENDING = 16

_cond = threading.Condition()
_queue: deque[str] = deque()
_busy = 0  # folders handed over and not yet removed (queued or being removed)
_thread: threading.Thread | None = None


def _remover() -> None:
    global _busy
    while True:
        with _cond:
            while not _queue:
                _cond.wait()
            path = _queue.popleft()
        try:
            shutil.rmtree(path, ignore_errors=True)
        finally:
            with _cond:
                _busy -= 1
                _cond.notify_all()


def remove_later(path: str) -> None:
    """Remove the folder ``path`` (and what it holds) soon, in the remover thread; at once, in
    this thread, when :data:`MAX_PENDING` folders are already waiting or in a process that
    :mod:`multiprocessing` started."""
    global _busy
    with _cond:
        if _busy < MAX_PENDING and multiprocessing.parent_process() is None and _running():
            _busy += 1
            _queue.append(path)
            _cond.notify_all()
            return
    shutil.rmtree(path, ignore_errors=True)


def _running() -> bool:
    # the remover thread, started on first use (with _cond held); False when no thread can
    # start (the interpreter is shutting down): the caller then removes its folder itself
    global _thread
    if _thread is None or not _thread.is_alive():
        thread = threading.Thread(target=_remover, name="arenabench-remover", daemon=True)
        try:
            thread.start()
        except RuntimeError:
            return False
        _thread = thread
    return True


def wait_removed(timeout: float | None = None) -> bool:
    """Wait until every folder handed to :func:`remove_later` so far is removed; returns
    whether they all are (false only when ``timeout`` seconds passed first)."""
    with _cond:
        return _cond.wait_for(lambda: _busy == 0, timeout)


def _after_fork_in_child() -> None:
    # a forked child removes none of its parent's folders, and holds none of its locks
    global _cond, _queue, _busy, _thread
    _cond, _queue, _busy, _thread = threading.Condition(), deque(), 0, None


os.register_at_fork(after_in_child=_after_fork_in_child)
atexit.register(wait_removed, 30.0)
