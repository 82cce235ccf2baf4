"""The per-run launcher of external commands: one small process that owns one run.

Started by :class:`arenabench.eval.runs.command.CommandPipeline` as
``python -I -S .../launcher.py RUNDIR/launch.bin`` (a few C-level standard modules only, so
it starts fast and imports nothing of the project; its configuration and result are
:mod:`marshal` dicts, read and written by the same interpreter). It

1. makes itself a child subreaper (``PR_SET_CHILD_SUBREAPER``): every process the command
   starts stays its descendant, however it detaches (``setsid``, double fork);
2. asks for SIGTERM when the harness dies (``PR_SET_PDEATHSIG``, even after SIGKILL of the
   harness): it then kills the run's processes and removes the run's directory;
3. puts the command in a pids cgroup of its own when one can be created (``--max-procs``),
   sets ``RLIMIT_AS`` (``--memory-limit``), ``RLIMIT_FSIZE`` (``--max-file-size``) and no core
   files, and starts it with stdout/stderr on pipes it reads itself, keeping only the last
   ``max_output`` bytes of each (memory stays bounded whatever the command prints);
4. waits for the command's *main* process (a detached child holding stdout open does not
   keep the run going), or the timeout, then SIGKILLs and reaps every remaining descendant;
5. writes ``RUNDIR/stdout``, ``RUNDIR/stderr`` (the tails) and ``RUNDIR/result.bin``.

Under bubblewrap (``box_bytes`` in the launch file) the launcher first enters a user and mount
namespace of its own and mounts the run's *box* there: a tmpfs of ``box_bytes`` at
``RUNDIR/box`` holding ``work`` (bound at ``/sandbox``: a copy of ``RUNDIR/work``, the image and
the files the harness put there), ``tmp`` (``/tmp``) and ``shm`` (``/dev/shm``), so that
everything a run may write is bounded in total and never lands on the machine's disk
(:func:`mount_box`). Once the command has ended, ``obstacles.txt`` and the image files it left
come back into ``RUNDIR/work`` (bounded: :func:`copy_back`); the box goes with the launcher's
namespace.

``result.bin``: ``rc`` (exit status, negative for a signal, ``null`` when not started),
``timed_out``, ``latency_ms`` (start of the command to the exit of its main process),
``stdout_bytes``/``stderr_bytes`` (total printed), ``pids_limit_hit`` (the cgroup refused a
fork), ``error`` (the command could not be started), ``harness_error`` (the launcher could not
prepare the run: not the command's failure), ``cpu_ms`` and ``wait_ms`` (of a timed-out run:
the CPU time its processes used and the time they waited for a CPU, from
``/proc/PID/schedstat``: :func:`schedstat`), ``box`` (``"tmpfs"``, ``"folder"`` where no
namespace could be made, or ``""`` without one).
"""

from __future__ import annotations

import ctypes
import marshal
import os
import resource
import select
import signal
import sys
import time

PR_SET_PDEATHSIG = 1
PR_SET_DUMPABLE = 4
PR_CAPBSET_DROP = 24
CAP_SYS_PTRACE = 19
PR_SET_CHILD_SUBREAPER = 36
CLONE_NEWNS = 0x00020000
CLONE_NEWUSER = 0x10000000
MS_NOSUID, MS_NODEV, MS_REC, MS_PRIVATE = 2, 4, 16384, 1 << 18

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

_stop_signal: int | None = None


class _Stop(Exception):
    pass


def _on_signal(signum: int, frame: object) -> None:
    global _stop_signal
    if _stop_signal is None:
        _stop_signal = signum
        raise _Stop()


_LIBC = ctypes.CDLL(None, use_errno=True)


def _prctl(option: int, value: int) -> None:
    if _LIBC.prctl(option, value, 0, 0, 0) != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"prctl({option}) failed: {os.strerror(err)}")


def _children_map() -> dict[int, list[int]]:
    children: dict[int, list[int]] = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat", "rb") as fh:
                stat = fh.read()
        except OSError:
            continue
        fields = stat[stat.rindex(b")") + 2 :].split()
        if fields[0] in (b"Z", b"X"):
            continue  # zombies: reaped below, nothing to kill
        children.setdefault(int(fields[1]), []).append(int(entry.name))
    return children


def descendants(root: int) -> list[int]:
    """Live (non-zombie) descendants of ``root``, from a scan of ``/proc``."""
    children = _children_map()
    out: list[int] = []
    stack = [root]
    while stack:
        for child in children.get(stack.pop(), ()):
            out.append(child)
            stack.append(child)
    return out


def _reap() -> None:
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return


def _cgroup_pids(cgroup: str) -> list[int]:
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
        pids = _cgroup_pids(cgroup) if cgroup else []
        if scan:
            pids += descendants(me)
        if not pids:
            _reap()
            return
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        _reap()
        time.sleep(0.001)


def cgroup_path(parent: str, pid: int) -> str:
    """The pids cgroup of the run whose launcher (or warm run manager) is ``pid``."""
    return os.path.join(parent, f"arenabench-run-{pid}")


def _write_cgroup_file(path: str, name: str, value: str) -> bool:
    """Write ``value`` into the file ``name`` of cgroup ``path``; whether it worked."""
    try:
        with open(os.path.join(path, name), "w") as fh:
            fh.write(value)
    except OSError:
        return False
    return True


def _new_cgroup(parent: str, name: str, value: str) -> str | None:
    """Make this process's run cgroup under ``parent`` and write ``value`` into its file
    ``name``; ``None`` (and no folder) where either fails."""
    path = cgroup_path(parent, os.getpid())
    try:
        os.mkdir(path)
    except OSError:
        return None
    if not _write_cgroup_file(path, name, value):
        try:
            os.rmdir(path)
        except OSError:
            pass
        return None
    return path


def _make_cgroup(parent: str | None, max_procs: int | str) -> str | None:
    return _new_cgroup(parent, "pids.max", str(max_procs)) if parent else None


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
    return _new_cgroup(parent, "cgroup.procs", "0")


def _limit_own_cgroup(path: str, max_procs: int | str) -> str | None:
    """Set ``pids.max`` of the cgroup this manager is in (one more for the manager)."""
    value = "max" if max_procs == "max" else str(int(max_procs) + 1)
    return path if _write_cgroup_file(path, "pids.max", value) else None


def _pids_limit_hit(cgroup: str | None) -> bool:
    if not cgroup:
        return False
    try:
        with open(os.path.join(cgroup, "pids.events")) as fh:
            for line in fh:
                key, _, value = line.partition(" ")
                if key == "max":
                    return int(value) > 0
    except (OSError, ValueError):
        pass
    return False


def _remove_cgroup(cgroup: str | None) -> None:
    if not cgroup:
        return
    for _ in range(200):
        try:
            os.rmdir(cgroup)
            return
        except FileNotFoundError:
            return
        except OSError:
            kill_descendants(cgroup, scan=False)
            time.sleep(0.005)


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
        pids = _cgroup_pids(cgroup)
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


def schedstat(pids: list[int]) -> tuple[float, float]:
    """CPU time and time spent waiting for a CPU (run queue), in ms, of the threads of
    ``pids`` summed (``/proc/PID/task/TID/schedstat``; a process gone counts nothing)."""
    cpu = wait = 0
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            try:
                with open(f"/proc/{pid}/task/{tid}/schedstat", "rb") as fh:
                    fields = fh.read().split()
                cpu += int(fields[0])
                wait += int(fields[1])
            except (OSError, ValueError, IndexError):
                continue
    return cpu / 1e6, wait / 1e6


def _check(result: int, what: str) -> None:
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
    _check(_LIBC.unshare(CLONE_NEWUSER | CLONE_NEWNS), "unshare")
    for name, text in (("setgroups", "deny"), ("uid_map", f"{uid} {uid} 1"),
                       ("gid_map", f"{gid} {gid} 1")):
        with open(f"/proc/self/{name}", "w") as fh:
            fh.write(text)
    _check(_LIBC.mount(None, b"/", None, MS_REC | MS_PRIVATE, None), "mount --make-rprivate /")


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
        _check(_LIBC.mount(b"tmpfs", box.encode(), b"tmpfs", MS_NOSUID | MS_NODEV,
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


class _Tail:
    """The last ``limit`` bytes of a stream, and how many were seen."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.data = bytearray()
        self.total = 0

    def add(self, chunk: bytes) -> None:
        self.total += len(chunk)
        self.data += chunk
        if len(self.data) > 2 * self.limit:
            del self.data[: len(self.data) - self.limit]

    def value(self) -> bytes:
        return bytes(self.data[-self.limit :])


def _child_setup(cfg: dict, cgroup: str | None) -> None:
    # runs in the forked child, before exec (``cgroup``: the one to move into, if any)
    if cgroup:
        with open(os.path.join(cgroup, "cgroup.procs"), "w") as fh:
            fh.write("0")
    _prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    _LIBC.prctl(PR_CAPBSET_DROP, CAP_SYS_PTRACE, 0, 0, 0)  # EPERM without it: nothing to drop
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_AS, (cfg["memory_bytes"], cfg["memory_bytes"]))
    resource.setrlimit(resource.RLIMIT_FSIZE, (cfg["max_file_size"], cfg["max_file_size"]))
    if cfg.get("nproc_rlimit") and cfg["max_procs"]:
        # RLIMIT_NPROC counts every process of the real uid, so the user's others are added
        # (approximate: the fallback where no pids cgroup can be made)
        n = cfg["pids_max"] + _processes_of(os.getuid())
        resource.setrlimit(resource.RLIMIT_NPROC, (n, n))


def _processes_of(uid: int) -> int:
    n = 0
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                n += entry.stat().st_uid == uid
            except OSError:
                pass
    return n


def _spawn(cfg: dict, cgroup: str | None, out_fd: int, err_fd: int, become=None) -> int:
    """fork + exec the command (new session, limits, cgroup); returns its pid.

    ``become(cfg)``, when given, replaces the ``execve`` in the child (the warm server's
    run: :func:`arenabench.eval.runs.warm_server.become_script`; it never returns).

    Raises
    ------
    OSError
        When it could not be started (the child's error, passed back through a pipe).
    """
    r_err, w_err = os.pipe()  # close-on-exec: EOF without data means exec succeeded
    pid = os.fork()
    if pid == 0:  # child
        try:
            os.close(r_err)
            os.setsid()
            null = os.open(os.devnull, os.O_RDONLY)
            os.dup2(null, 0)
            os.dup2(out_fd, 1)
            os.dup2(err_fd, 2)
            for s in (signal.SIGPIPE, signal.SIGXFSZ, signal.SIGTERM, signal.SIGINT,
                      signal.SIGHUP):
                signal.signal(s, signal.SIG_DFL)
            _child_setup(cfg, cgroup)
            os.closerange(3, w_err)
            os.closerange(w_err + 1, 1 << 16)
            os.chdir(cfg["cwd"])
            if become is not None:
                os.close(w_err)  # started: from here the run's own failures are its output
                w_err = -1
                become(cfg)
            os.execve(cfg["exe"], cfg["argv"], cfg["env"])
        except BaseException as exc:
            try:
                if w_err < 0:
                    os.write(2, f"arenabench: {type(exc).__name__}: {exc}\n".encode())
                    os._exit(1)
                os.write(w_err, f"{type(exc).__name__}: {exc}".encode(errors="replace"))
            finally:
                os._exit(127)
    os.close(w_err)
    try:
        chunks = []
        while True:
            chunk = os.read(r_err, 4096)
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(r_err)
    if chunks:
        os.waitpid(pid, 0)
        raise OSError(b"".join(chunks).decode(errors="replace"))
    return pid


def _write_result(rundir: str, result: dict, tails: dict[str, _Tail]) -> None:
    for name, t in tails.items():
        with open(os.path.join(rundir, name), "wb") as fh:
            fh.write(t.value())
    tmp = os.path.join(rundir, "result.bin.tmp")
    with open(tmp, "wb") as fh:
        marshal.dump(result, fh)
    os.replace(tmp, os.path.join(rundir, "result.bin"))


def _exit_status(status: int) -> int:
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _rmtree(path: str) -> None:
    import shutil

    shutil.rmtree(path, ignore_errors=True)


def _prepare_box(cfg: dict, result: dict) -> int:
    """The cold launcher's box (:func:`mount_box`) in a namespace of its own, seen by the
    bubblewrap it starts; returns a descriptor of ``box/work``."""
    try:
        enter_private_mounts()
        size, result["box"] = cfg["box_bytes"], "tmpfs"
    except OSError:  # no user namespace here: a plain folder (no bound on what is written)
        size, result["box"] = None, "folder"
    box = mount_box(cfg["rundir"], size)
    return os.open(os.path.join(box, "work"), os.O_RDONLY | os.O_DIRECTORY)


def _read_note(path: str) -> str:
    """The text of a small file the run's own side left (``""`` when there is none)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return ""
    try:
        return os.read(fd, 4000).decode(errors="replace")
    finally:
        os.close(fd)


def _box_problem(cfg: dict, exc: OSError) -> str:
    import errno

    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return (f"the files copied into the run's folder do not fit in its {cfg['box_bytes']} "
                "bytes (--max-disk)")
    return f"cannot prepare the run's folder: {exc}"


def _copy_back_to(rundir: str, box_fd: int, cfg: dict) -> None:
    try:
        dst = os.open(os.path.join(rundir, "work"), os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        copy_back(box_fd, dst, skip=cfg.get("image_name", ""))
    finally:
        os.close(dst)
        os.close(box_fd)


def run(cfg: dict, *, become=None, own_cgroup: str | None = None) -> int:
    """Run one command as described by ``cfg`` (the launch file); returns the exit status.

    ``become``: see :func:`_spawn` (the warm server's runs). ``own_cgroup``: the run's
    cgroup, under ``cfg["cgroup_parent"]``, that this process is already in
    (:func:`enter_cgroup`); otherwise the run's cgroup is made here and the command moved
    into it."""
    rundir = cfg["rundir"]
    tails = {"stdout": _Tail(cfg["max_output"]), "stderr": _Tail(cfg["max_output"])}
    result: dict = {"rc": None, "timed_out": False, "latency_ms": 0.0, "error": "",
                    "harness_error": "", "pids_limit_hit": False, "box": ""}
    # --max-procs 0: no process limit (the cgroup still holds the run's processes for cleanup)
    pids_max = cfg["pids_max"] if cfg["max_procs"] else "max"
    if own_cgroup:
        cgroup = _limit_own_cgroup(own_cgroup, pids_max)
    else:
        cgroup = _make_cgroup(cfg.get("cgroup_parent"), pids_max)
    attach = None if own_cgroup else cgroup
    cleaned = False
    try:
        if cgroup is None and cfg.get("cgroup_parent") and cfg["max_procs"]:
            # the parent took a probe's pids cgroup: failing now, run nothing rather than run
            # without the process limit (fail closed)
            result["harness_error"] = (
                f"cannot create the run's pids cgroup under {cfg['cgroup_parent']}: "
                f"--max-procs {cfg['max_procs']} cannot be enforced, so the command was not run")
            cleaned = True
            return 0
        box_fd = None
        if cfg.get("box_bytes") and become is None:  # a cold run under bubblewrap
            try:
                box_fd = _prepare_box(cfg, result)
            except OSError as exc:
                result["harness_error"] = _box_problem(cfg, exc)
                cleaned = True
                return 0
        r_out, w_out = os.pipe()
        r_err, w_err = os.pipe()
        start = time.perf_counter()
        try:
            pid = _spawn(cfg, attach, w_out, w_err, become)
        except OSError as exc:
            result["error"] = f"cannot start command: {exc}"
            cleaned = True
            return 0
        finally:
            os.close(w_out)
            os.close(w_err)
        deadline = start + cfg["timeout_s"]
        pidfd = os.pidfd_open(pid)
        poller = select.poll()
        streams = {r_out: tails["stdout"], r_err: tails["stderr"]}
        for fd in (pidfd, r_out, r_err):
            poller.register(fd, select.POLLIN)

        def pump(fd: int) -> None:
            """Keep one chunk of an output pipe; forget the pipe at end of file."""
            chunk = os.read(fd, 1 << 16)
            if chunk:
                streams[fd].add(chunk)
            else:
                poller.unregister(fd)
                del streams[fd]

        exited = False
        while not exited:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                result["timed_out"] = True
                break
            for fd, _ in poller.poll(remaining * 1000.0):
                if fd == pidfd:
                    exited = True
                    continue
                pump(fd)
        # in a sandbox nothing can leave the run's cgroup: reading it finds every process;
        # without one a process could move itself out, so /proc is scanned too
        scan = not cfg.get("sandboxed")
        if not exited:
            alive = (_cgroup_pids(cgroup) if cgroup else []) + descendants(os.getpid())
            result["cpu_ms"], result["wait_ms"] = schedstat(alive)
            kill_descendants(cgroup, scan=scan)
        result["rc"] = _exit_status(os.waitpid(pid, 0)[1])
        result["latency_ms"] = (time.perf_counter() - start) * 1000.0
        kill_descendants(cgroup, scan=scan)
        cleaned = True
        # every writer is gone: drain what is left in the pipes
        poller.unregister(pidfd)
        os.close(pidfd)
        drain_until = time.perf_counter() + 2.0
        while streams and time.perf_counter() < drain_until:
            for fd, _ in poller.poll(100):
                pump(fd)
        result["pids_limit_hit"] = _pids_limit_hit(cgroup)
        if become is not None:  # a warm run that could not be prepared says why in its folder
            result["harness_error"] = _read_note(os.path.join(rundir, "harness_error"))
        if box_fd is not None:
            _copy_back_to(rundir, box_fd, cfg)
        return 0
    except _Stop:
        kill_descendants(cgroup)
        _remove_cgroup(attach)
        _rmtree(rundir)
        return 128 + (_stop_signal or signal.SIGTERM)
    finally:
        if _stop_signal is None:
            if not cleaned:  # an unexpected error: still leave nothing behind
                kill_descendants(cgroup)
            _remove_cgroup(attach)
            _write_result(rundir, result, tails)


def main(argv: list[str]) -> int:
    """Entry point: ``launcher.py LAUNCH_FILE`` (a marshal dict)."""
    with open(argv[1], "rb") as fh:
        cfg = marshal.load(fh)
    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(s, _on_signal)
    try:
        _prctl(PR_SET_CHILD_SUBREAPER, 1)
        _prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        # not ptrace-attachable by the command it runs (which would stop the launcher and
        # with it the timeout): non-dumpable, and the command loses CAP_SYS_PTRACE
        _LIBC.prctl(PR_SET_DUMPABLE, 0, 0, 0, 0)
        if os.getppid() != cfg["parent_pid"]:  # the harness died before PDEATHSIG was set
            _rmtree(cfg["rundir"])
            return 128 + signal.SIGTERM
        return run(cfg)
    except _Stop:
        kill_descendants(None)
        _rmtree(cfg["rundir"])
        return 128 + (_stop_signal or signal.SIGTERM)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
