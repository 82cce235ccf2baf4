"""SIGINT / SIGTERM as an exception or a flag, for commands that must stop cleanly.

A long command (``eval``, ``sweep``, ``generate``) wraps its work in :func:`catch_interrupts`:
the first SIGINT or SIGTERM is remembered (:class:`InterruptState`) and, by default, raised in
the main thread as :class:`Interrupted`; the command then stops its workers, writes what is
finished and returns :attr:`Interrupted.exit_code` (130 for SIGINT, 143 for SIGTERM, the shell
convention 128 + signal number). Further signals while it cleans up are recorded, not raised,
so cleanup is never cut short by a second Ctrl-C.

Example
-------
>>> from arenabench.interrupts import Interrupted, catch_interrupts
>>> def main() -> int:
...     with catch_interrupts():
...         try:
...             work()
...         except Interrupted as exc:
...             write_partial_results()
...             return exc.exit_code
...     return 0

Outside the main thread (where Python cannot install signal handlers) the context manager
does nothing and the state never fires.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

#: The signals handled.
SIGNALS: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM)


def exit_code_for(signum: int) -> int:
    """Exit status of a command stopped by ``signum`` (128 + signal number: 130, 143)."""
    return 128 + int(signum)


class Interrupted(Exception):
    """Raised in the main thread when SIGINT or SIGTERM arrives inside :func:`catch_interrupts`.

    Attributes
    ----------
    signum : int
        The signal received.
    exit_code : int
        ``128 + signum``.
    """

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        self.exit_code = exit_code_for(signum)
        super().__init__(f"interrupted by {signal.Signals(signum).name}")


@dataclass
class InterruptState:
    """What :func:`catch_interrupts` saw: the first signal, and an event set when it came."""

    signum: int | None = None
    event: threading.Event = field(default_factory=threading.Event)

    @property
    def interrupted(self) -> bool:
        """Whether a signal arrived."""
        return self.signum is not None

    @property
    def exit_code(self) -> int | None:
        """``128 + signum``, or ``None`` when no signal arrived."""
        return None if self.signum is None else exit_code_for(self.signum)


@contextmanager
def catch_interrupts(*, raise_exception: bool = True) -> Iterator[InterruptState]:
    """Handle SIGINT and SIGTERM inside the ``with`` block; restore the old handlers after.

    Parameters
    ----------
    raise_exception : bool, keyword-only
        Raise :class:`Interrupted` in the main thread at the first signal (default). With
        ``False`` only the state is set (poll ``state.event``).

    Yields
    ------
    InterruptState
    """
    state = InterruptState()
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(signum: int, frame: object) -> None:
        if state.signum is not None:
            return  # already stopping: never cut the cleanup short
        state.signum = signum
        state.event.set()
        if raise_exception:
            raise Interrupted(signum)

    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, handler)
    try:
        yield state
    finally:
        for s, old in previous.items():
            signal.signal(s, old)
