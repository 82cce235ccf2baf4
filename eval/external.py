"""External pipelines (``--cmd``): each run contained, limited, cleaned up and categorised.

Interface (used by ``eval``, ``sweep`` and ``grade``)::

    CommandPipeline(template, *, settings=RunSettings(...), output="obstacles",
                    name="", base_dir=os.getcwd())
    pipeline.run(image_path) -> Prediction          # never raises for the command's failures
    pipeline.stop()                                 # kill running runs, refuse new ones
    pipeline.close()                                # end its warm servers (eval's end)

``settings`` (:class:`~arenabench.eval.run_limits.RunSettings`) holds the limits
(``limits.timeout_s``, ``memory_bytes``, ``max_procs``, ``max_file_size``, ``max_output``),
the sandbox mode, the image's name and extra environment variables. Construction raises
``ValueError`` (one line) for a template that cannot be split, an executable that does not
exist, ``output`` not in :data:`OUTPUT_MODES`, or ``sandbox="bwrap"`` where bubblewrap is
missing or does not work.

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
- A launcher process (:mod:`arenabench.eval.launcher`) owns the run: child subreaper, so no
  process the command starts outlives the run however it detaches; killed with its
  processes (and the run directory removed) when the harness dies, even by SIGKILL.
  stdout/stderr go through it and only their last ``max_output`` bytes are kept. The run
  ends when the command's main process exits (or at the timeout); then every remaining
  process of the run is killed.
- Sandbox (``settings.sandbox``): ``bwrap`` runs the command under bubblewrap with new user,
  mount, PID, IPC, UTS and network namespaces (no network), ``--die-with-parent``, a fresh
  ``/dev`` and ``/proc``; visible read-only: ``/usr`` (and the ``/bin``, ``/lib*`` links),
  a few ``/etc`` files, what the command's executable needs (:mod:`.interpreter`: a venv
  with its base installation and the source folders of its ``.pth`` and editable installs,
  conda, pyenv, a ``#!`` script's interpreter; the running Python's only for ``{python}``),
  and the submission's own folder (the folders of files named in the command); read-write
  only the private directory (at :data:`SANDBOX_DIR`) and ``/tmp`` (the run's ``tmp/``).
  The dataset, its ground truth and the rest of the machine are not visible; a dataset
  inside a visible folder (its root found by ``manifest.jsonl`` / ``dataset.json``, whatever
  its images' folder is called) is hidden under an empty tmpfs. ``grade`` never uses
  ``auto``'s fallback: it fails closed (:mod:`.preflight`).
  ``none`` runs without namespaces (private directory, environment, limits and cleanup
  still apply; it is no security boundary: the command can read what the harness can);
  ``auto`` is ``bwrap`` when it works, else ``none`` with one warning line on stderr.
- Limits: ``RLIMIT_AS`` per process (memory), ``RLIMIT_FSIZE`` (file size), a pids cgroup
  per run when the cgroup file system is writable (else ``RLIMIT_NPROC``, which the kernel
  does not enforce for root) for the number of processes, the timeout.

Outcome (:class:`~arenabench.eval.records.Prediction` status)
------------------------------------------------------------
``timeout`` (message ``timed out after T s ...``); ``limit`` when the run failed after
hitting a limit, the message starting with which: ``memory limit (--memory-limit 2G) ...``,
``process limit (--max-procs 64) ...``, ``file size limit (--max-file-size 64M) ...``;
``crash`` (non-zero exit other than 3, or a signal); ``markers_not_found`` (exit 3);
``bad_output`` (no or unparseable ``obstacles.txt``, one larger than
:data:`OBSTACLES_MAX_BYTES` or not a regular file, no JSON line); else ``ok``.
"""

from __future__ import annotations

import marshal
import os
import shlex
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import threading
from dataclasses import KW_ONLY, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from arenabench.competition import (
    EXIT_MARKERS_NOT_FOUND,
    OBSTACLES_FILE,
    OutputFormatError,
    parse_obstacles_txt,
)

from .records import Prediction, tail
from .run_limits import RunLimits, RunSettings
from .stale_runs import run_dir_prefix, sweep_stale_runs

OUTPUT_MODES: tuple[str, ...] = ("obstacles", "json")
#: Largest ``obstacles.txt`` read; a larger one is ``bad_output``.
OBSTACLES_MAX_BYTES = 64 * 1024
#: Where the private directory appears inside the bubblewrap sandbox.
SANDBOX_DIR = "/sandbox"
#: The launcher script (standard library only; run with ``python -I -S``).
LAUNCHER = str(Path(__file__).with_name("launcher.py"))
#: Seconds the harness waits for a launcher beyond the command's own timeout.
LAUNCHER_GRACE_S = 30.0

_ETC_FILES = (
    "/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/localtime",
    "/etc/nsswitch.conf", "/etc/passwd", "/etc/group", "/etc/alternatives", "/etc/fonts",
    "/etc/mime.types", "/etc/matplotlibrc",
)  # fmt: skip
_MEMORY_SIGNS = ("MemoryError", "std::bad_alloc", "Cannot allocate memory", "out of memory",
                 "Out of memory", "failed to map segment", "cannot allocate")
_FSIZE_SIGNS = ("File too large",)
_NPROC_SIGNS = ("Resource temporarily unavailable", "BlockingIOError", "fork: retry")

_warned = threading.Lock()
_warned_once: list[str] = []


def _warn_once(message: str) -> None:
    with _warned:
        if message in _warned_once:
            return
        _warned_once.append(message)
    print(f"arenabench: WARNING: {message}", file=sys.stderr, flush=True)


@lru_cache(maxsize=1)
def bwrap_problem() -> str | None:
    """Why bubblewrap cannot be used here (``None`` when it works): missing, or failing to
    create the namespaces (e.g. user namespaces disabled)."""
    exe = shutil.which("bwrap")
    if exe is None:
        return "bubblewrap (bwrap) is not installed"
    true = shutil.which("true") or "/bin/true"
    argv = [exe, *_NAMESPACE_ARGS, "--ro-bind", "/", "/", "--proc", "/proc", "--dev", "/dev",
            "--", true]
    try:
        done = subprocess.run(argv, capture_output=True, timeout=20, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"bubblewrap does not work here: {exc}"
    if done.returncode != 0:
        why = done.stderr.decode(errors="replace").strip().splitlines()[-1:] or ["?"]
        return f"bubblewrap does not work here: {why[0]}"
    return None


_NAMESPACE_ARGS = (
    "--unshare-user", "--uid", "1000", "--gid", "1000", "--unshare-pid", "--unshare-net",
    "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try", "--die-with-parent",
    "--new-session", "--hostname", "sandbox",
)  # fmt: skip


def resolve_sandbox(mode: str) -> str:
    """The sandbox a run gets: ``"bwrap"`` or ``"none"``.

    ``auto`` falls back to ``none`` with one warning line on stderr when bubblewrap is
    missing or broken; ``bwrap`` then raises ``ValueError``.
    """
    if mode == "none":
        return "none"
    problem = bwrap_problem()
    if problem is None:
        return "bwrap"
    if mode == "bwrap":
        raise ValueError(f"--sandbox bwrap: {problem} (install the 'bubblewrap' package)")
    _warn_once(f"{problem}; external commands run WITHOUT a sandbox (they can read the "
               "dataset and the network). Install 'bubblewrap' or pass --sandbox none to "
               "silence this.")
    return "none"


_CGROUP_PROBE_LOCK = threading.Lock()
_CGROUP_PARENT: list[str | None] = []  # the probe's answer, once found


def pids_cgroup_parent() -> str | None:
    """A writable pids-cgroup folder where each run gets a child cgroup, or ``None``.

    Probed once per process, under a lock (grade calls it from many threads at once) and
    with a probe folder of a name no other thread or process uses.
    """
    with _CGROUP_PROBE_LOCK:
        if not _CGROUP_PARENT:
            _CGROUP_PARENT.append(_probe_pids_cgroup_parent())
        return _CGROUP_PARENT[0]


def _probe_pids_cgroup_parent() -> str | None:
    import uuid

    candidates = ["/sys/fs/cgroup/pids"]
    try:
        for line in Path("/proc/self/cgroup").read_text().splitlines():
            hid, _, rest = line.partition(":")
            controllers, _, path = rest.partition(":")
            if hid == "0" and controllers == "":
                root = Path("/sys/fs/cgroup", path.lstrip("/"))
                sub = root / "cgroup.subtree_control"
                if sub.is_file() and "pids" in sub.read_text().split():
                    candidates.append(str(root))
    except OSError:
        pass
    for parent in candidates:
        probe = os.path.join(parent, f"arenabench-probe-{os.getpid()}-{uuid.uuid4().hex}")
        try:
            os.mkdir(probe)
        except OSError:
            continue
        ok = os.path.exists(os.path.join(probe, "pids.max"))
        try:
            os.rmdir(probe)
        except OSError:
            ok = False
        if ok:
            return parent
    return None


def _format_size(n: int) -> str:
    for unit, size in (("G", 1024**3), ("M", 1024**2), ("k", 1024)):
        if n >= size and n % size == 0:
            return f"{n // size}{unit}"
    return str(n)


def _decode(data: bytes) -> str:
    return data.decode("utf-8", errors="replace")


def _read_small(path: Path, limit: int) -> bytes:
    """Read a regular file of at most ``limit`` bytes without following links or blocking.

    Raises
    ------
    OutputFormatError
        When it is not a regular file or is larger than ``limit``.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as exc:
        raise OutputFormatError(f"{OBSTACLES_FILE} cannot be read: {exc.strerror}") from None
    st = os.fstat(fd)  # before fdopen, which refuses a directory with IsADirectoryError
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise OutputFormatError(f"{OBSTACLES_FILE} is {kind}")
    with os.fdopen(fd, "rb") as fh:
        if st.st_size > limit:
            raise OutputFormatError(
                f"{OBSTACLES_FILE} is {st.st_size} bytes, more than the {limit} allowed"
            )
        return fh.read(limit + 1)[:limit]


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


def dataset_folders(image_dir: Path) -> list[Path]:
    """The folders from ``image_dir``'s parent up to the dataset root that holds it (the
    nearest one with ``manifest.jsonl`` or ``dataset.json``); empty when there is none."""
    for k, folder in enumerate(image_dir.parents):
        if (folder / "manifest.jsonl").exists() or (folder / "dataset.json").exists():
            return list(image_dir.parents)[: k + 1]
        if k >= 8:
            break
    return []


def _is_within(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip("/") + "/")


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
        if self._cgroup is None and os.getuid() == 0 and self.limits.max_procs:
            _warn_once("no writable pids cgroup and running as root: --max-procs cannot be "
                       "enforced for external commands")
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
            if arg and "{" not in arg and not arg.startswith("-") and not os.path.isabs(arg):
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
        return [a.replace("{image}", image).replace("{python}", sys.executable)
                for a in self._resolved_args()]

    def _visible_paths(self) -> list[str]:
        """Read-only folders of the sandbox besides /usr (outermost first, no duplicates):
        what the command's executable needs (:mod:`arenabench.eval.interpreter`: a venv with
        its base installation, conda, pyenv, a ``#!`` script's interpreter), the running
        Python's only when the command names ``{python}``, and the submission's own folders
        (those of files named in the command)."""
        from .interpreter import interpreter_folders, outermost

        paths: set[str] = set()
        if self._executable:
            paths.update(interpreter_folders(self._executable).folders)
        if any("{python}" in a for a in self._argv):
            paths.update(interpreter_folders(sys.executable).folders)
        roots = ("/", "/proc", "/dev", "/sys", "/tmp", "/run", "/var", "/home", "/root", "/mnt")
        for arg in self._resolved_args():
            if "{" in arg or not os.path.isabs(arg) or not os.path.exists(arg):
                continue
            real = os.path.realpath(arg)
            folder = real if os.path.isdir(real) else os.path.dirname(real)
            # a file directly in a top folder such as /tmp: only the file itself
            paths.add(real if folder in roots and real != folder else folder)
        return [p for p in outermost(paths) if p not in roots]

    def _bwrap_argv(self, work: str, tmp: str, image_path: Path) -> list[str]:
        args = ["bwrap", *_NAMESPACE_ARGS, "--ro-bind", "/usr", "/usr"]
        for top in ("/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32"):
            if os.path.islink(top):
                args += ["--symlink", os.readlink(top), top]
            elif os.path.isdir(top):
                args += ["--ro-bind", top, top]
        for f in _ETC_FILES:
            args += ["--ro-bind-try", f, f]
        # the private directory and /tmp first: a submission under /tmp is bound on top
        args += ["--bind", tmp, "/tmp", "--bind", work, SANDBOX_DIR]
        visible = self._visible_paths()
        for p in visible:
            args += ["--ro-bind", p, p]
        # a dataset inside a visible folder is hidden under an empty tmpfs: the image's
        # folder and every folder up to the dataset's root (manifest.jsonl / dataset.json)
        image_dir = Path(os.path.realpath(image_path)).parent
        hide = [image_dir, *dataset_folders(image_dir)]
        for d in hide:
            ds = str(d)
            if any(_is_within(ds, v) and ds != v for v in visible) and not any(
                _is_within(v, ds) for v in visible
            ):
                args += ["--tmpfs", ds]
        # --as-pid-1: the command is pid 1 of the sandbox's PID namespace, so no process there
        # (bubblewrap's own init before) shows this argument list, bind paths included, in
        # /proc/*/cmdline
        args += ["--proc", "/proc", "--dev", "/dev", "--remount-ro", "/", "--chdir", SANDBOX_DIR,
                 "--as-pid-1", "--"]
        return [shutil.which("bwrap") or "bwrap", *args[1:]]

    def _sandbox_path(self) -> str:
        """``PATH`` inside the sandbox: the executable's folder, then the system's (the
        harness's own ``PATH`` would name host folders in ``/proc/self/environ``)."""
        system = "/usr/local/bin:/usr/bin:/bin"
        if not self._executable:
            return system
        return f"{os.path.dirname(self._executable)}:{system}"

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
        under bubblewrap ``PATH`` names no host folder (:meth:`_sandbox_path`)."""
        env = {
            "PATH": (self._sandbox_path() if self.sandbox == "bwrap"
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
        if self._warm is not None:
            from .warm_client import stop_warm

            stop_warm(self)

    def close(self) -> None:
        """End the command's idle warm servers (a later run starts one again)."""
        if self._warm is not None:
            from .warm_client import close_warm

            close_warm(self)

    def run(self, image_path: Path) -> Prediction:
        """Run the command on one image in a fresh private directory (never raises for the
        command's own failures)."""
        if self._stopped:
            return Prediction(status="crash", message="interrupted")
        if self._warm is not None:  # a Python script: through its warm server (warm_client)
            from .warm_client import run_warm

            warm = run_warm(self, self._warm, Path(image_path))
            if warm is not None:
                return warm
        rundir = tempfile.mkdtemp(prefix=run_dir_prefix())  # names its owner: stale_runs
        try:
            return self._run_in(Path(image_path), rundir)
        finally:
            shutil.rmtree(rundir, ignore_errors=True)

    def _run_in(self, image_path: Path, rundir: str) -> Prediction:
        work, tmp = os.path.join(rundir, "work"), os.path.join(rundir, "tmp")
        os.mkdir(work)
        os.mkdir(tmp)
        problem = self.fill_workdir(work, image_path)
        if problem:
            return Prediction(status="crash", message=problem)
        lim = self.limits
        if self.sandbox == "bwrap":
            argv = self._bwrap_argv(work, tmp, image_path) + self.argv(image_path)
            env = self._env(SANDBOX_DIR, "/tmp")
            pids_max = lim.max_procs + 2  # bubblewrap's own two processes
        else:
            argv = self.argv(image_path, image_dir=work)
            env = self._env(work, tmp)
            pids_max = lim.max_procs
        cfg = {
            "exe": argv[0] if self.sandbox == "bwrap" else (self._executable or argv[0]),
            "argv": argv, "env": env, "cwd": work, "rundir": rundir,
            "timeout_s": lim.timeout_s, "memory_bytes": lim.memory_bytes,
            "max_file_size": lim.max_file_size, "max_output": lim.max_output,
            "max_procs": lim.max_procs, "pids_max": pids_max,
            "cgroup_parent": self._cgroup, "sandboxed": self.sandbox == "bwrap",
            "nproc_rlimit": self._cgroup is None and os.getuid() != 0,
            "parent_pid": os.getpid(),
        }  # fmt: skip
        cfg_path = os.path.join(rundir, "launch.bin")
        with open(cfg_path, "wb") as fh:
            marshal.dump(cfg, fh)
        with self._lock:
            if self._stopped:
                return Prediction(status="crash", message="interrupted")
            with open(os.path.join(rundir, "launcher.log"), "wb") as log:
                # close_fds=False lets Python use posix_spawn (no fork of the harness); the
                # harness's own descriptors are non-inheritable (PEP 446)
                proc = subprocess.Popen(
                    [sys.executable, "-I", "-S", LAUNCHER, cfg_path],
                    stdin=subprocess.DEVNULL, stdout=log, stderr=log, close_fds=False,
                )
            self._live.add(proc)
        launcher_hung = False
        try:
            try:
                _wait(proc, lim.timeout_s + LAUNCHER_GRACE_S)
            except subprocess.TimeoutExpired:
                launcher_hung = True
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        finally:
            with self._lock:
                self._live.discard(proc)
        try:
            result = marshal.loads(Path(rundir, "result.bin").read_bytes())
        except (OSError, ValueError, EOFError, TypeError):
            if self._stopped:
                return Prediction(status="crash", message="interrupted")
            if launcher_hung:
                return Prediction(status="timeout", message=(
                    f"timed out after {lim.timeout_s:g} s; its launcher stopped answering and "
                    "was killed"), latency_ms=(lim.timeout_s + LAUNCHER_GRACE_S) * 1e3)
            log_text = tail(_decode(Path(rundir, "launcher.log").read_bytes()[-4000:]))
            return Prediction(status="crash",
                              message=f"the launcher failed (status {proc.returncode})",
                              stderr=log_text)
        out = _decode(Path(rundir, "stdout").read_bytes())
        err = _decode(Path(rundir, "stderr").read_bytes())
        return self._interpret(result, out, err, work)

    def _limit_hit(self, result: dict, stderr: str) -> str | None:
        """Which limit a failed run hit, as the message's start (``None``: none)."""
        lim, rc = self.limits, result["rc"]
        last = stderr[-4000:]
        if result.get("pids_limit_hit") or (
            self._cgroup is None and lim.max_procs and any(s in last for s in _NPROC_SIGNS)
        ):
            return f"process limit (--max-procs {lim.max_procs}) reached"
        if rc in (-signal.SIGXFSZ, 128 + signal.SIGXFSZ) or any(s in last for s in _FSIZE_SIGNS):
            return f"file size limit (--max-file-size {_format_size(lim.max_file_size)}) reached"
        if any(s in last for s in _MEMORY_SIGNS):
            return f"memory limit (--memory-limit {_format_size(lim.memory_bytes)}) reached"
        return None

    def _interpret(self, result: dict, stdout: str, stderr: str, workdir: str) -> Prediction:
        from .pipelines import last_json_line, prediction_from_result

        rc, latency = result["rc"], float(result["latency_ms"])
        keep = {"stdout": tail(stdout), "stderr": tail(stderr), "latency_ms": latency}
        if result.get("error"):
            return Prediction(status="crash", message=result["error"][:500], **keep)
        failed = result["timed_out"] or rc not in (0, EXIT_MARKERS_NOT_FOUND)
        which = self._limit_hit(result, stderr)
        last = stderr.strip().splitlines()[-1:] or [""]
        if which and (failed or result.get("pids_limit_hit")):
            return Prediction(status="limit", message=f"{which}: {last[0][:300]}".rstrip(": "),
                              **keep)
        if result["timed_out"]:
            msg = f"timed out after {self.limits.timeout_s:g} s (all its processes killed)"
            return Prediction(status="timeout", message=msg, **keep)
        if rc not in (0, EXIT_MARKERS_NOT_FOUND):
            why = f"killed by signal {-rc}" if rc < 0 else f"exit status {rc}"
            return Prediction(
                status="crash", message=f"{why}: {last[0][:300]}".rstrip(": "), **keep
            )
        try:
            if self.output == "json":
                parsed_json: Any = last_json_line(stdout)
                if rc == EXIT_MARKERS_NOT_FOUND and isinstance(parsed_json, dict):
                    parsed_json.setdefault("status", "markers_not_found")
                pred = prediction_from_result(parsed_json, latency_ms=latency, stdout=stdout)
                return Prediction(**{**pred.__dict__, "stderr": tail(stderr)})
            path = Path(workdir) / OBSTACLES_FILE
            if not os.path.lexists(path):
                if rc == EXIT_MARKERS_NOT_FOUND:
                    return Prediction(status="markers_not_found", message="exit status 3", **keep)
                return Prediction(
                    status="bad_output",
                    message=f"{OBSTACLES_FILE} was not written to the working directory",
                    **keep,
                )
            text = _read_small(path, OBSTACLES_MAX_BYTES).decode("utf-8", errors="replace")
            parsed = parse_obstacles_txt(text)
        except OutputFormatError as exc:
            if rc == EXIT_MARKERS_NOT_FOUND:
                return Prediction(status="markers_not_found", message=str(exc), **keep)
            return Prediction(status="bad_output", message=str(exc)[:500], **keep)
        return Prediction(
            status="markers_not_found" if rc == EXIT_MARKERS_NOT_FOUND else "ok",
            count=parsed.count,
            area=parsed.area,
            marker_ids=tuple(parsed.marker_ids),
            message="exit status 3: markers not found" if rc == EXIT_MARKERS_NOT_FOUND else "",
            **keep,
        )
