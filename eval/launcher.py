"""The per-run launcher of external commands: one small process that owns one run.

Started by :class:`arenabench.eval.external.CommandPipeline` as
``python -I -S .../launcher.py RUNDIR/launch.json`` (standard library only, so it starts
fast and imports nothing of the project). It

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
5. writes ``RUNDIR/stdout``, ``RUNDIR/stderr`` (the tails) and ``RUNDIR/result.json``.

``result.json``: ``rc`` (exit status, negative for a signal, ``null`` when not started),
``timed_out``, ``latency_ms`` (start of the command to the exit of its main process),
``stdout_bytes``/``stderr_bytes`` (total printed), ``pids_limit_hit`` (the cgroup refused a
fork), ``error`` (the command could not be started).
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import resource
import selectors
import shutil
import signal
import subprocess
import sys
import time

PR_SET_PDEATHSIG = 1
PR_SET_CHILD_SUBREAPER = 36

_stop_signal: int | None = None


class _Stop(Exception):
    pass


def _on_signal(signum: int, frame: object) -> None:
    global _stop_signal
    if _stop_signal is None:
        _stop_signal = signum
        raise _Stop()


def _prctl(option: int, value: int) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(option, value, 0, 0, 0) != 0:
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


def kill_descendants(cgroup: str | None = None) -> None:
    """SIGKILL and reap every descendant of this process (and everything in ``cgroup``)."""
    me = os.getpid()
    for _ in range(2000):
        pids = descendants(me)
        if cgroup:
            with contextlib.suppress(OSError):
                with open(os.path.join(cgroup, "cgroup.procs")) as fh:
                    pids += [int(p) for p in fh.read().split()]
        if not pids:
            _reap()
            return
        for pid in pids:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        _reap()
        time.sleep(0.001)


def _make_cgroup(parent: str | None, max_procs: int) -> str | None:
    if not parent:
        return None
    path = os.path.join(parent, f"arenabench-run-{os.getpid()}")
    try:
        os.mkdir(path)
        with open(os.path.join(path, "pids.max"), "w") as fh:
            fh.write(str(max_procs))
    except OSError:
        with contextlib.suppress(OSError):
            os.rmdir(path)
        return None
    return path


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
            kill_descendants(cgroup)
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
    # runs in the forked child, before exec
    if cgroup:
        with open(os.path.join(cgroup, "cgroup.procs"), "w") as fh:
            fh.write("0")
    _prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_AS, (cfg["memory_bytes"], cfg["memory_bytes"]))
    resource.setrlimit(resource.RLIMIT_FSIZE, (cfg["max_file_size"], cfg["max_file_size"]))
    if cfg.get("nproc_rlimit"):
        resource.setrlimit(resource.RLIMIT_NPROC, (cfg["max_procs"], cfg["max_procs"]))


def _write_result(rundir: str, result: dict, tails: dict[str, _Tail]) -> None:
    for name, t in tails.items():
        with open(os.path.join(rundir, name), "wb") as fh:
            fh.write(t.value())
    tmp = os.path.join(rundir, "result.json.tmp")
    with open(tmp, "w") as fh:
        json.dump(result, fh)
    os.replace(tmp, os.path.join(rundir, "result.json"))


def run(cfg: dict) -> int:
    """Run one command as described by ``cfg`` (the launch.json); returns the exit status."""
    rundir = cfg["rundir"]
    tails = {"stdout": _Tail(cfg["max_output"]), "stderr": _Tail(cfg["max_output"])}
    result: dict = {"rc": None, "timed_out": False, "latency_ms": 0.0, "error": "",
                    "pids_limit_hit": False}
    cgroup = _make_cgroup(cfg.get("cgroup_parent"), cfg["pids_max"])
    proc = None
    try:
        r_out, w_out = os.pipe()
        r_err, w_err = os.pipe()
        start = time.perf_counter()
        try:
            proc = subprocess.Popen(
                cfg["argv"], cwd=cfg["cwd"], env=cfg["env"], stdin=subprocess.DEVNULL,
                stdout=w_out, stderr=w_err, close_fds=True, start_new_session=True,
                preexec_fn=lambda: _child_setup(cfg, cgroup),
            )
        except (OSError, subprocess.SubprocessError) as exc:
            result["error"] = f"cannot start command: {exc}"
            return 0
        finally:
            os.close(w_out)
            os.close(w_err)
        deadline = start + cfg["timeout_s"]
        pidfd = os.pidfd_open(proc.pid)
        sel = selectors.DefaultSelector()
        sel.register(pidfd, selectors.EVENT_READ, None)
        sel.register(r_out, selectors.EVENT_READ, tails["stdout"])
        sel.register(r_err, selectors.EVENT_READ, tails["stderr"])
        exited = False
        while not exited:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                result["timed_out"] = True
                break
            for key, _ in sel.select(timeout=remaining):
                if key.data is None:
                    exited = True
                    continue
                chunk = os.read(key.fd, 1 << 16)
                if chunk:
                    key.data.add(chunk)
                else:
                    sel.unregister(key.fd)
        if exited:
            result["rc"] = proc.wait()
            result["latency_ms"] = (time.perf_counter() - start) * 1000.0
            kill_descendants(cgroup)
        else:
            kill_descendants(cgroup)
            result["rc"] = proc.wait()
            result["latency_ms"] = (time.perf_counter() - start) * 1000.0
        # every writer is gone: drain what is left in the pipes
        sel.unregister(pidfd)
        os.close(pidfd)
        drain_until = time.perf_counter() + 2.0
        while sel.get_map() and time.perf_counter() < drain_until:
            for key, _ in sel.select(timeout=0.1):
                chunk = os.read(key.fd, 1 << 16)
                if chunk:
                    key.data.add(chunk)
                else:
                    sel.unregister(key.fd)
        result["pids_limit_hit"] = _pids_limit_hit(cgroup)
        return 0
    except _Stop:
        kill_descendants(cgroup)
        _remove_cgroup(cgroup)
        shutil.rmtree(rundir, ignore_errors=True)
        return 128 + (_stop_signal or signal.SIGTERM)
    finally:
        if _stop_signal is None:
            kill_descendants(cgroup)
            _remove_cgroup(cgroup)
            _write_result(rundir, result, tails)


def main(argv: list[str]) -> int:
    """Entry point: ``launcher.py LAUNCH_JSON``."""
    with open(argv[1]) as fh:
        cfg = json.load(fh)
    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(s, _on_signal)
    try:
        _prctl(PR_SET_CHILD_SUBREAPER, 1)
        _prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != cfg["parent_pid"]:  # the harness died before PDEATHSIG was set
            shutil.rmtree(cfg["rundir"], ignore_errors=True)
            return 128 + signal.SIGTERM
        return run(cfg)
    except _Stop:
        shutil.rmtree(cfg["rundir"], ignore_errors=True)
        return 128 + (_stop_signal or signal.SIGTERM)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
