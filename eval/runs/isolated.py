"""In-process pipelines named ``"pkg.module:function"``, each run in a child process that can be
killed and replaced.

A team's Python function is as untrusted as its ``map.py``: ``sys.exit(0)``, ``os._exit(0)``,
a ``KeyboardInterrupt`` or an endless loop inside it must fail that image only (``crash`` or
``timeout``), never end the harness or hang it. :class:`IsolatedCallablePipeline` keeps one
child process per worker thread (started with ``spawn``, SIGINT ignored, dying with this
process); the child imports the function once and calls it on each image it is sent. A child
that exits or overruns ``timeout_s`` is killed, the image is categorised, and the next image
gets a fresh child.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from arenabench.aruco import aruco_dictionary
from arenabench.eval.pipelines import CallablePipeline
from arenabench.eval.scoring.answers import not_a_mapping, short_repr
from arenabench.eval.scoring.results import Prediction
from arenabench.frame import COMPETITION_DICTIONARY, COMPETITION_MARKER_IDS, CORNER_ORDER
from arenabench.interrupts import children_ignore_sigint
from arenabench.limits import DEFAULT_TIMEOUT_S
from arenabench.local_pool import spawn_context
from arenabench.workers import init_worker

from . import proctools
from .sandbox import pids_cgroup_parent

#: Seconds a child may take to start and import the pipeline's module.
START_TIMEOUT_S = 120.0
#: The message that asks a child for its trial call (:func:`trial_call`).
TRIAL = ("trial",)
#: Side of the trial image in px, and of its markers.
TRIAL_SIDE_PX, TRIAL_MARKER_PX = 400, 64


def trial_image() -> Any:
    """A small synthetic arena (BGR uint8): a grey floor, the competition's four markers in
    its corners (NW, NE, SE, SW) with white quiet zones, and one dark box in the middle: what
    any pipeline can be called on."""
    import cv2
    import numpy as np

    side, m, pad = TRIAL_SIDE_PX, TRIAL_MARKER_PX, 8
    image = np.full((side, side, 3), 170, np.uint8)
    dictionary = aruco_dictionary(COMPETITION_DICTIONARY)
    far = side - m - 2 * pad
    corners = {"nw": (0, 0), "ne": (far, 0), "se": (far, far), "sw": (0, far)}
    for corner in CORNER_ORDER:
        x, y = corners[corner]
        marker = cv2.aruco.generateImageMarker(dictionary, COMPETITION_MARKER_IDS[corner], m)
        sheet = cv2.copyMakeBorder(marker, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
        image[y:y + m + 2 * pad, x:x + m + 2 * pad] = sheet[:, :, None]
    cv2.rectangle(image, (side // 2 - 30, side // 2 - 20), (side // 2 + 30, side // 2 + 20),
                  (40, 40, 40), -1)
    return image


def trial_call(func: Any) -> tuple[str, str]:
    """Call ``func`` on :func:`trial_image` (in an isolated child): ``("refused", why)`` when
    it cannot be a pipeline (it refuses an image with a ``TypeError``, or returns what no
    pipeline returns: :func:`~arenabench.eval.scoring.answers.not_a_mapping`), else
    ``("ok", "")`` (its other failures are scored per image)."""
    try:
        result = func(trial_image())
    except TypeError as exc:
        return "refused", f"cannot take an image (TypeError: {exc})"[:300]
    except BaseException:  # its own failure on this image: scored per image
        return "ok", ""
    if not_a_mapping(result):
        return "refused", (f"returned {type(result).__name__} {short_repr(result)} for an image, "
                           "not a result (a mapping, or an object with count and area "
                           "attributes)")
    return "ok", ""


def _serve(conn: Any, spec: str, parent_pid: int, cgroup_parent: str | None) -> None:
    """The child: import ``spec`` once, then answer each image path with a Prediction.

    It is a child subreaper, in a pids cgroup of its own where one can be made
    (:func:`_hold_descendants`): whatever process the function starts (``setsid``, a double
    fork) stays where :meth:`IsolatedCallablePipeline.close` finds and kills it."""
    init_worker(parent_pid=parent_pid)
    _hold_descendants(cgroup_parent)
    try:
        pipe = CallablePipeline(spec)
    except BaseException as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    conn.send(("ready", ""))
    while True:
        try:
            path = conn.recv()
        except (EOFError, OSError):
            return
        if path == TRIAL:
            conn.send(trial_call(pipe.func))
            continue
        start = time.perf_counter()
        try:
            pred = pipe.run(Path(path))
        except SystemExit as exc:  # sys.exit() inside the pipeline: that image fails
            pred = Prediction(status="crash", latency_ms=(time.perf_counter() - start) * 1e3,
                              message=f"the pipeline called sys.exit({exc.code!r})")
        except KeyboardInterrupt:
            pred = Prediction(status="crash", latency_ms=(time.perf_counter() - start) * 1e3,
                              message="the pipeline raised KeyboardInterrupt")
        conn.send(pred)


def _hold_descendants(cgroup_parent: str | None) -> None:
    """Make this process a child subreaper and, under ``cgroup_parent``, move it into a pids
    cgroup of its own (:func:`arenabench.eval.runs.proctools.cgroup_path` of its pid: named as a
    run's, so a later command's sweep removes it if this harness is killed)."""
    proctools.LIBC.prctl(proctools.PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
    if cgroup_parent:
        proctools.enter_cgroup(cgroup_parent)


def _end_tree(pid: int, cgroup_parent: str | None) -> None:
    """SIGKILL what child ``pid`` started (its descendants, and its cgroup's processes) and
    remove its cgroup; the child itself is ended by its caller."""
    for other in proctools.descendants(pid):
        try:
            os.kill(other, signal.SIGKILL)
        except OSError:
            pass
    if cgroup_parent:
        group = proctools.cgroup_path(cgroup_parent, pid)
        if os.path.isdir(group):
            for other in proctools.cgroup_pids(group):
                if other != pid:
                    try:
                        os.kill(other, signal.SIGKILL)
                    except OSError:
                        pass


def _remove_group(pid: int, cgroup_parent: str | None) -> None:
    if cgroup_parent:
        proctools.kill_cgroup_tree(proctools.cgroup_path(cgroup_parent, pid))


@dataclass(eq=False)
class _Child:
    process: Any
    conn: Any


@dataclass
class IsolatedCallablePipeline:
    """A ``"pkg.module:function"`` pipeline run in killable child processes.

    Parameters
    ----------
    spec : str
        ``"pkg.module:function"`` (checked here: it must import in this process too).
    timeout_s : float, keyword-only
        Seconds one image may take; then the child is killed and the image is ``timeout``.
    """

    spec: str
    timeout_s: float = DEFAULT_TIMEOUT_S
    #: Runs in child processes of its own (never in a process pool's workers).
    in_process: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        self.name = CallablePipeline(self.spec).name  # import errors: one line, now
        self._local = threading.local()
        self._lock = threading.Lock()
        self._children: set[_Child] = set()
        self._stopped = False
        self._cgroup = pids_cgroup_parent()
        self._spare: _Child | None = None  # the trial's child, for the first image

    def trial(self) -> str | None:
        """Call the function once on a small synthetic arena in a child (:func:`trial_call`)
        before any image: why it is no pipeline (one line), or ``None``. A child that cannot
        start, exits or overruns ``timeout_s`` proves nothing here (its images will say)."""
        try:
            child = self._start()
        except RuntimeError:
            return None
        try:
            child.conn.send(TRIAL)
            if not child.conn.poll(self.timeout_s):
                self._kill(child)
                return None
            kind, why = child.conn.recv()
        except (EOFError, OSError):
            self._kill(child)
            return None
        if kind != "ok":
            self._kill(child)
            return f"pipeline {self.spec!r}: {why}"
        self._spare = child
        return None

    def _start(self) -> _Child:
        ctx = spawn_context()
        ours, theirs = ctx.Pipe()
        with children_ignore_sigint():
            # not a daemon, so the function may start processes of its own; it dies with
            # this process (init_worker) and close() ends it
            process = ctx.Process(target=_serve,
                                  args=(theirs, self.spec, os.getpid(), self._cgroup),
                                  daemon=False, name=f"arenabench-pipeline {self.spec}")
            process.start()
        theirs.close()
        child = _Child(process, ours)
        with self._lock:
            self._children.add(child)
        if not ours.poll(START_TIMEOUT_S):
            self._kill(child)
            raise RuntimeError(f"pipeline {self.spec!r}: its process did not start in "
                               f"{START_TIMEOUT_S:g} s")
        try:
            kind, message = ours.recv()
        except (EOFError, OSError):
            kind, message = "error", f"its process exited ({process.exitcode})"
        if kind != "ready":
            self._kill(child)
            raise RuntimeError(f"pipeline {self.spec!r}: {message}")
        return child

    def _kill(self, child: _Child) -> None:
        with self._lock:
            self._children.discard(child)
        pid = child.process.pid
        if child.process.is_alive():
            _end_tree(pid, self._cgroup)  # what it started, while it still holds them
            child.process.kill()
        child.process.join(5)
        _end_tree(pid, self._cgroup)  # orphans of a child that ended by itself: its cgroup
        _remove_group(pid, self._cgroup)
        child.conn.close()
        if getattr(self._local, "child", None) is child:
            self._local.child = None

    def run(self, image_path: Path) -> Prediction:
        """Run the function on one image in this thread's child (started on first use)."""
        if self._stopped:
            return Prediction(status="crash", message="interrupted")
        child = getattr(self._local, "child", None)
        if child is None or not child.process.is_alive():
            with self._lock:
                spare, self._spare = self._spare, None
            if spare is not None and spare.process.is_alive():
                child = self._local.child = spare
        if child is None or not child.process.is_alive():
            try:
                child = self._local.child = self._start()
            except RuntimeError as exc:
                return Prediction(status="crash", message=str(exc)[:500])
        start = time.perf_counter()
        try:
            child.conn.send(str(image_path))
            if not child.conn.poll(self.timeout_s):
                self._kill(child)
                return Prediction(status="timeout", latency_ms=self.timeout_s * 1e3,
                                  message=f"timed out after {self.timeout_s:g} s (its process "
                                          "killed)")
            return child.conn.recv()
        except (EOFError, OSError, BrokenPipeError):
            child.process.join(5)
            code = child.process.exitcode
            self._kill(child)
            why = (f"killed by signal {-code}" if code is not None and code < 0
                   else f"exit status {code}")
            return Prediction(status="crash", latency_ms=(time.perf_counter() - start) * 1e3,
                              message=f"the pipeline ended its process ({why}; os._exit or a "
                                      "fatal error)")

    def threads(self, workers: int) -> int:
        """One thread (and child process) per worker."""
        return workers

    def stop(self) -> None:
        """Kill every child (an interrupted run)."""
        self._stopped = True
        with self._lock:
            children = list(self._children)
        for child in children:
            self._kill(child)

    def close(self) -> None:
        """End the children (the run is over)."""
        self.stop()


def trial_pipeline(spec: str, *, timeout_s: float) -> None:
    """Refuse a ``"pkg.module:function"`` that is no pipeline before any image
    (:meth:`IsolatedCallablePipeline.trial`, in a child that is then ended).

    Raises
    ------
    ValueError
        One line naming the spec and what the function did.
    """
    pipe = IsolatedCallablePipeline(spec, timeout_s=timeout_s)
    try:
        problem = pipe.trial()
    finally:
        pipe.close()
    if problem:
        raise ValueError(problem)
