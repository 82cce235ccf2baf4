"""What the run machinery's stand-alone processes share: standard library only.

The launcher of a cold run (``launcher.py``, run as ``python -I -S``), the warm server and its
run managers (``warm_server.py``, run with the team's interpreter inside the sandbox, which
gets this module's source from the harness) and the warm server's keeper (``warm_keeper.py``)
cannot import the project; they load this module beside them (:func:`load_sibling` in each)
or from source. The harness imports it as ``arenabench.eval.runs.proctools``. It holds:

- the Linux constants they use (``prctl`` options, clone flags, mount flags) and
  :data:`RUN_GRACE_S`;
- the process walk (:func:`descendants`), killing a run's processes (:func:`kill_descendants`,
  :func:`kill_cgroup_tree`), the run's pids cgroup (:func:`cgroup_path`, :func:`new_cgroup`,
  :func:`enter_cgroup`), removing a folder (:func:`rmtree`), a run's CPU and run-queue wait
  (:func:`schedstat`);
- the run's box, a size-limited tmpfs (:func:`enter_private_mounts`, :func:`mount_box`,
  :func:`copy_back`);
- the launch configuration (:class:`LaunchConfig`): built once by the harness, serialised once
  (:meth:`LaunchConfig.to_dict`), read once by the launcher or a warm run manager
  (:meth:`LaunchConfig.from_dict`).
"""

from __future__ import annotations

import ctypes
import os
import signal
import time
from collections.abc import Iterator

PR_SET_PDEATHSIG = 1
PR_SET_DUMPABLE = 4
PR_CAPBSET_DROP = 24
CAP_SYS_PTRACE = 19
PR_SET_CHILD_SUBREAPER = 36
CLONE_NEWNS = 0x00020000
CLONE_NEWCGROUP = 0x02000000
CLONE_NEWUTS = 0x04000000
CLONE_NEWIPC = 0x08000000
CLONE_NEWUSER = 0x10000000
CLONE_NEWPID = 0x20000000
CLONE_NEWNET = 0x40000000
MS_RDONLY, MS_NOSUID, MS_NODEV, MS_NOEXEC, MS_REMOUNT = 1, 2, 4, 8, 32
MS_BIND, MS_REC, MS_PRIVATE = 4096, 16384, 1 << 18
MNT_DETACH = 2

#: Seconds the harness waits for a run's end beyond the command's own timeout (the launcher
#: or the warm run manager kills the run at the timeout: this covers their own exit).
RUN_GRACE_S = 30.0

#: The run's box in its folder, and the folders in it: the working directory (``/sandbox``),
#: ``/tmp`` and ``/dev/shm`` (:func:`mount_box`).
BOX, BOX_DIRS = "box", ("work", "tmp", "shm")
#: What comes back out of a run's box (:func:`copy_back`): the answer file, and image files the
#: run left (reports show them); at most this many files and bytes in all.
ANSWER_FILE = "obstacles.txt"
RESULT_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
RESULT_FILES_MAX, RESULT_BYTES_MAX = 16, 16 << 20
#: Bytes of ``obstacles.txt`` brought back (the harness reads at most
#: :data:`arenabench.eval.runs.predictions.OBSTACLES_MAX_BYTES` of it, and judges its size).
ANSWER_COPY_BYTES = 1 << 20


LIBC = ctypes.CDLL(None, use_errno=True)


def prctl(option: int, value: int) -> None:
    if LIBC.prctl(option, value, 0, 0, 0) != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"prctl({option}) failed: {os.strerror(err)}")


def stat_fields(pid: int | str) -> list[bytes] | None:
    """The fields of ``/proc/PID/stat`` after the command's name (state, ppid, pgrp, ...), or
    None when the process is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            stat = fh.read()
    except OSError:
        return None
    return stat[stat.rindex(b")") + 2 :].split()


def live_processes() -> Iterator[tuple[int, list[bytes]]]:
    """(pid, :func:`stat_fields`) of every process that is not a zombie."""
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            fields = stat_fields(entry.name)
            if fields is not None and fields[0] not in (b"Z", b"X"):
                yield int(entry.name), fields


def children_map() -> dict[int, list[int]]:
    children: dict[int, list[int]] = {}
    for pid, fields in live_processes():  # zombies: reaped below, nothing to kill
        children.setdefault(int(fields[1]), []).append(pid)
    return children


def descendants(root: int) -> list[int]:
    """Live (non-zombie) descendants of ``root``, from a scan of ``/proc``."""
    children = children_map()
    out: list[int] = []
    stack = [root]
    while stack:
        for child in children.get(stack.pop(), ()):
            out.append(child)
            stack.append(child)
    return out


def reap() -> None:
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return


def cgroup_pids(cgroup: str) -> list[int]:
    """The processes in ``cgroup``, this one left out (a warm run's manager is in its run's
    cgroup: :func:`enter_cgroup`)."""
    me = os.getpid()
    try:
        with open(os.path.join(cgroup, "cgroup.procs")) as fh:
            return [pid for pid in map(int, fh.read().split()) if pid != me]
    except OSError:
        return []


def kill_descendants(cgroup: str | None = None, *, scan: bool = True) -> None:
    """SIGKILL and reap every process of the run: everything in ``cgroup`` and, with
    ``scan`` (always without a cgroup), every descendant of this process found in ``/proc``."""
    me = os.getpid()
    scan = scan or not cgroup
    for _ in range(2000):
        pids = cgroup_pids(cgroup) if cgroup else []
        if scan:
            pids += descendants(me)
        if not pids:
            reap()
            return
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        reap()
        time.sleep(0.001)


def cgroup_path(parent: str, pid: int) -> str:
    """The pids cgroup of the run whose launcher (or warm run manager) is ``pid``."""
    return os.path.join(parent, f"arenabench-run-{pid}")


def write_cgroup_file(path: str, name: str, value: str) -> bool:
    """Write ``value`` into the file ``name`` of cgroup ``path``; whether it worked."""
    try:
        with open(os.path.join(path, name), "w") as fh:
            fh.write(value)
    except OSError:
        return False
    return True


def new_cgroup(parent: str, name: str, value: str) -> str | None:
    """Make this process's run cgroup under ``parent`` and write ``value`` into its file
    ``name``; ``None`` (and no folder) where either fails."""
    path = cgroup_path(parent, os.getpid())
    try:
        os.mkdir(path)
    except OSError:
        return None
    if not write_cgroup_file(path, name, value):
        try:
            os.rmdir(path)
        except OSError:
            pass
        return None
    return path


def enter_cgroup(parent: str) -> str | None:
    """Make this process's run cgroup under ``parent`` and move this process into it, before
    the run is asked for (a warm server's standby run manager); ``None`` where it cannot.

    Moving a process between cgroups waits for an RCU grace period (``cgroup.procs`` takes
    ``cgroup_threadgroup_rwsem`` for writing): 10-30 ms of wall time when moves are tens of
    milliseconds apart, measured on this project's 2-core machine, against 0.3 ms back to
    back. A standby pays it while an earlier run goes; its run then starts in the cgroup by
    ``fork`` alone. The cgroup's ``pids.max`` stays unlimited until :func:`run` sets it,
    before any of the run's code; :func:`run` never removes it (its manager is in it): the
    server does, once the manager has ended.
    """
    return new_cgroup(parent, "cgroup.procs", "0")


def kill_cgroup_tree(cgroup: str, *, remove: bool = True, tries: int = 200) -> bool:
    """SIGKILL every process in ``cgroup`` and in the cgroups under it (from outside: the
    processes are not this one's children, so nothing is reaped here) and, with ``remove``,
    remove them, deepest first; whether none is left."""
    for _ in range(tries):
        try:
            entries = list(os.scandir(cgroup))
        except FileNotFoundError:
            return True
        except OSError:
            return False
        for entry in entries:
            if entry.is_dir(follow_symlinks=False):
                kill_cgroup_tree(entry.path, remove=remove, tries=1)
        pids = cgroup_pids(cgroup)
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        if not remove:
            if not pids:
                return True
        else:
            try:
                os.rmdir(cgroup)
                return True
            except FileNotFoundError:
                return True
            except OSError:
                pass
        if tries > 1:
            time.sleep(0.005)
    return False


def _task_files(pids: list[int], name: str) -> Iterator[bytes]:
    """The file ``name`` of every thread of ``pids`` (``/proc/PID/task/TID/NAME``); a process
    or thread gone gives nothing."""
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            try:
                with open(f"/proc/{pid}/task/{tid}/{name}", "rb") as fh:
                    yield fh.read()
            except OSError:
                continue


def _stat_fields(text: bytes) -> list[bytes]:
    """A ``stat`` file's fields after the command name (state first)."""
    return text.rsplit(b")", 1)[-1].split()


def schedstat(pids: list[int]) -> tuple[float, float]:
    """CPU time and time spent waiting for a CPU (run queue), in ms, of the threads of
    ``pids`` summed (``/proc/PID/task/TID/schedstat``; a process gone counts nothing)."""
    cpu = wait = 0
    for text in _task_files(pids, "schedstat"):
        try:
            fields = text.split()
            cpu, wait = cpu + int(fields[0]), wait + int(fields[1])
        except (ValueError, IndexError):
            continue
    return cpu / 1e6, wait / 1e6


#: Scheduling policies a run may choose for itself that make it wait behind everything else.
SCHED_BATCH, SCHED_IDLE = 3, 5


def runnable_threads(pids: list[int]) -> tuple[int, int]:
    """The threads of ``pids`` that want a CPU now (state ``R``), and the CPUs they may use
    (the fewest any of them may: its affinity). More of the first than the second: they wait
    for each other."""
    cpus = os.cpu_count() or 1
    for pid in pids:
        try:
            cpus = min(cpus, len(os.sched_getaffinity(pid)))
        except OSError:
            continue
    runnable = sum(_stat_fields(text)[:1] == [b"R"] for text in _task_files(pids, "stat"))
    return runnable, cpus


def lowered_priority(pids: list[int]) -> bool:
    """Whether a thread of ``pids`` gave itself less of the CPU than this process has: a higher
    nice value, or the batch or idle scheduling policy (``/proc/PID/task/TID/stat``). Waiting
    for a CPU then is the run's own doing, never the machine's."""
    own = os.getpriority(os.PRIO_PROCESS, 0)
    for text in _task_files(pids, "stat"):
        try:
            fields = _stat_fields(text)
            nice, policy = int(fields[16]), int(fields[38])
        except (ValueError, IndexError):
            continue
        if nice > own or policy in (SCHED_BATCH, SCHED_IDLE):
            return True
    return False


def check(result: int, what: str) -> None:
    if result != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"{what}: {os.strerror(err)}")


def enter_private_mounts() -> None:
    """Enter a user and mount namespace of this process's own (its uid and gid mapped to
    themselves, every mount private), where :func:`mount_box` can mount the run's tmpfs.

    Raises
    ------
    OSError
        Where user namespaces cannot be made (the box is then a plain folder).
    """
    uid, gid = os.getuid(), os.getgid()
    check(LIBC.unshare(CLONE_NEWUSER | CLONE_NEWNS), "unshare")
    for name, text in (("setgroups", "deny"), ("uid_map", f"{uid} {uid} 1"),
                       ("gid_map", f"{gid} {gid} 1")):
        with open(f"/proc/self/{name}", "w") as fh:
            fh.write(text)
    check(LIBC.mount(None, b"/", None, MS_REC | MS_PRIVATE, None), "mount --make-rprivate /")


def mount_box(rundir: str, size: int | None) -> str:
    """Make the run's box at ``RUNDIR/box``: a tmpfs of ``size`` bytes in this process's mount
    namespace (``None``: a plain folder, where no namespace could be made), its folders
    :data:`BOX_DIRS`, and a copy of ``RUNDIR/work`` (the image and the harness's files) in
    ``box/work``. Returns the box's path.

    Raises
    ------
    OSError
        When it cannot be made, or the files do not fit (``ENOSPC``).
    """
    box = os.path.join(rundir, BOX)
    os.makedirs(box, exist_ok=True)
    if size is not None:
        check(LIBC.mount(b"tmpfs", box.encode(), b"tmpfs", MS_NOSUID | MS_NODEV,
                           f"size={int(size)},mode=0700".encode()), "mount tmpfs")
    for name in BOX_DIRS:
        os.mkdir(os.path.join(box, name), 0o700)
    import shutil

    shutil.copytree(os.path.join(rundir, "work"), os.path.join(box, "work"), symlinks=True,
                    dirs_exist_ok=True)
    return box


def _result_names(src_fd: int, skip: str) -> list[str]:
    """The answer file first, then the image files, of the folder ``src_fd`` (top level; at
    most a few thousand entries looked at: a run may leave millions)."""
    names = [ANSWER_FILE]
    with os.scandir(src_fd) as entries:
        for n, entry in enumerate(entries):
            if n >= 4096 or len(names) > RESULT_FILES_MAX:
                break
            if entry.name != skip and entry.name.lower().endswith(RESULT_SUFFIXES):
                names.append(entry.name)
    return names[:RESULT_FILES_MAX]


def _copy_answer(src_fd: int, dst_fd: int) -> None:
    """Bring ``obstacles.txt`` back as the harness must judge it: a regular file's first
    :data:`ANSWER_COPY_BYTES` bytes, at its full size (the rest a hole); a folder, a link
    (same target) or any other kind of file as one of that kind (the harness says which)."""
    import stat

    try:
        st = os.stat(ANSWER_FILE, dir_fd=src_fd, follow_symlinks=False)
    except OSError:
        return
    try:
        os.unlink(ANSWER_FILE, dir_fd=dst_fd)
    except OSError:
        pass
    try:
        if stat.S_ISDIR(st.st_mode):
            os.mkdir(ANSWER_FILE, 0o700, dir_fd=dst_fd)
        elif stat.S_ISLNK(st.st_mode):
            os.symlink(os.readlink(ANSWER_FILE, dir_fd=src_fd), ANSWER_FILE, dir_fd=dst_fd)
        elif not stat.S_ISREG(st.st_mode):
            os.mkfifo(ANSWER_FILE, 0o600, dir_fd=dst_fd)
        else:
            fd = os.open(ANSWER_FILE, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK, dir_fd=src_fd)
            try:
                data = os.read(fd, ANSWER_COPY_BYTES)
            finally:
                os.close(fd)
            out = os.open(ANSWER_FILE, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW,
                          0o600, dir_fd=dst_fd)
            try:
                os.write(out, data)
                os.ftruncate(out, st.st_size)  # its size, as the harness checks it
            finally:
                os.close(out)
    except OSError:
        pass


def copy_back(src_fd: int, dst_fd: int, *, skip: str) -> None:
    """Copy ``obstacles.txt`` (:func:`_copy_answer`) and the image files a run left in its
    working folder (``src_fd``: its box's ``work``) into ``dst_fd`` (the run folder's ``work``
    on the machine): regular files only, links not followed, at most
    :data:`RESULT_FILES_MAX` files and :data:`RESULT_BYTES_MAX` bytes in all; ``skip`` (the
    input image's name) stays."""
    import stat

    _copy_answer(src_fd, dst_fd)
    budget = RESULT_BYTES_MAX
    for name in _result_names(src_fd, skip)[1:]:
        try:
            fd = os.open(name, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK, dir_fd=src_fd)
        except OSError:
            continue
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or st.st_size > budget:
                continue
            data = os.read(fd, st.st_size + 1) if st.st_size else b""
            if len(data) > budget:
                continue
            budget -= len(data)
        finally:
            os.close(fd)
        try:
            os.unlink(name, dir_fd=dst_fd)
        except OSError:
            pass
        try:
            out = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600,
                          dir_fd=dst_fd)
        except OSError:
            continue
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(out, view):]
        finally:
            os.close(out)


def rmtree(path: str, *, tries: int = 1) -> None:
    """Remove the folder ``path`` and what it holds, errors ignored (``tries`` times, 20 ms
    apart, while it is still there)."""
    import shutil

    for n in range(tries):
        shutil.rmtree(path, ignore_errors=True)
        if n + 1 < tries and os.path.exists(path):
            time.sleep(0.02)
        else:
            return


class _Record:
    """A typed record, as a dataclass is, without :mod:`dataclasses`: this module is imported
    by every cold run's launcher, a fresh ``python -I -S``, where importing ``dataclasses``
    (and ``inspect`` with it) would cost about 20 ms of CPU per image. The fields are the
    class's annotations, in order; a class attribute is the field's default (a list or dict
    default is copied for each record); a field without one is required."""

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The record's fields, in order."""
        names: dict[str, None] = {}
        for klass in reversed(cls.__mro__):
            names.update(dict.fromkeys(klass.__dict__.get("__annotations__", {})))  # noqa: RUF063 (no inspect here)
        return tuple(names)

    def __init__(self, **values) -> None:
        names = self.field_names()
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise TypeError(f"{type(self).__name__}: unknown field(s) {', '.join(unknown)}")
        for name in names:
            if name in values:
                value = values[name]
            elif hasattr(type(self), name):
                value = getattr(type(self), name)
                value = type(value)(value) if isinstance(value, (list, dict)) else value
            else:
                raise TypeError(f"{type(self).__name__}: missing field {name!r}")
            setattr(self, name, value)

    def to_dict(self) -> dict:
        """Plain values only (for :mod:`marshal` and JSON); a nested record as its dict."""
        return {name: value.to_dict() if isinstance(value, _Record) else
                (type(value)(value) if isinstance(value, (list, dict)) else value)
                for name in self.field_names() for value in (getattr(self, name),)}

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and self.to_dict() == other.to_dict()

    def __repr__(self) -> str:
        fields = ", ".join(f"{n}={getattr(self, n)!r}" for n in self.field_names())
        return f"{type(self).__name__}({fields})"


class WarmLaunch(_Record):
    """The warm-run part of a :class:`LaunchConfig` (``None`` for a cold run).

    Parameters
    ----------
    isolate : bool
        The run enters namespaces of its own (under bubblewrap).
    hide : list of str
        The server's folders, hidden from the run (an empty tmpfs each).
    hide_if_there : list of str
        Folders hidden only where they were bound for the server.
    keep : list of str
        Read-only folders under ``/tmp`` kept visible on top of the run's own ``/tmp``.
    target : dict or None
        What the run becomes (``module``, ``script``, ``argv``, ``path0``): set by the server.
    env_changes : dict
        What the server's preloaded imports set in the environment (set by the server).
    """

    isolate: bool = False
    hide: list[str] = []  # noqa: RUF012 (copied for each record)
    hide_if_there: list[str] = []  # noqa: RUF012
    keep: list[str] = []  # noqa: RUF012
    target: dict | None = None
    env_changes: dict = {}  # noqa: RUF012


class RunRecord(_Record):
    """What a run's launcher (cold) or the warm server's run manager writes to
    ``RUNDIR/result.bin`` (as :meth:`to_dict`, a :mod:`marshal` dict), and what
    :func:`arenabench.eval.runs.predictions.prediction_from_run` reads.

    Attributes
    ----------
    rc : int or None
        Exit status of the command's main process, negative for a signal; ``None`` when it
        never started.
    timed_out : bool
        The command outran its timeout (and was killed).
    latency_ms : float
        From the command's start to its main process's exit.
    error : str
        The command could not be started (its failure).
    harness_error : str
        The launcher could not prepare the run (the harness's failure, never the command's).
    pids_limit_hit : bool
        The run's pids cgroup refused a fork.
    box : str
        ``"tmpfs"``, ``"folder"`` where no namespace could be made, or ``""`` (no box).
    cpu_ms, wait_ms : float
        Of a timed-out run: the CPU time its processes used and the time they waited for a
        CPU (:func:`schedstat`).
    lowered_priority : bool
        Of a timed-out run: it raised its own nice value or took an idle policy
        (:func:`lowered_priority`).
    runnable, cpus : int
        Of a timed-out run: its threads that wanted a CPU at the timeout, and the CPUs they
        may use (:func:`runnable_threads`).
    """

    rc: int | None = None
    timed_out: bool = False
    latency_ms: float = 0.0
    error: str = ""
    harness_error: str = ""
    pids_limit_hit: bool = False
    box: str = ""
    cpu_ms: float = 0.0
    wait_ms: float = 0.0
    lowered_priority: bool = False
    runnable: int = 0
    cpus: int = 0

    @classmethod
    def from_dict(cls, d: dict) -> RunRecord:
        """Inverse of :meth:`to_dict` (``TypeError`` for a field it does not know)."""
        if not isinstance(d, dict):
            raise TypeError(f"a run's result is a dict, got {type(d).__name__}")
        return cls(**d)


class LaunchConfig(_Record):
    """How one run is launched: everything the launcher (or a warm run manager) needs.

    Parameters
    ----------
    exe, argv, env, cwd : str, list, dict, str
        What is executed, with which arguments and environment, from which folder.
    rundir : str
        The run's folder (``work``, ``tmp``, its box; ``stdout``, ``stderr``, ``result.bin``).
    timeout_s, memory_bytes, max_file_size, max_output, max_procs : limits
        The run's limits (:class:`arenabench.eval.runs.limits.RunLimits`).
    pids_max : int
        The run cgroup's ``pids.max`` (the command's processes and the sandbox's own).
    cgroup_parent : str or None
        Where the run's pids cgroup is made (``None``: ``RLIMIT_NPROC`` instead, except for
        root, whom it does not bind).
    sandboxed : bool
        Under bubblewrap (nothing can leave the run's cgroup: reading it finds every process).
    nproc_rlimit : bool
        Hold the run to ``RLIMIT_NPROC`` (where no cgroup holds it and it binds).
    parent_pid : int
        The harness (a launcher started after the harness died runs nothing); 0 for a warm
        run (the server sets it).
    box_bytes : int or None
        Size of the run's box under bubblewrap (:func:`mount_box`); ``None``: no box.
    image_name : str
        The input image's name in the run's folder (never brought back by :func:`copy_back`).
    warm : WarmLaunch or None
        The warm run's part, ``None`` for a cold run.
    """

    exe: str
    argv: list[str]
    env: dict
    cwd: str
    rundir: str
    timeout_s: float
    memory_bytes: int
    max_file_size: int
    max_output: int
    max_procs: int
    pids_max: int
    cgroup_parent: str | None = None
    sandboxed: bool = False
    nproc_rlimit: bool = False
    parent_pid: int = 0
    box_bytes: int | None = None
    image_name: str = ""
    warm: WarmLaunch | None = None

    @classmethod
    def from_dict(cls, d: dict) -> LaunchConfig:
        """Inverse of :meth:`to_dict`."""
        d = dict(d)
        warm = d.pop("warm", None)
        return cls(**d, warm=None if warm is None else WarmLaunch(**warm))
