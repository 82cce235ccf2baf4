"""The per-run launcher of external commands: one small process that owns one run.

Started by :class:`arenabench.eval.runs.pipeline.CommandPipeline` as
``python -I -S .../launcher.py RUNDIR/launch.bin`` (a few C-level standard modules only, so
it starts fast and imports nothing of the project but :mod:`.proctools`, which it loads from
beside it; its configuration, a :class:`~arenabench.eval.runs.proctools.LaunchConfig`, and its
result are :mod:`marshal` dicts, read and written by the same interpreter). It

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
(:func:`.proctools.mount_box`). Once the command has ended, ``obstacles.txt`` and the image
files it left come back into ``RUNDIR/work`` (bounded: :func:`.proctools.copy_back`); the box
goes with the launcher's namespace.

``result.bin``: a :class:`~arenabench.eval.runs.proctools.RunRecord` (its fields say what each
value means).
"""

from __future__ import annotations

import marshal
import os
import resource
import select
import signal
import sys
import time


def load_sibling(name: str):
    """A stand-alone module of this package: the package's own where this file is imported as
    part of it, the warm server's copy (sent as source, in :data:`sys.modules` as
    ``_arenabench_<name>``), else the file beside this one (run as ``python -I -S``)."""
    if __package__:
        import importlib

        return importlib.import_module(f"{__package__}.{name}")
    if f"_arenabench_{name}" in sys.modules:
        return sys.modules[f"_arenabench_{name}"]
    import importlib.util

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), f"{name}.py")
    spec = importlib.util.spec_from_file_location(f"_arenabench_{name}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


tools = load_sibling("proctools")
LaunchConfig = tools.LaunchConfig
RunRecord = tools.RunRecord

_stop_signal: int | None = None


class Stopped(Exception):
    """Raised in the main thread by the first stop signal (:func:`on_stop_signal`)."""


def on_stop_signal(signum: int, frame: object) -> None:
    """Signal handler: the first stop signal raises :class:`Stopped`; later ones are ignored."""
    global _stop_signal
    if _stop_signal is None:
        _stop_signal = signum
        raise Stopped()


def _make_cgroup(parent: str | None, max_procs: int | str) -> str | None:
    return tools.new_cgroup(parent, "pids.max", str(max_procs)) if parent else None


def _limit_own_cgroup(path: str, max_procs: int | str) -> str | None:
    """Set ``pids.max`` of the cgroup this manager is in (one more for the manager)."""
    value = "max" if max_procs == "max" else str(int(max_procs) + 1)
    return path if tools.write_cgroup_file(path, "pids.max", value) else None


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
            tools.kill_descendants(cgroup, scan=False)
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


def _child_setup(cfg: LaunchConfig, cgroup: str | None) -> None:
    # runs in the forked child, before exec (``cgroup``: the one to move into, if any)
    if cgroup:
        with open(os.path.join(cgroup, "cgroup.procs"), "w") as fh:
            fh.write("0")
    tools.prctl(tools.PR_SET_PDEATHSIG, signal.SIGKILL)
    # EPERM without the capability: nothing to drop
    tools.LIBC.prctl(tools.PR_CAPBSET_DROP, tools.CAP_SYS_PTRACE, 0, 0, 0)
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_AS, (cfg.memory_bytes, cfg.memory_bytes))
    resource.setrlimit(resource.RLIMIT_FSIZE, (cfg.max_file_size, cfg.max_file_size))
    if cfg.nproc_rlimit and cfg.max_procs:
        # RLIMIT_NPROC counts every process of the real uid, so the user's others are added
        # (approximate: the fallback where no pids cgroup can be made)
        n = cfg.pids_max + _processes_of(os.getuid())
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


def _spawn(cfg: LaunchConfig, cgroup: str | None, out_fd: int, err_fd: int, become=None) -> int:
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
            os.chdir(cfg.cwd)
            if become is not None:
                os.close(w_err)  # started: from here the run's own failures are its output
                w_err = -1
                become(cfg)
            os.execve(cfg.exe, cfg.argv, cfg.env)
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


def _write_result(rundir: str, result: RunRecord, tails: dict[str, _Tail]) -> None:
    for name, t in tails.items():
        with open(os.path.join(rundir, name), "wb") as fh:
            fh.write(t.value())
    tmp = os.path.join(rundir, "result.bin.tmp")
    with open(tmp, "wb") as fh:
        marshal.dump(result.to_dict(), fh)
    os.replace(tmp, os.path.join(rundir, "result.bin"))


def _exit_status(status: int) -> int:
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _prepare_box(cfg: LaunchConfig, result: RunRecord) -> int:
    """The cold launcher's box (:func:`.proctools.mount_box`) in a namespace of its own, seen
    by the bubblewrap it starts; returns a descriptor of ``box/work``."""
    try:
        tools.enter_private_mounts()
        size, result.box = cfg.box_bytes, "tmpfs"
    except OSError:  # no user namespace here: a plain folder (no bound on what is written)
        size, result.box = None, "folder"
    box = tools.mount_box(cfg.rundir, size)
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


def _box_problem(cfg: LaunchConfig, exc: OSError) -> str:
    import errno

    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return (f"the files copied into the run's folder do not fit in its {cfg.box_bytes} "
                "bytes (--max-disk)")
    return f"cannot prepare the run's folder: {exc}"


def _copy_back_to(rundir: str, box_fd: int, cfg: LaunchConfig) -> None:
    try:
        dst = os.open(os.path.join(rundir, "work"), os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        tools.copy_back(box_fd, dst, skip=cfg.image_name)
    finally:
        os.close(dst)
        os.close(box_fd)


class _Pipes:
    """The command's main process (a pidfd) and its output pipes, polled together: each
    chunk goes to its tail, a pipe at end of file is forgotten."""

    def __init__(self, pid: int, streams: dict[int, _Tail]) -> None:
        self.pidfd = os.pidfd_open(pid)
        self.poller = select.poll()
        self.streams = streams
        for fd in (self.pidfd, *streams):
            self.poller.register(fd, select.POLLIN)

    def pump(self, fd: int) -> None:
        """Keep one chunk of an output pipe; forget the pipe at end of file."""
        chunk = os.read(fd, 1 << 16)
        if chunk:
            self.streams[fd].add(chunk)
        else:
            self.poller.unregister(fd)
            del self.streams[fd]

    def wait(self, deadline: float) -> bool:
        """Read the pipes until the main process exits (``True``) or ``deadline`` passes."""
        while True:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                return False
            exited = False
            for fd, _ in self.poller.poll(remaining * 1000.0):
                if fd == self.pidfd:
                    exited = True
                    continue
                self.pump(fd)
            if exited:
                return True

    def drain(self, within_s: float = 2.0) -> None:
        """Once every writer is gone: read what is left (for at most ``within_s``)."""
        self.poller.unregister(self.pidfd)
        os.close(self.pidfd)
        until = time.perf_counter() + within_s
        while self.streams and time.perf_counter() < until:
            for fd, _ in self.poller.poll(100):
                self.pump(fd)


def _account(result: RunRecord, cgroup: str | None) -> None:
    """A timed-out run's CPU account, before its processes are killed: CPU time, wait for a
    CPU, its runnable threads and CPUs, whether it lowered its priority."""
    alive = tools.descendants(os.getpid())
    alive += tools.cgroup_pids(cgroup) if cgroup else []
    alive = sorted(set(alive))  # a process of both counts once
    result.cpu_ms, result.wait_ms = tools.schedstat(alive)
    result.lowered_priority = tools.lowered_priority(alive)
    result.runnable, result.cpus = tools.runnable_threads(alive)


def run(cfg: LaunchConfig, *, become=None, own_cgroup: str | None = None) -> int:
    """Run one command as ``cfg`` says; returns the exit status.

    ``become``: see :func:`_spawn` (the warm server's runs). ``own_cgroup``: the run's
    cgroup, under ``cfg.cgroup_parent``, that this process is already in
    (:func:`.proctools.enter_cgroup`); otherwise the run's cgroup is made here and the command
    moved into it."""
    rundir = cfg.rundir
    tails = {"stdout": _Tail(cfg.max_output), "stderr": _Tail(cfg.max_output)}
    result = RunRecord()
    # --max-procs 0: no process limit (the cgroup still holds the run's processes for cleanup)
    pids_max = cfg.pids_max if cfg.max_procs else "max"
    if own_cgroup:
        cgroup = _limit_own_cgroup(own_cgroup, pids_max)
    else:
        cgroup = _make_cgroup(cfg.cgroup_parent, pids_max)
    attach = None if own_cgroup else cgroup
    cleaned = False
    try:
        if cgroup is None and cfg.cgroup_parent and cfg.max_procs:
            # the parent took a probe's pids cgroup: failing now, run nothing rather than run
            # without the process limit (fail closed)
            result.harness_error = (
                f"cannot create the run's pids cgroup under {cfg.cgroup_parent}: "
                f"--max-procs {cfg.max_procs} cannot be enforced, so the command was not run")
            cleaned = True
            return 0
        box_fd = None
        if cfg.box_bytes and become is None:  # a cold run under bubblewrap
            try:
                box_fd = _prepare_box(cfg, result)
            except OSError as exc:
                result.harness_error = _box_problem(cfg, exc)
                cleaned = True
                return 0
        r_out, w_out = os.pipe()
        r_err, w_err = os.pipe()
        start = time.perf_counter()
        try:
            pid = _spawn(cfg, attach, w_out, w_err, become)
        except OSError as exc:
            result.error = f"cannot start command: {exc}"
            cleaned = True
            return 0
        finally:
            os.close(w_out)
            os.close(w_err)
        pipes = _Pipes(pid, {r_out: tails["stdout"], r_err: tails["stderr"]})
        result.timed_out = not pipes.wait(start + cfg.timeout_s)
        # in a sandbox nothing can leave the run's cgroup: reading it finds every process;
        # without one a process could move itself out, so /proc is scanned too
        scan = not cfg.sandboxed
        if result.timed_out:
            _account(result, cgroup)
            tools.kill_descendants(cgroup, scan=scan)
        result.rc = _exit_status(os.waitpid(pid, 0)[1])
        result.latency_ms = (time.perf_counter() - start) * 1000.0
        tools.kill_descendants(cgroup, scan=scan)
        cleaned = True
        pipes.drain()  # every writer is gone: what is left in the pipes
        result.pids_limit_hit = _pids_limit_hit(cgroup)
        if become is not None:  # a warm run that could not be prepared says why in its folder
            result.harness_error = _read_note(os.path.join(rundir, "harness_error"))
        if box_fd is not None:
            _copy_back_to(rundir, box_fd, cfg)
        return 0
    except Stopped:
        tools.kill_descendants(cgroup)
        _remove_cgroup(attach)
        tools.rmtree(rundir)
        return 128 + (_stop_signal or signal.SIGTERM)
    finally:
        if _stop_signal is None:
            if not cleaned:  # an unexpected error: still leave nothing behind
                tools.kill_descendants(cgroup)
            _remove_cgroup(attach)
            _write_result(rundir, result, tails)


def main(argv: list[str]) -> int:
    """Entry point: ``launcher.py LAUNCH_FILE`` (a marshal dict of a :class:`LaunchConfig`)."""
    with open(argv[1], "rb") as fh:
        cfg = LaunchConfig.from_dict(marshal.load(fh))
    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(s, on_stop_signal)
    try:
        tools.prctl(tools.PR_SET_CHILD_SUBREAPER, 1)
        tools.prctl(tools.PR_SET_PDEATHSIG, signal.SIGTERM)
        # not ptrace-attachable by the command it runs (which would stop the launcher and
        # with it the timeout): non-dumpable, and the command loses CAP_SYS_PTRACE
        tools.LIBC.prctl(tools.PR_SET_DUMPABLE, 0, 0, 0, 0)
        if os.getppid() != cfg.parent_pid:  # the harness died before PDEATHSIG was set
            tools.rmtree(cfg.rundir)
            return 128 + signal.SIGTERM
        return run(cfg)
    except Stopped:
        tools.kill_descendants(None)
        tools.rmtree(cfg.rundir)
        return 128 + (_stop_signal or signal.SIGTERM)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
