"""Sweeping what killed runs of external commands left behind.

A run's private directory is ``$TMPDIR/arenabench-run-<harness pid>-XXXX`` and its pids cgroup
``<parent>/arenabench-run-<launcher pid>``; a warm server's folder is
``$TMPDIR/arenabench-warm-XXXX``, a random name with the harness's pid in its file ``owner``
(a warm run's mount table shows the folder's path: nothing in it counts servers or names a
process, :func:`make_warm_dir`) and its cgroup
``<parent>/arenabench-warm-<harness pid>-<random hex>`` (its runs' cgroups inside it; a warm
run's cgroup namespace hides it); the preflight's,
the phase check's and a sweep worker's folders are ``$TMPDIR/<prefix><owner pid>-XXXX``
(:data:`OWNED_PREFIXES`); all are removed when the run, the server or the step ends. When the whole
process group is killed with SIGKILL (harness and launchers together) nothing is left to
remove them, so the next run that starts external commands removes those whose owner process
is gone (:func:`sweep_stale_runs`, once per process; a cgroup with the processes and cgroups
left in it). A folder whose pid is alive is never
touched (even if the pid was reused: then it stays until the next sweep).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import threading
import time
from pathlib import Path

#: Name prefix of run directories and run cgroups.
RUN_PREFIX = "arenabench-run-"
#: Name prefix of warm servers' folders and cgroups (:mod:`arenabench.eval.runs.warm_client`).
WARM_PREFIX = "arenabench-warm-"
#: Name prefixes of the other temporary folders a command owns while it runs untrusted code
#: (the preflight's submissions, the phase check's images, a sweep worker's runs).
OWNED_PREFIXES = ("arenabench-preflight-", "arenabench-phase-", "arenabench-sweep-")

#: The file of a warm server's folder that holds its owner's pid.
OWNER_FILE = "owner"
#: Seconds a warm server's folder may lack its ``owner`` file (its harness was killed between
#: making it and writing the file) before a sweep takes it for a stale one.
OWNERLESS_GRACE_S = 60.0

# (a warm folder of an earlier version named its owner: arenabench-warm-<pid>-XXXX; today's
# random names hold no "-" after the prefix)
_RUN_DIR = re.compile("^(?:" + "|".join(map(re.escape, (RUN_PREFIX, WARM_PREFIX,
                                                          *OWNED_PREFIXES))) + r")(\d+)-")
_WARM_DIR = re.compile(rf"^{WARM_PREFIX}[A-Za-z0-9_]+$")
_RUN_CGROUP = re.compile(rf"^(?:{RUN_PREFIX}(\d+)|{WARM_PREFIX}(\d+)-[0-9a-f]+)$")
_SWEPT = threading.Event()
_LOCK = threading.Lock()


def run_dir_prefix() -> str:
    """``mkdtemp`` prefix of this process's run directories (names the owner pid)."""
    return f"{RUN_PREFIX}{os.getpid()}-"


def make_warm_dir() -> str:
    """Make a folder for one of this process's warm servers and return its path:
    ``$TMPDIR/arenabench-warm-XXXX``, a random name (every run of the server finds the path in
    its mount table, so it says nothing of which server, process or step made it), this
    process's pid in its file :data:`OWNER_FILE` (for :func:`sweep_stale_runs`)."""
    home = tempfile.mkdtemp(prefix=WARM_PREFIX)
    try:
        Path(home, OWNER_FILE).write_text(str(os.getpid()), encoding="ascii")
    except BaseException:
        shutil.rmtree(home, ignore_errors=True)
        raise
    return home


def _warm_owner(folder: Path) -> int | None:
    """The pid in a warm server folder's owner file; ``None`` when it has none (yet)."""
    try:
        return int(Path(folder, OWNER_FILE).read_text(encoding="ascii").strip())
    except (OSError, ValueError):
        return None


def _owner(entry: Path) -> int | None:
    """The owner pid of a folder this module sweeps; ``None`` when ``entry`` is none of them,
    ``0`` for an ownerless warm folder old enough to be stale."""
    m = _RUN_DIR.match(entry.name)
    if m:
        return int(m.group(1))
    if not _WARM_DIR.match(entry.name):
        return None
    pid = _warm_owner(entry)
    if pid is not None:
        return pid
    try:
        young = time.time() - entry.stat().st_mtime < OWNERLESS_GRACE_S
    except OSError:
        return None
    return None if young else 0


def owned_dir_prefix(prefix: str) -> str:
    """``mkdtemp`` prefix of one of this process's other folders (``prefix`` one of
    :data:`OWNED_PREFIXES`; names the owner pid, so that a later sweep removes it once this
    process is gone)."""
    if prefix not in OWNED_PREFIXES:
        raise ValueError(f"prefix must be one of {OWNED_PREFIXES}, got {prefix!r}")
    return f"{prefix}{os.getpid()}-"


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, killed but not yet reaped by whoever adopted it, does
    not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in ("Z", "X")


def sweep_stale_runs(*, tmpdir: str | None = None, cgroup_parent: str | None = None,
                     force: bool = False) -> list[str]:
    """Remove run directories under ``tmpdir`` (default: :func:`tempfile.gettempdir`) and
    run cgroups under ``cgroup_parent`` whose owner pid is gone; once per process unless
    ``force``.

    Returns
    -------
    list of str
        The paths removed.
    """
    with _LOCK:
        if _SWEPT.is_set() and not force:
            return []
        _SWEPT.set()
    removed: list[str] = []
    root = Path(tmpdir or tempfile.gettempdir())
    try:
        entries = list(root.iterdir())
    except OSError:
        entries = []
    for entry in entries:
        pid = _owner(entry)
        if pid is None or pid == os.getpid() or (pid and _alive(pid)):
            continue
        try:
            if entry.is_dir() and not entry.is_symlink() and entry.stat().st_uid == os.getuid():
                shutil.rmtree(entry, ignore_errors=True)
                if not entry.exists():
                    removed.append(str(entry))
        except OSError:
            continue
    if cgroup_parent:
        try:
            groups = list(Path(cgroup_parent).iterdir())
        except OSError:
            groups = []
        for group in groups:
            m = _RUN_CGROUP.match(group.name)
            if not m or _alive(int(m.group(1) or m.group(2))):
                continue
            if _remove_cgroup(group):
                removed.append(str(group))
    return removed


def _remove_cgroup(group: Path) -> bool:
    """SIGKILL what is left in ``group`` and in the cgroups under it (orphans of a dead
    launcher or warm server; not our children, so never reaped here) and remove them, deepest
    first; ``False`` when one stays."""
    from .proctools import kill_cgroup_tree

    return group.exists() and kill_cgroup_tree(str(group))
