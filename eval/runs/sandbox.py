"""Containing an external command's run: bubblewrap, the pids cgroup, the resource limits.

Used by :class:`~arenabench.eval.runs.pipeline.CommandPipeline` (cold runs) and
:mod:`arenabench.eval.runs.warm_client` (warm servers and their runs); it starts no command itself.

Sandbox (``RunSettings.sandbox``)
---------------------------------
``bwrap`` runs the command under bubblewrap with new user, mount, PID, IPC, UTS and network
namespaces (no network), ``--die-with-parent``, a fresh ``/dev`` and ``/proc``, the command as
PID 1 of its PID namespace (no process there shows bubblewrap's arguments); visible read-only:
``/usr`` (and the ``/bin``, ``/lib*`` links), a few ``/etc`` files, what the command's
executable needs (:mod:`.interpreter`: a venv with its base installation and the source
folders of its ``.pth`` and editable installs, conda, pyenv, a ``#!`` script's interpreter;
the running Python's only for ``{python}``), and the submission's own folder (the folders of
files named in the command); read-write only the private directory (at :data:`SANDBOX_DIR`)
and ``/tmp`` (the run's ``tmp/``). The dataset, its ground truth and the rest of the machine
are not visible; a dataset inside a visible folder (its root found by ``manifest.jsonl`` /
``dataset.json``, whatever its images' folder is called) is hidden under an empty tmpfs.
``grade`` never uses ``auto``'s fallback: it fails closed (:mod:`.preflight`).
``none`` runs without namespaces (private directory, environment, limits and cleanup still
apply; it is no security boundary: the command can read what the harness can); ``auto`` is
``bwrap`` when it works, else ``none`` with one warning line on stderr.

Limits
------
``RLIMIT_AS`` per process (memory), ``RLIMIT_FSIZE`` (file size), a pids cgroup per run when
the cgroup file system is writable (else ``RLIMIT_NPROC``, which the kernel does not enforce
for root) for the number of processes, the timeout. The launcher
(:mod:`arenabench.eval.runs.launcher`, standard library only) applies them from the fields
:class:`~.proctools.LaunchConfig` carries.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
from functools import cache, lru_cache
from pathlib import Path

#: Where the private directory appears inside the bubblewrap sandbox.
SANDBOX_DIR = "/sandbox"
#: ``PATH``'s system part inside the sandbox.
SYSTEM_PATH = "/usr/local/bin:/usr/bin:/bin"

_ETC_FILES = (
    "/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/localtime",
    "/etc/nsswitch.conf", "/etc/passwd", "/etc/group", "/etc/alternatives", "/etc/fonts",
    "/etc/mime.types", "/etc/matplotlibrc",
)  # fmt: skip
_NAMESPACE_ARGS = (
    "--unshare-user", "--uid", "1000", "--gid", "1000", "--unshare-pid", "--unshare-net",
    "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try", "--die-with-parent",
    "--new-session", "--hostname", "sandbox",
)  # fmt: skip
#: Top folders never bound as a whole (a file directly in one is bound alone).
_TOP_FOLDERS = ("/", "/proc", "/dev", "/sys", "/tmp", "/run", "/var", "/home", "/root", "/mnt")

_WARNING_LOCK = threading.Lock()


@cache
def _warn(message: str) -> None:
    print(f"arenabench: WARNING: {message}", file=sys.stderr, flush=True)


def warn_once(message: str) -> None:
    """Print ``arenabench: WARNING: message`` on stderr, once per process."""
    with _WARNING_LOCK:
        _warn(message)


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
    warn_once(f"{problem}; external commands run WITHOUT a sandbox (they can read the "
              "dataset and the network). Install 'bubblewrap' or pass --sandbox none to "
              "silence this.")
    return "none"


_CGROUP_PROBE_LOCK = threading.Lock()


def pids_cgroup_parent() -> str | None:
    """A writable pids-cgroup folder where each run gets a child cgroup, or ``None``.

    Probed once per process, under a lock (grade calls it from many threads at once) and
    with a probe folder of a name no other thread or process uses.
    """
    with _CGROUP_PROBE_LOCK:
        return _probe_pids_cgroup_parent()


def forget_probes() -> None:
    """Forget what this process found out once (bubblewrap, the pids cgroup parent, the
    warnings printed), so that the next call looks again: for tests that change the
    machine's state (``PATH``) under a running process."""
    with _CGROUP_PROBE_LOCK, _WARNING_LOCK:
        bwrap_problem.cache_clear()
        _probe_pids_cgroup_parent.cache_clear()
        _warn.cache_clear()


@lru_cache(maxsize=1)
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


def warn_if_procs_unlimited(cgroup: str | None, *, max_procs: int) -> None:
    """Warn once when a process limit (``max_procs`` > 0) cannot be enforced: no pids cgroup,
    and root (whom ``RLIMIT_NPROC`` does not bind)."""
    if cgroup is None and os.getuid() == 0 and max_procs:
        warn_once("no writable pids cgroup and running as root: --max-procs cannot be "
                  "enforced for external commands")


def dataset_folders(image_dir: Path) -> list[Path]:
    """The folders from ``image_dir``'s parent up to the dataset root that holds it (the
    nearest one with ``manifest.jsonl`` or ``dataset.json``); empty when there is none."""
    for k, folder in enumerate(image_dir.parents):
        if (folder / "manifest.jsonl").exists() or (folder / "dataset.json").exists():
            return list(image_dir.parents)[: k + 1]
        if k >= 8:
            break
    return []


def is_within(path: str, root: str) -> bool:
    """Whether ``path`` is ``root`` or inside it (both absolute, normalised)."""
    return path == root or path.startswith(root.rstrip("/") + "/")


def visible_paths(executable: str | None, args: list[str], *, python: bool) -> list[str]:
    """Read-only folders of the sandbox besides /usr (outermost first, no duplicates).

    Parameters
    ----------
    executable : str or None
        The command's executable: what it needs is visible (:mod:`arenabench.eval.runs.interpreter`:
        a venv with its base installation, conda, pyenv, a ``#!`` script's interpreter).
    args : list of str
        The command's arguments, relative paths made absolute: the folders of the files
        named (the submission's own) are visible.
    python : bool, keyword-only
        Whether the command names ``{python}`` (then the running Python's folders are visible).
    """
    from .interpreter import interpreter_folders, outermost

    paths: set[str] = set()
    if executable:
        paths.update(interpreter_folders(executable).folders)
    if python:
        paths.update(interpreter_folders(sys.executable).folders)
    for arg in args:
        # a path that exists, as written (a template's placeholders are relative:
        # '{image}', or absent from the disk; a team folder may be named 'x{image}y')
        if not os.path.isabs(arg) or not os.path.exists(arg):
            continue
        real = os.path.realpath(arg)
        folder = real if os.path.isdir(real) else os.path.dirname(real)
        # a file directly in a top folder such as /tmp: only the file itself
        paths.add(real if folder in _TOP_FOLDERS and real != folder else folder)
    return [p for p in outermost(paths) if p not in _TOP_FOLDERS]


def bwrap_argv(work: str, tmp: str, shm: str, image_path: Path, visible: list[str]) -> list[str]:
    """The bubblewrap prefix of one run's command line.

    Parameters
    ----------
    work, tmp, shm : str
        The run's private directory (bound at :data:`SANDBOX_DIR`, the command's cwd), its
        ``/tmp`` and its ``/dev/shm`` (the rest of ``/dev`` is read-only): the folders of its
        box (:func:`arenabench.eval.runs.proctools.mount_box`), the only places it can write.
    image_path : Path
        The dataset image: its folder and every folder up to the dataset's root are hidden
        under an empty tmpfs where they lie inside a visible folder.
    visible : list of str
        The read-only folders (:func:`visible_paths`).
    """
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
    for p in visible:
        args += ["--ro-bind", p, p]
    # a dataset inside a visible folder is hidden under an empty tmpfs: the image's
    # folder and every folder up to the dataset's root (manifest.jsonl / dataset.json)
    image_dir = Path(os.path.realpath(image_path)).parent
    hide = [image_dir, *dataset_folders(image_dir)]
    for d in hide:
        ds = str(d)
        if any(is_within(ds, v) and ds != v for v in visible) and not any(
            is_within(v, ds) for v in visible
        ):
            args += ["--tmpfs", ds]
    # --as-pid-1: the command is pid 1 of the sandbox's PID namespace, so no process there
    # (bubblewrap's own init before) shows this argument list, bind paths included, in
    # /proc/*/cmdline
    args += ["--proc", "/proc", "--dev", "/dev", "--bind", shm, "/dev/shm",
             "--remount-ro", "/dev", "--remount-ro", "/", "--chdir", SANDBOX_DIR,
             "--as-pid-1", "--"]
    return [shutil.which("bwrap") or "bwrap", *args[1:]]


def sandbox_path(executable: str | None) -> str:
    """``PATH`` inside the sandbox: the executable's folder, then the system's (the harness's
    own ``PATH`` would name host folders in ``/proc/self/environ``)."""
    if not executable:
        return SYSTEM_PATH
    return f"{os.path.dirname(executable)}:{SYSTEM_PATH}"
