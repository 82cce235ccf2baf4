"""The harness side of the warm interpreter (fork server) of Python ``--cmd`` pipelines.

A command that runs a Python script (``python``, ``python3``, ``python3.X``, ``{python}`` or
a virtual environment's ``.../bin/python``, followed by a ``.py`` file or ``-m module``) is,
unless ``--no-warm`` (:attr:`RunSettings.warm` false), run through one server process per
command (:mod:`arenabench.eval.runs.warm_server`), started inside the same sandbox as a cold run
(same bubblewrap arguments, namespaces and visible folders) with the command's interpreter.
The server imports numpy and cv2 once; each image is a process forked from it that becomes
the run (see the server's docstring). What a script can tell: ``docs/warm-interpreter.md``.

Interface (used by :class:`~arenabench.eval.runs.command.CommandPipeline`)::

    warm_target(argv) -> WarmTarget | None     # is the (resolved) command a Python script?
    run_warm(pipe, target, image_path) -> Prediction | None   # None: run it cold
    stop_warm(pipe)                            # kill the pipeline's running warm runs
    close_warm(pipe)                           # end the pipeline's idle servers
    close_all()                                # end every server (also at exit)

Servers are shared by every pipeline with the same command, settings, folder and dataset
folder (``grade`` makes a pipeline per image); at most :data:`MAX_IDLE_SERVERS` idle ones
are kept. A server that cannot start, or whose runs cannot get their private namespaces,
makes that command run cold, with one warning line.
"""

from __future__ import annotations

import atexit
import itertools
import marshal
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from arenabench.eval.scoring.results import HarnessError, Prediction

from .launcher import BOX_DIRS
from .remover import remove_later, wait_removed
from .slots import Held, hold
from .stale import WARM_PREFIX, warm_dir_prefix
from .warm_server import recv_message, send_message

if TYPE_CHECKING:
    from .command import CommandPipeline

#: Where a server's folder of private run directories appears in the sandbox (hidden from runs).
WARM_DIR = "/.arenabench-warm"
#: Where the server's pids-cgroup folder appears in the sandbox (hidden from runs).
CGROUP_DIR = "/.arenabench-cgroup"
#: Idle servers kept (least recently used ones beyond this are ended).
MAX_IDLE_SERVERS = 4
#: Seconds a server may take to import its modules and say it is ready.
START_TIMEOUT_S = 120.0
#: Seconds the harness waits for a run's end beyond the command's own timeout.
RUN_GRACE_S = 30.0
#: glibc tunables of the server process (inherited by its runs, as memory, not as environment).
SERVER_MALLOC_TUNABLES = "glibc.malloc.hugetlb=1"
#: Where glibc reads, at a process's start, whether transparent huge pages are left to
#: madvise: bound read-only into the server's sandbox (which has no /sys otherwise) and hidden
#: from its runs again, as the server's own folders are.
THP_SETTINGS = "/sys/kernel/mm/transparent_hugepage"

SERVER_SOURCE = Path(__file__).with_name("warm_server.py")
LAUNCHER_SOURCE = Path(__file__).with_name("launcher.py")
WARM_UP_SOURCE = Path(__file__).with_name("warm_up.py")
_PYTHON_NAME = re.compile(r"python(\d+(\.\d+)*)?")
_MODULE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
KEEPER = str(Path(__file__).with_name("warm_keeper.py"))


@dataclass(frozen=True)
class WarmTarget:
    """What a warm run executes: a script file or a module (exactly one is set)."""

    script: str | None = None
    module: str | None = None


def warm_target(argv: list[str]) -> WarmTarget | None:
    """The script or module that ``argv`` (the command's resolved arguments, before
    ``{image}`` substitution) runs with a Python interpreter, or ``None`` when it is not
    ``PYTHON FILE.py ...`` or ``PYTHON -m MODULE ...``."""
    if len(argv) < 2:
        return None
    if argv[0] != "{python}" and not _PYTHON_NAME.fullmatch(os.path.basename(argv[0])):
        return None
    if argv[1] == "-m" and len(argv) > 2 and _MODULE_NAME.fullmatch(argv[2]):
        return WarmTarget(module=argv[2])
    script = argv[1]
    if script.endswith(".py") and "{" not in script and os.path.isabs(script) and \
            os.path.isfile(script):
        return WarmTarget(script=script)
    return None


class _Waiter:
    def __init__(self, pipe: CommandPipeline) -> None:
        self.pipe = pipe
        self.done = threading.Event()
        self.rc: int | None = None
        self.slot: Held | None = None  # its run slot, given back as soon as the run has ended

    def ended(self, rc: int | None) -> None:
        self.rc = rc
        if self.slot is not None:
            self.slot.release()
        self.done.set()


_counter = itertools.count()


class WarmServer:
    """One server process (in its sandbox) and the runs it has under way."""

    def __init__(self, pipe: CommandPipeline, image_path: Path, target: WarmTarget) -> None:
        self.target = target
        self.isolate = pipe.sandbox == "bwrap"
        self.home = tempfile.mkdtemp(prefix=warm_dir_prefix())  # names its owner: stale_runs
        self.cgroup: str | None = None
        self.keep: list[str] = []
        self._lock = threading.Lock()
        self._waiting: dict[str, _Waiter] = {}
        self.dead = False
        self.proc: subprocess.Popen | None = None
        self.sock: socket.socket | None = None
        try:
            self._start(pipe, image_path)
        except BaseException:
            self.close()
            raise

    def _start(self, pipe: CommandPipeline, image_path: Path) -> None:
        base_work, base_tmp = os.path.join(self.home, "work"), os.path.join(self.home, "tmp")
        for name in BOX_DIRS:  # the server's own folders (each run mounts its box over them)
            os.mkdir(os.path.join(self.home, name))
        python = pipe._executable or sys.executable
        ours, theirs = socket.socketpair()
        self.sock = ours
        # the folder on its command line names the server in ps (and in the tests)
        server = [python, "-c", SERVER_SOURCE.read_text(), str(theirs.fileno()), self.home]
        if self.isolate:
            if pipe._cgroup:
                cg = os.path.join(pipe._cgroup, f"{WARM_PREFIX}{os.getpid()}-{next(_counter)}")
                os.mkdir(cg)
                self.cgroup = cg
            argv = pipe._bwrap_argv(self.home, image_path)
            extra = ["--bind", self.home, WARM_DIR]
            # read by the server's glibc at its start only; hidden from the runs again
            extra += ["--ro-bind-try", THP_SETTINGS, THP_SETTINGS]
            if self.cgroup:
                extra += ["--bind", self.cgroup, CGROUP_DIR]
            at = argv.index("--remount-ro")
            argv = argv[:at] + extra + argv[at:] + server
            from .sandbox import SANDBOX_DIR

            env = pipe._env(SANDBOX_DIR, "/tmp")
        else:
            argv, env = server, pipe._env(base_work, base_tmp)
        # the server's malloc (and so every run's, a fork of it) backs its big blocks with
        # transparent huge pages where the kernel leaves them to madvise: a run's fresh
        # image buffers fault in 2 MiB at a time (the runs' environment does not name it)
        env.setdefault("GLIBC_TUNABLES", SERVER_MALLOC_TUNABLES)
        log = open(os.path.join(self.home, "server.log"), "wb")
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-I", "-S", KEEPER, str(os.getpid()), self.home,
                 self.cgroup or "-", str(theirs.fileno()), "--", *argv],
                stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env, cwd=base_work,
                pass_fds=(theirs.fileno(),),
            )
        finally:
            log.close()
            theirs.close()
        self.keep = [p for p in pipe._visible_paths() if p == "/tmp" or p.startswith("/tmp/")]
        private = sorted({os.path.dirname(a) for a in pipe._resolved_args()
                          if os.path.isabs(a) and os.path.isfile(a)})
        send_message(ours, {
            "parent_pid": 0 if self.isolate else self.proc.pid, "isolate": self.isolate,
            "launcher_source": LAUNCHER_SOURCE.read_text(), "script": self.target.script,
            "private_dirs": private, "warm_up_source": WARM_UP_SOURCE.read_text(),
        })
        ours.settimeout(START_TIMEOUT_S)
        try:
            hello = recv_message(ours)
        except OSError as exc:
            raise RuntimeError(f"the warm server did not start: {exc}") from None
        ours.settimeout(None)
        if not hello or not hello.get("ready"):
            log_tail = Path(self.home, "server.log").read_bytes()[-300:].decode(errors="replace")
            raise RuntimeError(f"the warm server did not start: {log_tail.strip()}")
        if hello.get("isolation"):
            raise RuntimeError(f"warm runs cannot get private namespaces here: "
                               f"{hello['isolation']}")
        if hello.get("cold"):
            raise RuntimeError(hello["cold"])
        threading.Thread(target=self._read, name="arenabench-warm", daemon=True).start()

    def _read(self) -> None:
        assert self.sock is not None
        try:
            while True:
                msg = recv_message(self.sock)
                if msg is None:
                    break
                with self._lock:
                    waiter = self._waiting.get(msg["id"])
                if waiter is not None:
                    waiter.ended(msg["rc"])
        except (OSError, ValueError):
            pass
        with self._lock:
            self.dead = True
            waiters = list(self._waiting.values())
        for w in waiters:
            w.done.set()

    @property
    def busy(self) -> bool:
        """Whether runs are under way."""
        with self._lock:
            return bool(self._waiting)

    def run(self, pipe: CommandPipeline, image_path: Path) -> Prediction | None:
        """Run ``pipe``'s command on one image as a warm run (never raises for the
        command's own failures); ``None`` when the server failed it (the server is then
        ended, and the image runs cold).

        Raises
        ------
        HarnessError
            When the run's folder cannot be made or filled.
        """
        token = secrets.token_hex(12)
        rundir = os.path.join(self.home, token)
        work, tmp = os.path.join(rundir, "work"), os.path.join(rundir, "tmp")
        try:
            os.mkdir(rundir, 0o700)
        except OSError as exc:
            raise HarnessError(f"cannot make a run's folder in {self.home}: "
                               f"{exc.strerror or exc}") from None
        try:
            try:
                os.mkdir(work)
                os.mkdir(tmp)
            except OSError as exc:
                raise HarnessError(f"cannot make a run's folder in {rundir}: "
                                   f"{exc.strerror or exc}") from None
            problem = pipe.fill_workdir(work, Path(image_path))
            if problem:
                raise HarnessError(problem)
            return self._run_in(pipe, image_path, token, rundir, work, tmp)
        finally:
            remove_later(rundir)  # the worker goes on with its next image meanwhile

    def _run_in(self, pipe: CommandPipeline, image_path: Path, token: str, rundir: str,
                work: str, tmp: str) -> Prediction | None:
        from .sandbox import SANDBOX_DIR

        lim = pipe.limits
        if self.isolate:
            view = f"{WARM_DIR}/{token}"
            cmd, env = pipe.argv(image_path), pipe._env(SANDBOX_DIR, "/tmp")
            env["PWD"] = SANDBOX_DIR  # as bubblewrap's --chdir sets it
            cgroup_parent = CGROUP_DIR if self.cgroup else None
        else:
            view = rundir
            cmd, env = pipe.argv(image_path, image_dir=work), pipe._env(work, tmp)
            cgroup_parent = pipe._cgroup
        t = self.target
        if t.module:
            target = {"module": t.module, "script": None, "argv": [t.module, *cmd[3:]],
                      "path0": ""}
        else:
            target = {"module": None, "script": t.script, "argv": cmd[1:],
                      "path0": os.path.dirname(os.path.realpath(t.script or ""))}
        cfg = {
            "exe": cmd[0], "argv": cmd, "env": env, "cwd": f"{view}/work", "rundir": view,
            "timeout_s": lim.timeout_s, "memory_bytes": lim.memory_bytes,
            "max_file_size": lim.max_file_size, "max_output": lim.max_output,
            # the run's keeper (outside its PID namespace) is one more process of the cgroup
            "max_procs": lim.max_procs, "pids_max": lim.max_procs + int(self.isolate),
            "cgroup_parent": cgroup_parent, "sandboxed": self.isolate,
            "box_bytes": lim.disk_bytes if self.isolate else None,
            "image_name": pipe.image_name(image_path),
            "nproc_rlimit": cgroup_parent is None and os.getuid() != 0, "parent_pid": 0,
            "warm_isolate": self.isolate,
            "warm_hide": [WARM_DIR] + ([CGROUP_DIR] if self.cgroup else []),
            "warm_hide_if_there": [THP_SETTINGS],
            "warm_keep": self.keep,
        }  # fmt: skip
        waiter = _Waiter(pipe)
        with self._lock:
            if self.dead:
                return None
            self._waiting[token] = waiter
        try:
            if pipe._stopped:  # stopped before its waiter was there for stop() to find
                return Prediction(status="crash", message="interrupted")
            waiter.slot = hold(pipe.slots, lambda: pipe._stopped)
            if waiter.slot is None:
                return Prediction(status="crash", message="interrupted")
            assert self.sock is not None
            try:
                send_message(self.sock, {"op": "run", "id": token, "cfg": cfg, "target": target})
            except OSError:  # the server has ended: the image runs cold
                return None
            if not waiter.done.wait(lim.timeout_s + RUN_GRACE_S):
                self.kill(token)
                waiter.done.wait(10.0)
        finally:
            with self._lock:
                self._waiting.pop(token, None)
            if waiter.slot is not None:
                waiter.slot.release()
        try:
            result = marshal.loads(Path(rundir, "result.bin").read_bytes())
        except (OSError, ValueError, EOFError, TypeError):
            if pipe._stopped:
                return Prediction(status="crash", message="interrupted")
            # the server or the run's manager failed (the harness's code, out of the run's
            # reach): never the script's verdict; this server ends, the image runs cold
            with self._lock:
                self.dead = True
            return None
        out = Path(rundir, "stdout").read_bytes().decode("utf-8", errors="replace")
        err = Path(rundir, "stderr").read_bytes().decode("utf-8", errors="replace")
        return pipe._interpret(result, out, err, work)

    def kill(self, token: str) -> None:
        """End one run (its manager kills its processes and removes its directory)."""
        try:
            assert self.sock is not None
            send_message(self.sock, {"op": "kill", "id": token})
        except OSError:
            pass

    def stop(self, pipe: CommandPipeline) -> None:
        """End the runs of ``pipe``."""
        with self._lock:
            tokens = [k for k, w in self._waiting.items() if w.pipe is pipe]
        for token in tokens:
            self.kill(token)

    def close(self) -> None:
        """End the server (its runs are killed) and remove its folders."""
        with self._lock:
            self.dead = True
        if self.sock is not None:
            try:
                self.sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self.sock.close()
        if self.proc is not None:
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.send_signal(signal.SIGKILL)
                self.proc.wait()
        shutil.rmtree(self.home, ignore_errors=True)
        if self.cgroup:
            try:
                os.rmdir(self.cgroup)
            except OSError:
                pass


_registry_lock = threading.Lock()
_servers: OrderedDict[tuple, WarmServer] = OrderedDict()
_cold: set[tuple] = set()
_start_locks: dict[tuple, threading.Lock] = {}


#: The image-folder part of a server's key, by (command key, image folder as named): finding
#: the sandbox's visible folders reads the interpreter's site-packages (milliseconds per run).
_folder_parts: dict[tuple, str] = {}
_MAX_FOLDER_PARTS = 4096


def _key(pipe: CommandPipeline, image_path: Path | None) -> tuple:
    """Servers are shared by the same command, settings and folder; under bubblewrap also
    by the image folder when it lies inside a visible folder (the sandbox hides it)."""
    key = (pipe.template, pipe.base_dir, pipe.settings, pipe.sandbox, pipe._executable)
    if image_path is None:
        return key
    named = (key, os.path.dirname(os.path.abspath(image_path)))
    part = _folder_parts.get(named)
    if part is None:
        folder = str(Path(os.path.realpath(image_path)).parent)
        from .sandbox import is_within

        hidden = pipe.sandbox == "bwrap" and any(is_within(folder, v)
                                                  for v in pipe._visible_paths())
        part = folder if hidden else ""
        if len(_folder_parts) >= _MAX_FOLDER_PARTS:
            _folder_parts.clear()
        _folder_parts[named] = part
    return (*key, part)


def _live(key: tuple) -> WarmServer | None:
    """The key's running server (marked most recently used), with the registry lock held."""
    server = _servers.get(key)
    if server is None or server.dead:
        return None
    _servers.move_to_end(key)
    return server


def _server_for(pipe: CommandPipeline, target: WarmTarget, image_path: Path) -> WarmServer | None:
    key = _key(pipe, image_path)
    with _registry_lock:
        if key in _cold:
            return None
        server = _live(key)
        if server is not None:
            return server
        start_lock = _start_locks.setdefault(key, threading.Lock())
    # one start per key at a time; the runs of other servers go on meanwhile (grade: a
    # team's server starts while the other worker finishes the team before)
    with start_lock:
        with _registry_lock:
            if key in _cold:
                return None
            server = _live(key)
            if server is not None:
                return server
            dead = _servers.pop(key, None)
        if dead is not None:
            dead.close()
        try:
            server = WarmServer(pipe, image_path, target)
        except (OSError, RuntimeError, ValueError) as exc:
            with _registry_lock:
                _cold.add(key)
            from .sandbox import warn_once

            warn_once(f"{exc}; {pipe.name!r} runs with one Python process per image")
            return None
        with _registry_lock:
            _servers[key] = server
            idle = [k for k, s in _servers.items() if k != key and not s.busy]
            ends = [_servers.pop(k) for k in idle[: max(0, len(_servers) - MAX_IDLE_SERVERS)]]
    for old in ends:
        old.close()
    return server


def run_warm(pipe: CommandPipeline, target: WarmTarget, image_path: Path) -> Prediction | None:
    """Run one image through the command's warm server; ``None`` when it must run cold (no
    server, or the server failed the run: its next run starts a new one)."""
    server = _server_for(pipe, target, image_path)
    return None if server is None else server.run(pipe, image_path)


def stop_warm(pipe: CommandPipeline) -> None:
    """Kill ``pipe``'s running warm runs."""
    with _registry_lock:
        servers = list(_servers.values())
    for server in servers:
        server.stop(pipe)


def close_warm(pipe: CommandPipeline) -> None:
    """End the idle warm servers of ``pipe``'s command (the end of an evaluation)."""
    prefix = _key(pipe, None)
    with _registry_lock:
        ends = [k for k, s in _servers.items() if k[: len(prefix)] == prefix and not s.busy]
        servers = [_servers.pop(k) for k in ends]
    for server in servers:
        server.close()


def close_all() -> None:
    """End every warm server (their runs are killed, their folders removed), once the folders
    of finished runs are removed."""
    wait_removed()
    with _registry_lock:
        servers = list(_servers.values())
        _servers.clear()
        _cold.clear()
    for server in servers:
        server.close()


atexit.register(close_all)
