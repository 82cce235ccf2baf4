"""Cold runs: a launcher process per image (:mod:`.launcher`), a new interpreter for a Python
script (``--no-warm``, any other program, and a warm server's failure).

How one image runs:

- a run folder ``$TMPDIR/arenabench-run-<harness pid>-XXXX`` holds ``work/`` (the command's
  private directory: its cwd and ``HOME``, holding only a copy of the image) and ``tmp/``;
  under bubblewrap the launcher makes the run's box (a tmpfs of ``--max-disk``) at ``box/``;
- the run's :class:`~.proctools.LaunchConfig` is written once (``launch.bin``), the launcher
  started with ``python -I -S`` (posix_spawn: no fork of the harness), its end waited for
  (``--timeout`` plus :data:`~.proctools.RUN_GRACE_S`);
- its result, stdout and stderr are read, and the command's :class:`Command` says what they
  come to; the folder is handed to the context's remover.
"""

from __future__ import annotations

import marshal
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from arenabench.eval.scoring.results import HarnessError, Prediction

from .proctools import BOX, RUN_GRACE_S, RunRecord
from .sandbox import SANDBOX_DIR
from .slots import hold
from .stale import run_dir_prefix

if TYPE_CHECKING:
    from .command import RunJob, RunPlace

#: The launcher script (standard library only; run with ``python -I -S``).
LAUNCHER = str(Path(__file__).with_name("launcher.py"))


def _decode(data: bytes) -> str:
    return data.decode("utf-8", errors="replace")


def _wait(proc: subprocess.Popen, timeout: float) -> int:
    """``proc.wait(timeout)`` without its polling sleeps (a pidfd is readable at exit)."""
    try:
        fd = os.pidfd_open(proc.pid)
    except (AttributeError, OSError):  # old kernel, or already reaped
        return proc.wait(timeout=timeout)
    try:
        ready, _, _ = select.select([fd], [], [], timeout)
    finally:
        os.close(fd)
    if not ready:
        raise subprocess.TimeoutExpired(proc.args, timeout)
    return proc.wait()


class ColdRunner:
    """Runs a command on one image through a launcher of its own (a :class:`.command.Runner`;
    always answers). One per pipeline; the run slots and the folder remover are its
    context's."""

    def __init__(self, context: RunPlace) -> None:
        self.context = context
        self._lock = threading.Lock()
        self._live: set[subprocess.Popen] = set()

    def run(self, pipe: RunJob, image_path: Path) -> Prediction:
        """Run ``pipe``'s command on one image (never raises for the command's own failures).

        Raises
        ------
        HarnessError
            No run folder can be made or filled, the launcher cannot start or fails.
        """
        try:
            rundir = tempfile.mkdtemp(prefix=run_dir_prefix())  # names its owner: stale
        except OSError as exc:
            raise HarnessError(f"cannot make a run's folder in {tempfile.gettempdir()}: "
                               f"{exc.strerror or exc}") from None
        try:
            return self._run_in(pipe, Path(image_path), rundir)
        finally:
            self.context.remover.remove_later(rundir)  # the worker goes on meanwhile

    def _run_in(self, pipe: RunJob, image_path: Path, rundir: str) -> Prediction:
        command = pipe.command
        work, tmp = os.path.join(rundir, "work"), os.path.join(rundir, "tmp")
        try:
            os.mkdir(work)
            os.mkdir(tmp)
        except OSError as exc:
            raise HarnessError(f"cannot make a run's folder in {rundir}: "
                               f"{exc.strerror or exc}") from None
        problem = command.fill_workdir(work, image_path)
        if problem:
            raise HarnessError(problem)
        if command.sandboxed:  # the launcher makes the run's box (a tmpfs) at rundir/box
            argv = (command.bwrap_argv(os.path.join(rundir, BOX), image_path)
                    + command.argv_for(image_path))
            exe, env = argv[0], command.env(SANDBOX_DIR, "/tmp")
            extra = 1  # bubblewrap's own process (the command is pid 1)
        else:
            argv = command.argv_for(image_path, image_dir=work)
            exe, env, extra = command.executable or argv[0], command.env(work, tmp), 0
        cfg = command.launch_config(exe=exe, argv=argv, env=env, cwd=work, rundir=rundir,
                                    image_path=image_path,
                                    cgroup_parent=command.cgroup_parent, extra_procs=extra,
                                    parent_pid=os.getpid())
        cfg_path = os.path.join(rundir, "launch.bin")
        try:
            with open(cfg_path, "wb") as fh:
                marshal.dump(cfg.to_dict(), fh)
        except OSError as exc:
            raise HarnessError(f"cannot write {cfg_path}: {exc.strerror or exc}") from None
        slot = hold(self.context.slots, lambda: pipe.stopped)
        if slot is None:
            return Prediction(status="crash", message="interrupted")
        try:
            with self._lock:
                if pipe.stopped:
                    return Prediction(status="crash", message="interrupted")
                try:
                    with open(os.path.join(rundir, "launcher.log"), "wb") as log:
                        # close_fds=False lets Python use posix_spawn (no fork of the
                        # harness); its own descriptors are non-inheritable (PEP 446)
                        proc = subprocess.Popen(
                            [sys.executable, "-I", "-S", LAUNCHER, cfg_path],
                            stdin=subprocess.DEVNULL, stdout=log, stderr=log, close_fds=False,
                        )
                except OSError as exc:
                    raise HarnessError(f"cannot start a run's launcher: "
                                       f"{exc.strerror or exc}") from None
                self._live.add(proc)
            launcher_hung = self._wait_launcher(proc, command.limits.timeout_s)
        finally:
            slot.release()
        try:
            raw = marshal.loads(Path(rundir, "result.bin").read_bytes())
            result = RunRecord.from_dict(raw)
        except (OSError, ValueError, EOFError, TypeError):
            if pipe.stopped:
                return Prediction(status="crash", message="interrupted")
            if launcher_hung:
                timeout = command.limits.timeout_s
                return Prediction(status="timeout", message=(
                    f"timed out after {timeout:g} s; its launcher stopped answering and "
                    "was killed"), latency_ms=(timeout + RUN_GRACE_S) * 1e3)
            try:
                log_text = _decode(Path(rundir, "launcher.log").read_bytes()[-4000:])
            except OSError:
                log_text = ""
            last = (log_text.strip().splitlines() or [""])[-1][:300]
            raise HarnessError(
                f"a run's launcher failed (status {proc.returncode}): {last}") from None
        out = _decode(Path(rundir, "stdout").read_bytes())
        err = _decode(Path(rundir, "stderr").read_bytes())
        return command.interpret(result, out, err, work)

    def _wait_launcher(self, proc: subprocess.Popen, timeout_s: float) -> bool:
        """Wait for a run's launcher; ``True`` when it outlived the timeout and its grace and
        was killed."""
        try:
            _wait(proc, timeout_s + RUN_GRACE_S)
            return False
        except subprocess.TimeoutExpired:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            return True
        finally:
            with self._lock:
                self._live.discard(proc)

    def stop(self, pipe: RunJob) -> None:
        """SIGTERM every running launcher (each kills its run's processes and removes its
        folder)."""
        with self._lock:
            live = list(self._live)
        for proc in live:
            try:
                proc.send_signal(signal.SIGTERM)
            except OSError:
                pass
