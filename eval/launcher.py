"""The per-run launcher of external commands: one small process that owns one run.

Started by :class:`arenabench.eval.external.CommandPipeline` as
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

``result.bin``: ``rc`` (exit status, negative for a signal, ``null`` when not started),
``timed_out``, ``latency_ms`` (start of the command to the exit of its main process),
``stdout_bytes``/``stderr_bytes`` (total printed), ``pids_limit_hit`` (the cgroup refused a
fork), ``error`` (the command could not be started).
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
    run: :func:`arenabench.eval.warm_server.become_script`; it never returns).

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


def run(cfg: dict, *, become=None, own_cgroup: str | None = None) -> int:
    """Run one command as described by ``cfg`` (the launch file); returns the exit status.

    ``become``: see :func:`_spawn` (the warm server's runs). ``own_cgroup``: the run's
    cgroup, under ``cfg["cgroup_parent"]``, that this process is already in
    (:func:`enter_cgroup`); otherwise the run's cgroup is made here and the command moved
    into it."""
    rundir = cfg["rundir"]
    tails = {"stdout": _Tail(cfg["max_output"]), "stderr": _Tail(cfg["max_output"])}
    result: dict = {"rc": None, "timed_out": False, "latency_ms": 0.0, "error": "",
                    "pids_limit_hit": False}
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
            result["error"] = (f"cannot create the run's pids cgroup under "
                               f"{cfg['cgroup_parent']}: --max-procs {cfg['max_procs']} cannot "
                               "be enforced, so the command was not run")
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
