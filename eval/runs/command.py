"""External pipelines (``--cmd``): each run contained, limited, cleaned up and categorised.

Interface (used by ``eval``, ``sweep`` and ``grade``)::

    CommandPipeline(template, *, settings=RunSettings(...), output="obstacles",
                    name="", base_dir=os.getcwd())
    pipeline.run(image_path) -> Prediction          # never raises for the command's failures
    pipeline.stop()                                 # kill running runs, refuse new ones
    pipeline.close()                                # end its warm servers (eval's end)

``settings`` (:class:`~arenabench.eval.runs.limits.RunSettings`) holds the limits
(``limits.timeout_s``, ``memory_bytes``, ``max_procs``, ``max_file_size``, ``max_output``),
the sandbox mode, the image's name and extra environment variables. Construction raises
``ValueError`` (one line) for a template that cannot be split, an executable that does not
exist, ``output`` not in :data:`~arenabench.eval.runs.predictions.OUTPUT_MODES`, or
``sandbox="bwrap"`` where bubblewrap is missing or does not work.

How one image runs
------------------
- A run directory ``$TMPDIR/arenabench-run-XXXX`` holds ``work/`` (the command's private
  directory: its cwd and ``HOME``, holding only a copy of the image named
  ``settings.image_name`` or ``image`` + the original extension) and ``tmp/`` (its
  ``TMPDIR``). ``{image}`` in the template is the copy; the dataset's path never appears in
  the command's arguments or environment. The run directory is removed afterwards.
- Environment: only ``PATH``, ``HOME``, ``LANG``/``LC_ALL`` (``C.UTF-8``), ``TMPDIR`` and
  ``settings.env``; under bubblewrap ``PATH`` is the executable's folder, then
  ``/usr/local/bin:/usr/bin:/bin`` (no host folder), and the command runs as PID 1 of its
  PID namespace (no process there shows bubblewrap's arguments).
- A launcher process (:mod:`arenabench.eval.runs.launcher`) owns the run: child subreaper, so no
  process the command starts outlives the run however it detaches; killed with its
  processes (and the run directory removed) when the harness dies, even by SIGKILL.
  stdout/stderr go through it and only their last ``max_output`` bytes are kept. The run
  ends when the command's main process exits (or at the timeout); then every remaining
  process of the run is killed.
- Sandbox (``settings.sandbox``: ``bwrap``, ``none`` or ``auto``) and limits (memory, file
  size, processes, the timeout): :mod:`arenabench.eval.runs.sandbox`.
- Outcome (:class:`~arenabench.eval.scoring.results.Prediction` status ``ok``,
  ``markers_not_found``, ``timeout``, ``limit``, ``crash`` or ``bad_output``): the run's files
  and output are read by :func:`arenabench.eval.runs.predictions.prediction_from_run`.
"""

from __future__ import annotations

import marshal
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from dataclasses import KW_ONLY, dataclass, field
from pathlib import Path

from arenabench.cmdtemplate import fill, placeholders
from arenabench.competition import OBSTACLES_FILE
from arenabench.eval.scoring.results import HarnessError, Prediction

from .launcher import BOX, BOX_DIRS
from .limits import RunLimits, RunSettings
from .predictions import OUTPUT_MODES, STARVED_RETRIES, prediction_from_run
from .remover import remove_later, wait_removed
from .sandbox import (
    SANDBOX_DIR,
    bwrap_argv,
    launch_limits,
    pids_cgroup_parent,
    resolve_sandbox,
    sandbox_path,
    visible_paths,
    warn_if_procs_unlimited,
)
from .slots import RunSlots, hold
from .stale import run_dir_prefix, sweep_stale_runs

#: The launcher script (standard library only; run with ``python -I -S``).
LAUNCHER = str(Path(__file__).with_name("launcher.py"))
#: Seconds the harness waits for a launcher beyond the command's own timeout.
LAUNCHER_GRACE_S = 30.0


def _decode(data: bytes) -> str:
    return data.decode("utf-8", errors="replace")


def _wait(proc: subprocess.Popen, timeout: float) -> int:
    """``proc.wait(timeout)`` without its polling sleeps (a pidfd is readable at exit)."""
    import select

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


@dataclass
class CommandPipeline:
    """An external command, run once per image the way competition scripts are graded.

    Parameters
    ----------
    template : str
        Command line, split with :func:`shlex.split` (no shell). In every argument
        ``{image}`` becomes the path of the image's private copy and ``{python}`` the running
        Python interpreter; substitution is per argument, so paths with spaces survive.
        Arguments naming an existing file or folder relative to ``base_dir`` are made
        absolute (their folders are the submission's, visible read-only in the sandbox).
    settings : RunSettings, keyword-only
        Limits (``settings.limits.timeout_s`` is the per-image timeout), sandbox mode,
        image name and extra environment.
    output : {"obstacles", "json"}, keyword-only
        Read ``obstacles.txt`` from the working directory, or the last JSON object line on
        stdout.
    name : str, keyword-only
        Name in reports (default: the template).
    base_dir : str, keyword-only
        Folder that relative paths in the template are relative to (default: the current
        directory when the pipeline is created).
    slots : RunSlots, optional, keyword-only
        Shared with the other pipelines of a grade or evaluation: a run waits for a free slot
        before its command starts and gives it back at its end (:mod:`.run_slots`). Default:
        no limit beyond the caller's threads.

    Raises
    ------
    ValueError
        One line naming the problem: bad template or ``output``, an executable that does not
        exist, ``sandbox="bwrap"`` without a working bubblewrap.

    Notes
    -----
    Exit status 0 means "answer written"; 3 means markers not found; any other non-zero
    exit is a ``crash`` (or ``limit``, see the module docstring).
    """

    template: str
    _: KW_ONLY
    settings: RunSettings = field(default_factory=RunSettings)
    output: str = "obstacles"
    name: str = ""
    base_dir: str = field(default_factory=os.getcwd)
    slots: RunSlots | None = field(default=None, repr=False, compare=False)
    in_process: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.settings, RunSettings):
            raise ValueError(f"settings must be a RunSettings, got {self.settings!r}")
        if self.output not in OUTPUT_MODES:
            raise ValueError(f"output must be one of {OUTPUT_MODES}, got {self.output!r}")
        try:
            self._argv = shlex.split(self.template)
        except ValueError as exc:
            raise ValueError(f"template cannot be split into arguments: {exc}") from None
        if not self._argv:
            raise ValueError(f"template must not be empty, got {self.template!r}")
        self.name = self.name or self.template
        self._executable = self._resolve_executable()
        self.sandbox = resolve_sandbox(self.settings.sandbox)
        self._cgroup = pids_cgroup_parent()
        sweep_stale_runs(cgroup_parent=self._cgroup)  # what SIGKILLed runs left, once
        warn_if_procs_unlimited(self._cgroup, max_procs=self.limits.max_procs)
        self._lock = threading.Lock()
        self._live: set[subprocess.Popen] = set()
        self._stopped = False
        from .warm_client import warm_target

        self._warm = warm_target(self._resolved_args()) if self.settings.warm else None

    @property
    def limits(self) -> RunLimits:
        """The run limits (``settings.limits``)."""
        return self.settings.limits

    def _resolve_executable(self) -> str | None:
        exe = self._argv[0]
        if "{" in exe:
            return None if "{python}" != exe else sys.executable
        if "/" in exe:
            path = Path(self.base_dir, exe)
            if not path.is_file() or not os.access(path, os.X_OK):
                why = "does not exist" if not path.exists() else "is not an executable file"
                raise ValueError(f"--cmd: executable {exe!r} {why} (relative to {self.base_dir})")
            return os.path.abspath(path)  # not resolved: a venv's python is a symlink
        found = shutil.which(exe)
        if found is None:
            raise ValueError(f"--cmd: executable {exe!r} not found on PATH")
        return found

    def _resolved_args(self) -> list[str]:
        out = []
        for arg in self._argv:
            if placeholders(arg):  # filled per run (argv)
                out.append(arg)
                continue
            arg = fill(arg, {})  # literal text: '{{' is a brace
            if arg and not arg.startswith("-") and not os.path.isabs(arg):
                candidate = Path(self.base_dir, arg)  # '' is an argument, never the folder
                try:
                    exists = candidate.exists()
                except OSError:  # e.g. longer than a file name may be: an argument, not a path
                    exists = False
                if exists:
                    arg = os.path.abspath(candidate)
            out.append(arg)
        return out

    def image_name(self, image_path: Path) -> str:
        """File name of the image's copy in the private directory."""
        return self.settings.image_name or "image" + Path(image_path).suffix

    def argv(self, image_path: Path, *, image_dir: str | None = None) -> list[str]:
        """The command's argument list for one image (without any sandbox prefix).

        ``{image}`` is ``image_dir`` (default: :data:`SANDBOX_DIR` under bubblewrap) joined
        with :meth:`image_name`.
        """
        if image_dir is None:
            image_dir = SANDBOX_DIR if self.sandbox == "bwrap" else str(Path(image_path).parent)
        image = os.path.join(image_dir, self.image_name(image_path))
        values = {"image": image, "python": sys.executable}
        # one pass per template argument (arenabench.cmdtemplate.fill): a value, or a path
        # resolved from a literal argument, is never searched for placeholders
        return [fill(t, values) if placeholders(t) else a
                for t, a in zip(self._argv, self._resolved_args(), strict=True)]

    def _visible_paths(self) -> list[str]:
        """Read-only folders of the sandbox besides /usr (:func:`.sandbox.visible_paths`)."""
        return visible_paths(self._executable, self._resolved_args(),
                             python=any("{python}" in a for a in self._argv))

    def _bwrap_argv(self, folder: str, image_path: Path) -> list[str]:
        """bubblewrap's arguments for a run (or a warm server) whose folders ``work``, ``tmp``
        and ``shm`` are in ``folder``."""
        work, tmp, shm = (os.path.join(folder, name) for name in BOX_DIRS)
        return bwrap_argv(work, tmp, shm, image_path, self._visible_paths())

    def fill_workdir(self, work: str, image_path: Path) -> str | None:
        """Fill a run's private working directory ``work`` (cold and warm runs alike): the files
        of ``settings.workdir_from``, if any, then the image's copy. Returns ``None``, or why
        it failed (one line)."""
        try:
            if self.settings.workdir_from:
                shutil.copytree(self.settings.workdir_from, work, symlinks=True,
                                dirs_exist_ok=True, ignore=shutil.ignore_patterns(
                                    "__pycache__", ".git", OBSTACLES_FILE))
        except (OSError, shutil.Error) as exc:
            return f"cannot copy {self.settings.workdir_from} into the run's folder: {exc}"
        try:
            shutil.copyfile(image_path, os.path.join(work, self.image_name(image_path)))
        except OSError as exc:
            return f"cannot copy the image: {exc}"
        return None

    def _env(self, home: str, tmp: str) -> dict[str, str]:
        """The command's whole environment (cold runs, warm servers and warm runs alike);
        under bubblewrap ``PATH`` names no host folder (:func:`.sandbox.sandbox_path`)."""
        env = {
            "PATH": (sandbox_path(self._executable) if self.sandbox == "bwrap"
                     else os.environ.get("PATH", os.defpath)),
            "HOME": home,
            "LANG": "C.UTF-8",
            "LC_ALL": "C.UTF-8",
            "TMPDIR": tmp,
        }
        env.update(self.settings.env)
        return env

    def stop(self) -> None:
        """Kill every running run (their launchers clean up) and make later runs return at
        once as ``crash`` with message ``interrupted``."""
        with self._lock:
            self._stopped = True
            live = list(self._live)
        for proc in live:
            try:
                proc.send_signal(signal.SIGTERM)
            except OSError:
                pass
        if self.slots is not None:
            self.slots.wake()
        if self._warm is not None:
            from .warm_client import stop_warm

            stop_warm(self)

    def close(self) -> None:
        """End the command's idle warm servers (a later run starts one again), once the
        folders of finished runs are removed."""
        wait_removed()
        if self._warm is not None:
            from .warm_client import close_warm

            close_warm(self)

    def run(self, image_path: Path) -> Prediction:
        """Run the command on one image in a fresh private directory (never raises for the
        command's own failures). A run that timed out starved (it waited for a CPU most of
        the time: :data:`.predictions.STARVED_SHARE`) is run again, up to
        :data:`.predictions.STARVED_RETRIES` times.

        Raises
        ------
        HarnessError
            When the harness cannot run the image (no space for the run's folder, the image
            cannot be copied, the launcher fails): the harness's failure, never scored.
        """
        pred = self._run_once(Path(image_path))
        for _ in range(STARVED_RETRIES):
            if not pred.starved or self._stopped:
                break
            pred = self._run_once(Path(image_path))
        return pred

    def _run_once(self, image_path: Path) -> Prediction:
        if self._stopped:
            return Prediction(status="crash", message="interrupted")
        if self._warm is not None:  # a Python script: through its warm server (warm_client)
            from .warm_client import run_warm

            warm = run_warm(self, self._warm, image_path)
            if warm is not None:
                return warm
        try:
            rundir = tempfile.mkdtemp(prefix=run_dir_prefix())  # names its owner: stale_runs
        except OSError as exc:
            raise HarnessError(f"cannot make a run's folder in {tempfile.gettempdir()}: "
                               f"{exc.strerror or exc}") from None
        try:
            return self._run_in(image_path, rundir)
        finally:
            remove_later(rundir)  # the worker goes on with its next image meanwhile

    def _run_in(self, image_path: Path, rundir: str) -> Prediction:
        work, tmp = os.path.join(rundir, "work"), os.path.join(rundir, "tmp")
        try:
            os.mkdir(work)
            os.mkdir(tmp)
        except OSError as exc:
            raise HarnessError(f"cannot make a run's folder in {rundir}: "
                               f"{exc.strerror or exc}") from None
        problem = self.fill_workdir(work, image_path)
        if problem:
            raise HarnessError(problem)
        lim = self.limits
        if self.sandbox == "bwrap":  # the launcher makes the run's box (a tmpfs) at rundir/box
            argv = self._bwrap_argv(os.path.join(rundir, BOX), image_path) + self.argv(image_path)
            env = self._env(SANDBOX_DIR, "/tmp")
            pids_max = lim.max_procs + 1  # bubblewrap's own process (the command is pid 1)
        else:
            argv = self.argv(image_path, image_dir=work)
            env = self._env(work, tmp)
            pids_max = lim.max_procs
        cfg = {
            "exe": argv[0] if self.sandbox == "bwrap" else (self._executable or argv[0]),
            "argv": argv, "env": env, "cwd": work, "rundir": rundir,
            **launch_limits(lim, cgroup_parent=self._cgroup, sandboxed=self.sandbox == "bwrap",
                            pids_max=pids_max),
            "box_bytes": lim.disk_bytes if self.sandbox == "bwrap" else None,
            "image_name": self.image_name(image_path),
            "parent_pid": os.getpid(),
        }  # fmt: skip
        cfg_path = os.path.join(rundir, "launch.bin")
        try:
            with open(cfg_path, "wb") as fh:
                marshal.dump(cfg, fh)
        except OSError as exc:
            raise HarnessError(f"cannot write {cfg_path}: {exc.strerror or exc}") from None
        slot = hold(self.slots, lambda: self._stopped)
        if slot is None:
            return Prediction(status="crash", message="interrupted")
        try:
            with self._lock:
                if self._stopped:
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
            launcher_hung = self._wait_launcher(proc)
        finally:
            slot.release()
        try:
            result = marshal.loads(Path(rundir, "result.bin").read_bytes())
        except (OSError, ValueError, EOFError, TypeError):
            if self._stopped:
                return Prediction(status="crash", message="interrupted")
            if launcher_hung:
                return Prediction(status="timeout", message=(
                    f"timed out after {lim.timeout_s:g} s; its launcher stopped answering and "
                    "was killed"), latency_ms=(lim.timeout_s + LAUNCHER_GRACE_S) * 1e3)
            try:
                log_text = _decode(Path(rundir, "launcher.log").read_bytes()[-4000:])
            except OSError:
                log_text = ""
            last = (log_text.strip().splitlines() or [""])[-1][:300]
            raise HarnessError(
                f"a run's launcher failed (status {proc.returncode}): {last}") from None
        out = _decode(Path(rundir, "stdout").read_bytes())
        err = _decode(Path(rundir, "stderr").read_bytes())
        return self._interpret(result, out, err, work)

    def _wait_launcher(self, proc: subprocess.Popen) -> bool:
        """Wait for a cold run's launcher; ``True`` when it outlived the timeout and its grace
        and was killed."""
        try:
            _wait(proc, self.limits.timeout_s + LAUNCHER_GRACE_S)
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

    def _interpret(self, result: dict, stdout: str, stderr: str, workdir: str) -> Prediction:
        """The run's :class:`Prediction` (:func:`.predictions.prediction_from_run`)."""
        return prediction_from_run(result, stdout, stderr, workdir, output=self.output,
                                   limits=self.limits, pids_cgroup=self._cgroup is not None)
