"""Run an ``arenabench`` command inside the test process, as a subprocess would see it.

A fresh interpreter costs about half a second of CPU per command (start-up and imports);
hundreds of tests only check what a command answers (exit status, a one-line error, the
files it writes), which the process adds nothing to. :func:`run_cli` calls the top-level
dispatcher :func:`arenabench.cli.main` with the file descriptors 1 and 2 captured (so the
output of the command's child processes is captured too, as with ``capture_output``) and
returns the same three fields as :func:`subprocess.run`.

It also checks that the command left no global state behind: signal handlers, the working
directory, the environment, the umask, live child processes. Tests whose point is the real
process (signals, closed pipes, hangs, the interpreter's exit status, an environment read at
import time) keep running ``python -m arenabench`` in a subprocess.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from arenabench.cli import main
from arenabench.glplatform import PROCESS_ENV

#: Variables set for the rest of the process, by design: the OpenGL platform is chosen once,
#: before the first ``import OpenGL`` (:data:`arenabench.glplatform.PROCESS_ENV`); OpenCV's
#: loader extends the library path at its first import.
PROCESS_WIDE_ENV = frozenset({*PROCESS_ENV, "LD_LIBRARY_PATH"})

_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGPIPE, signal.SIGCHLD)


@dataclass(frozen=True)
class CliResult:
    """What a command answered: the fields of :class:`subprocess.CompletedProcess` tests read."""

    args: tuple[str, ...]
    returncode: int
    stdout: str
    stderr: str


def _state() -> dict[str, object]:
    mask = os.umask(0o022)
    os.umask(mask)
    env = {k: v for k, v in os.environ.items() if k not in PROCESS_WIDE_ENV}
    return {"signals": {s: signal.getsignal(s) for s in _SIGNALS}, "cwd": os.getcwd(),
            "env": env, "umask": mask}


def run_cli(*argv: str, cwd: str | Path | None = None,
            env: Mapping[str, str | None] | None = None) -> CliResult:
    """``arenabench ARGV`` in this process, its output captured at the file descriptors.

    Parameters
    ----------
    *argv : str
        The command line after ``arenabench``.
    cwd : path, optional, keyword-only
        Working directory for the call (restored afterwards).
    env : mapping, optional, keyword-only
        Variables set for the call (``None``: unset), restored afterwards.

    Returns
    -------
    CliResult

    Raises
    ------
    AssertionError
        When the command left global state behind (signal handlers, working directory,
        environment, umask, live child processes).
    """
    old_cwd = os.getcwd()
    old_env = {k: os.environ.get(k) for k in (env or {})}
    for key, value in (env or {}).items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
    if cwd is not None:
        os.chdir(cwd)
    streams = sys.stdout, sys.stderr
    for stream in streams:
        stream.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile() as out_f, tempfile.TemporaryFile() as err_f:
        os.dup2(out_f.fileno(), 1)
        os.dup2(err_f.fileno(), 2)
        sys.stdout = open(1, "w", encoding="utf-8", closefd=False, buffering=1)
        sys.stderr = open(2, "w", encoding="utf-8", closefd=False, buffering=1)
        before = _state()
        try:
            code = _call(list(argv))
        finally:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.close()  # flushes; fds 1 and 2 stay open (closefd=False)
                except (OSError, ValueError):
                    pass
            sys.stdout, sys.stderr = streams
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            after = _state()
            os.chdir(old_cwd)
            for key, value in old_env.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value
        out_f.seek(0)
        err_f.seek(0)
        stdout = out_f.read().decode("utf-8", errors="replace")
        stderr = err_f.read().decode("utf-8", errors="replace")
    leaked = {k: (before[k], after[k]) for k in before if before[k] != after[k]}
    assert not leaked, f"arenabench {' '.join(argv)} left global state behind: {leaked}"
    children = multiprocessing.active_children()
    assert not children, f"arenabench {' '.join(argv)} left child processes: {children}"
    return CliResult(args=tuple(argv), returncode=code, stdout=stdout, stderr=stderr)


def env_changes(env: Mapping[str, str]) -> dict[str, str | None]:
    """The ``env`` argument of :func:`run_cli` that makes the environment exactly ``env`` (the
    ``env`` of :func:`subprocess.run`): its variables set, the others unset."""
    changes: dict[str, str | None] = {k: v for k, v in env.items() if os.environ.get(k) != v}
    changes.update({k: None for k in os.environ if k not in env})
    return changes


def _call(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:  # what the interpreter would make of it
        if exc.code is None:
            return 0
        if isinstance(exc.code, int):
            return exc.code
        print(exc.code, file=sys.stderr)
        return 1


__all__ = ["CliResult", "env_changes", "run_cli"]
