"""Removing finished runs' private folders off the run path.

A worker that has read a run's results (``obstacles.txt``, stdout, stderr, the launcher's
result) hands the run's folder to :meth:`FolderRemover.remove_later` and goes on with its next
image; one thread of the remover removes the folders in the order they came. What it buys is
measured in docs/measurements.md ("Run folders removed off the run path").

Rules:

- one remover per :class:`~arenabench.eval.runs.context.RunContext` (so per evaluation, grade,
  check or sweep worker); it starts its thread on first use and stops it in :meth:`close`,
  which returns once every folder handed over is removed: nothing is left that a caller could
  see, and nothing outlives the context (a later folder starts the thread again);
- at most :data:`MAX_PENDING` folders wait; beyond that the caller removes its folder itself,
  so that the disk the waiting folders take stays bounded;
- in a process that :mod:`multiprocessing` started (the workers of ``sweep`` and of a Dask
  cluster, which may leave with ``os._exit``) the caller removes its folder itself;
- a folder that cannot be removed is left as ``shutil.rmtree(..., ignore_errors=True)`` leaves
  it: the next command's sweep (:mod:`.stale`) removes it once this process is gone.
"""

from __future__ import annotations

import multiprocessing
import shutil
import threading
from collections import deque

#: Folders that may wait for removal at once (beyond this a caller removes its own).
MAX_PENDING = 16


class FolderRemover:
    """Removes folders handed to it in a thread of its own (see the module docstring)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._queue: deque[str | None] = deque()
        self._busy = 0  # folders handed over and not yet removed (queued or being removed)
        self._thread: threading.Thread | None = None

    @property
    def pending(self) -> int:
        """Folders handed over and not yet removed."""
        with self._cond:
            return self._busy

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._queue:
                    self._cond.wait()
                path = self._queue.popleft()
            if path is None:  # close(): every folder before it is removed
                return
            try:
                shutil.rmtree(path, ignore_errors=True)
            finally:
                with self._cond:
                    self._busy -= 1
                    self._cond.notify_all()

    def remove_later(self, path: str) -> None:
        """Remove the folder ``path`` (and what it holds) soon, in the remover's thread; at
        once, in this thread, when :data:`MAX_PENDING` folders are already waiting
        or in a process that :mod:`multiprocessing` started."""
        with self._cond:
            if (self._busy < MAX_PENDING and multiprocessing.parent_process() is None
                    and self._running()):
                self._busy += 1
                self._queue.append(path)
                self._cond.notify_all()
                return
        shutil.rmtree(path, ignore_errors=True)

    def _running(self) -> bool:
        # the thread, started on first use (with the condition held); False when no thread
        # can start (the interpreter is shutting down): the caller then removes its folder
        if self._thread is None or not self._thread.is_alive():
            thread = threading.Thread(target=self._loop, name="arenabench-remover", daemon=True)
            try:
                thread.start()
            except RuntimeError:
                return False
            self._thread = thread
        return True

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until every folder handed over so far is removed; whether they all are
        (false only when ``timeout`` seconds passed first)."""
        with self._cond:
            return self._cond.wait_for(lambda: self._busy == 0, timeout)

    def close(self, timeout: float | None = None) -> bool:
        """Remove every folder handed over (waiting for them), then end the thread (a later
        folder starts it again). Whether every folder is removed."""
        done = self.wait(timeout)
        with self._cond:
            thread, self._thread = self._thread, None
            if thread is not None:
                self._queue.append(None)
                self._cond.notify_all()
        if thread is not None and done and thread is not threading.current_thread():
            thread.join(timeout)
        return done
