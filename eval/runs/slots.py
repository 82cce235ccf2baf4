"""At most N external runs at once, shared by the pipelines of one grade or evaluation.

``grade`` and ``eval --cmd`` with ``W >= 2`` workers run ``W + 1`` harness threads and one
:class:`RunSlots` of ``W`` (:func:`extra_thread`). A run holds a slot from the moment its
command starts (a cold launcher spawned, a warm run sent to its server) until its end is known
(the launcher has exited, the server has said the run ended). So no more than ``W`` commands run
at once, as before, and their latencies and timeouts mean what they meant; the extra thread
prepares the next image meanwhile (its pipeline, its private folder, the image's copy) and takes
the slot the moment a run ends, rather than after the run's worker has read the results and
prepared its next image (docs/warm-interpreter.md, "Run slots").

A thread waiting for a slot returns at once when its pipeline is stopped
(:meth:`CommandPipeline.stop` calls :meth:`RunSlots.wake`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable


class RunSlots:
    """``n`` slots for running commands.

    Parameters
    ----------
    n : int
        Commands that may run at once (>= 1).

    Raises
    ------
    ValueError
        ``n`` is not a positive integer.
    """

    def __init__(self, n: int) -> None:
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise ValueError(f"run slots must be a positive integer, got {n!r}")
        self.n = n
        self._cond = threading.Condition()
        self._free = n
        self._waiting = 0

    def take(self, stopped: Callable[[], bool]) -> bool:
        """Wait for a free slot and take it; ``False`` (nothing taken) once ``stopped()``."""
        with self._cond:
            while not stopped():
                if self._free:
                    self._free -= 1
                    return True
                self._waiting += 1
                try:
                    self._cond.wait()
                finally:
                    self._waiting -= 1
            return False

    def give(self) -> None:
        """Give a slot back (once per successful :meth:`take`)."""
        with self._cond:
            if self._free >= self.n:
                raise RuntimeError("a run slot was given back twice")
            self._free += 1
            self._cond.notify_all()

    def wake(self) -> None:
        """Wake every waiting thread (to see that its pipeline was stopped)."""
        with self._cond:
            self._cond.notify_all()

    @property
    def waiting(self) -> int:
        """Threads now waiting in :meth:`take` for a slot."""
        with self._cond:
            return self._waiting

    @property
    def free(self) -> int:
        """Slots free now."""
        with self._cond:
            return self._free


def extra_thread(slots: RunSlots | None, workers: int) -> int:
    """Threads to add to ``workers`` for runs under ``slots``: one where runs already go in
    parallel (``workers >= 2``); none for one worker, whose images keep starting in the
    dataset's order (a waiting thread could take the slot before the one with the earlier
    image)."""
    return int(slots is not None and workers >= 2)


def hold(slots: RunSlots | None, stopped: Callable[[], bool]) -> Held | None:
    """A run's slot before its command starts: a :class:`Held` (holding nothing without
    ``slots``), or ``None`` once ``stopped()`` (the run is not to start)."""
    if slots is not None and not slots.take(stopped):
        return None
    return Held(slots)


class Held:
    """One run's hold on a slot: given back once, by whichever side learns of the end first
    (the warm server's reader thread, or the run's own thread)."""

    __slots__ = ("_lock", "_slots")

    def __init__(self, slots: RunSlots | None) -> None:
        self._slots = slots
        self._lock = threading.Lock()

    def release(self) -> None:
        """Give the slot back, unless it was given back already."""
        with self._lock:
            slots, self._slots = self._slots, None
        if slots is not None:
            slots.give()
