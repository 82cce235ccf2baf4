"""Stopping long commands cleanly on SIGINT (Ctrl-C) and SIGTERM.

In the command's process::

    with stop_on_signals() as stop:
        try:
            do_the_work()            # the first signal raises Interrupted here
        except Interrupted:
            pass                     # the work has unwound through its finally blocks
        write_what_finished()
    if stop.requested:
        print("interrupted: 37 of 200 images written; ...")
        return stop.exit_code        # 130 for SIGINT, 143 for SIGTERM

The first SIGINT or SIGTERM raises :class:`Interrupted` in the main thread, wherever it is
(waiting on a worker pool, rendering, running a subprocess), so the work unwinds through its
``finally`` blocks: pools are shut down, subprocesses killed, temporary files removed.
:class:`Interrupted` derives from ``BaseException``, so ``except Exception`` does not swallow
it. ``with stop.deferred():`` holds it back while a block runs and raises it when the block
ends. Libraries may swallow it all the same (trimesh wraps its imports, and some of its
computations, in ``except BaseException``; PyOpenGL turns it into ``ctypes.ArgumentError``;
Python drops an exception raised in a ``__del__``). So code that runs such libraries holds a
stop until it ends (:func:`deferred_stops`: a render, the import of pyrender), every work loop
calls :func:`checkpoint` between its units, which raises :class:`Interrupted` again once a
stop was asked, and :func:`arenabench.cli.run` turns a command that still returns 0 after a
stop signal into that signal's exit status. A second
signal does not cut the unwinding short: what finished is still written (partial reports
take a second or two; one line on stderr says so); a third exits at once with the same status
(the user insists). A signal ignored when the block is entered (``nohup``, a background job
of a non-interactive shell) stays ignored. Exit statuses follow the shell's convention for a
process ended by a signal: 128 + the signal number.

In worker processes (a ``multiprocessing`` pool's initializer): :func:`init_worker_process`
makes the worker die with its parent (even one killed with SIGKILL; Linux), ignore SIGINT
(Ctrl-C reaches the whole process group: the parent decides what happens) and, on SIGTERM,
unwind the task at hand when it runs inside :func:`worker_task`, then exit. In the parent,
workers started inside :func:`children_ignore_sigint` ignore SIGINT from their first
instruction, and :func:`stop_workers` ends every ``multiprocessing`` child: SIGTERM, then
SIGKILL after a grace period.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, wait
from concurrent.futures import TimeoutError as FutureTimeout
from contextlib import contextmanager
from typing import Any

#: Longest a main-thread wait goes without running Python code. The kernel delivers a
#: process's signal to any of its threads; when that is not the main thread, CPython only
#: sets a flag, and a main thread blocked on a lock (a future's result, ``wait``) runs the
#: handler when it next runs Python code: a stop landing there waited for the next result
#: (a hanging run: its whole timeout). The waits below wake this often to let it in.
STOP_POLL_S = 0.25

#: The signals that stop a command.
STOP_SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM)
#: The stop signal that exits at once, without writing what finished (the first unwinds,
#: the second is noted while the partial outputs are written).
INSIST_SIGNALS = 3
#: Seconds :func:`stop_workers` waits after SIGTERM before it sends SIGKILL.
WORKER_GRACE_S = 3.0

_PR_SET_PDEATHSIG = 1


def exit_code(signum: int) -> int:
    """The exit status of a command stopped by signal ``signum``: 128 + its number."""
    return 128 + int(signum)


def signal_name(signum: int) -> str:
    """``"SIGINT"`` for 2, and so on."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


class Interrupted(BaseException):
    """Raised in the main thread by the first stop signal.

    Attributes
    ----------
    signum : int
        The signal received.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(f"interrupted by {signal_name(signum)}")
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        """130 for SIGINT, 143 for SIGTERM."""
        return exit_code(self.signum)


class StopRequest:
    """What :func:`stop_on_signals` yields: whether, and by which signal, a stop was asked."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.count = 0
        self._raised = False
        self._deferring = 0

    @property
    def requested(self) -> bool:
        """Whether a stop signal arrived."""
        return self.signum is not None

    @property
    def exit_code(self) -> int | None:
        """130 (SIGINT) or 143 (SIGTERM) once a signal arrived, else None."""
        return None if self.signum is None else exit_code(self.signum)

    @property
    def signal_name(self) -> str | None:
        """``"SIGINT"`` or ``"SIGTERM"`` once a signal arrived, else None."""
        return None if self.signum is None else signal_name(self.signum)

    def check(self) -> None:
        """Raise :class:`Interrupted` if a stop was asked and not raised yet."""
        if self.signum is not None and not self._raised:
            self._raised = True
            raise Interrupted(self.signum)

    @contextmanager
    def deferred(self) -> Iterator[None]:
        """Hold a stop back while the block runs; raise :class:`Interrupted` when it ends."""
        self._deferring += 1
        try:
            yield
        finally:
            self._deferring -= 1
        if not self._deferring:
            self.check()

    def _handle(self, signum: int, frame) -> None:
        global _received
        self.count += 1
        if _received is None:
            _received = int(signum)
        if self.count >= INSIST_SIGNALS:  # the user insists: leave now
            os._exit(exit_code(self.signum or signum))
        if self.signum is not None:  # a second signal: finish writing what finished
            try:
                os.write(2, f"arenabench: {signal_name(signum)} again: writing what finished; "
                         "once more to leave at once\n".encode())
            except OSError:
                pass
            return
        self.signum = int(signum)
        if not self._deferring:
            self.check()


#: The :class:`StopRequest` of every :func:`stop_on_signals` block now entered (innermost last).
_ACTIVE: list[StopRequest] = []
#: The first stop signal a :func:`stop_on_signals` block received since :func:`forget_received`.
_received: int | None = None


def checkpoint() -> None:
    """Raise :class:`Interrupted` when the innermost :func:`stop_on_signals` block got a stop.

    Call it between a loop's units of work (an image, a render, a team). The handler already
    raised :class:`Interrupted` where the main thread was, but a library may have swallowed it
    (trimesh catches ``BaseException`` around imports and computations); raising it again
    here keeps a stop from being lost. No effect outside such a block, or inside a
    :meth:`StopRequest.deferred` block (the stop is raised when that block ends).
    """
    if _ACTIVE:
        stop = _ACTIVE[-1]
        if stop.signum is not None and not stop._deferring:
            stop._raised = True
            raise Interrupted(stop.signum)


@contextmanager
def deferred_stops() -> Iterator[None]:
    """:meth:`StopRequest.deferred` of the innermost :func:`stop_on_signals` block (no effect
    outside one, or outside the main thread).

    For code that a stop must not cut in two, when the caller has no :class:`StopRequest` at
    hand: a render (trimesh and PyOpenGL would swallow the stop or turn it into a crash) and
    the import of pyrender (trimesh's ``except BaseException`` around its optional imports
    would leave a module half-imported for the rest of the process).
    """
    if _ACTIVE and threading.current_thread() is threading.main_thread():
        with _ACTIVE[-1].deferred():
            yield
    else:
        yield


def received() -> int | None:
    """The first stop signal received inside a :func:`stop_on_signals` block since
    :func:`forget_received` (None: none)."""
    return _received


def forget_received() -> None:
    """Start a command afresh: :func:`received` is None until its next stop signal."""
    global _received
    _received = None


@contextmanager
def stop_on_signals(signals: tuple[int, ...] = STOP_SIGNALS) -> Iterator[StopRequest]:
    """Turn ``signals`` into :class:`Interrupted` (the first) and an immediate exit (the next).

    Must be entered in the main thread. The previous handlers are restored on exit.

    Parameters
    ----------
    signals : tuple of int
        Default SIGINT and SIGTERM.

    Yields
    ------
    StopRequest
    """
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError("stop_on_signals must be entered in the main thread")
    stop = StopRequest()
    previous = {}
    for sig in signals:
        old = signal.getsignal(sig)
        if old is signal.SIG_IGN:
            continue
        previous[sig] = old
        signal.signal(sig, stop._handle)
    _ACTIVE.append(stop)
    try:
        yield stop
    finally:
        _ACTIVE.remove(stop)
        for sig, old in previous.items():
            signal.signal(sig, old)


# ----------------------------------------------------------------------------- workers

_IN_WORKER = False
_IN_TASK = False


def _die_with_parent(parent_pid: int | None) -> None:
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no prctl
            pass
    if parent_pid is not None and os.getppid() != parent_pid:  # the parent is already gone
        os._exit(exit_code(signal.SIGTERM))


def _worker_sigterm(signum: int, frame) -> None:
    if _IN_TASK:
        raise Interrupted(signum)
    os._exit(exit_code(signum))


def init_worker_process(*, parent_pid: int | None = None) -> None:
    """Call first in a worker process's initializer.

    The worker gets SIGTERM when its parent dies (``PR_SET_PDEATHSIG`` on Linux, so even a
    parent killed with SIGKILL leaves no worker behind), ignores SIGINT, and on SIGTERM
    unwinds the task running inside :func:`worker_task` (killing its subprocesses, removing
    temporary files) and exits, or exits at once when idle.

    Parameters
    ----------
    parent_pid : int, optional, keyword-only
        The parent's pid (``os.getpid()`` in the parent): a worker whose parent died before
        this call exits at once.
    """
    global _IN_WORKER
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_sigterm)
    _IN_WORKER = True


@contextmanager
def worker_task() -> Iterator[None]:
    """Run one task of a worker set up by :func:`init_worker_process` (elsewhere: no effect).

    A SIGTERM during the task raises :class:`Interrupted` in it; once the task has unwound,
    the worker exits with status 143.
    """
    global _IN_TASK
    if not _IN_WORKER:
        yield
        return
    _IN_TASK = True
    try:
        yield
    except Interrupted as exc:
        os._exit(exc.exit_code)
    finally:
        _IN_TASK = False


@contextmanager
def children_ignore_sigint() -> Iterator[None]:
    """Start worker processes inside this block: they begin life ignoring SIGINT.

    A Ctrl-C reaches every process of the terminal's process group; a worker still importing
    its modules (before :func:`init_worker_process` runs) would print a KeyboardInterrupt
    traceback. An ignored signal stays ignored across ``exec``, so workers started here never
    see it. In this process SIGINT is ignored only while the block runs (milliseconds: the
    workers are started, not waited for). No effect outside the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


#: Seconds to wait, in all, for the children ended by SIGKILL to be reaped (a loaded machine
#: reaps late: a worker killed while it reads its imports from a busy disk).
KILLED_JOIN_S = 10.0


def stop_workers(*, grace_s: float = WORKER_GRACE_S,
                 processes: Sequence[multiprocessing.process.BaseProcess] | None = None) -> int:
    """End every live ``multiprocessing`` child of this process: SIGTERM, then SIGKILL.

    Parameters
    ----------
    grace_s : float, keyword-only
        Seconds to wait for the children to exit after SIGTERM.
    processes : sequence of multiprocessing.Process, optional, keyword-only
        End only these (one pool's workers) instead of every child.

    Returns
    -------
    int
        How many children were running.
    """
    children = (multiprocessing.active_children() if processes is None
                else [p for p in processes if p.is_alive()])
    for child in children:
        child.terminate()
    deadline = time.monotonic() + grace_s
    for child in children:
        child.join(max(0.0, deadline - time.monotonic()))
    killed = [child for child in children if child.is_alive()]
    for child in killed:
        child.kill()
    # SIGKILL cannot be refused, but a child in uninterruptible sleep (reading its imports
    # from a busy disk, say) dies only when it leaves it: wait for each, up to KILLED_JOIN_S
    # in all, sending SIGKILL again now and then
    deadline = time.monotonic() + KILLED_JOIN_S
    while killed and time.monotonic() < deadline:
        for child in killed:
            child.join(min(0.5, max(0.0, deadline - time.monotonic())))
        killed = [child for child in killed if child.is_alive()]
        for child in killed:
            child.kill()
    return len(children)


def result_of(future: Future) -> Any:
    """``future.result()``, waiting in steps of :data:`STOP_POLL_S` so that a stop signal is
    acted on at once wherever the kernel delivered it."""
    while True:
        try:
            return future.result(timeout=STOP_POLL_S)
        except FutureTimeout:
            continue


def as_done(futures: Iterable[Future]) -> Iterator[Future]:
    """The futures as they finish (like :func:`concurrent.futures.as_completed`), waiting in
    steps of :data:`STOP_POLL_S` so that a stop signal is acted on at once."""
    pending = set(futures)
    while pending:
        done, pending = wait(pending, timeout=STOP_POLL_S, return_when=FIRST_COMPLETED)
        yield from done


def first_done(pending: Iterable[Future]) -> set[Future]:
    """``wait(pending, return_when=FIRST_COMPLETED)``'s done set, waiting in steps of
    :data:`STOP_POLL_S` so that a stop signal is acted on at once."""
    pending = set(pending)
    while True:
        done, _ = wait(pending, timeout=STOP_POLL_S, return_when=FIRST_COMPLETED)
        if done or not pending:
            return done
