"""The harness side of the warm interpreter (fork server) of Python ``--cmd`` pipelines.

A command that runs a Python script (``python``, ``python3``, ``python3.X``, ``{python}`` or
a virtual environment's ``.../bin/python``, followed by a ``.py`` file or ``-m module``) is,
unless ``--no-warm`` (:attr:`RunSettings.warm` false), run through one server process per
command (:mod:`arenabench.eval.runs.warm_server`), started inside the same sandbox as a cold run
(same bubblewrap arguments, namespaces and visible folders) with the command's interpreter.
The server imports numpy and cv2 once; each image is a process forked from it that becomes
the run (see the server's docstring). What a script can tell: ``docs/warm-interpreter.md``.

Interface: :class:`WarmServers`, the
warm servers of one :class:`~arenabench.eval.runs.context.RunContext` and a
:class:`~arenabench.eval.runs.command.Runner` of its pipelines::

    servers.run(pipe, image_path) -> Prediction | None   # None: the image runs cold
    servers.stop(pipe)                                   # kill the pipeline's warm runs
    servers.close_idle(command)                          # end a command's idle servers
    servers.close()                                      # end every server (the context's end)

Servers are shared by every pipeline of the context with the same command, settings, folder
and dataset folder (``grade`` makes a pipeline per image); at most :data:`MAX_IDLE_SERVERS`
idle ones are kept. A server that cannot start, or whose runs cannot get their private
namespaces, makes that command run cold, with one warning line.
"""

from __future__ import annotations

import marshal
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import threading
from collections import OrderedDict
from pathlib import Path
from typing import TYPE_CHECKING

from arenabench.eval.scoring.results import HarnessError, Prediction

from .proctools import BOX_DIRS, RUN_GRACE_S, RunRecord, WarmLaunch
from .sandbox import SANDBOX_DIR, is_within, warn_once
from .slots import Held, hold
from .stale import WARM_PREFIX, make_warm_dir
from .warm_server import recv_message, send_message

if TYPE_CHECKING:
    from .command import Command, RunJob, RunPlace

#: Where a server's folder of private run directories appears in the sandbox (hidden from runs).
WARM_DIR = "/.arenabench-warm"
#: Where the server's pids-cgroup folder appears in the sandbox (hidden from runs).
CGROUP_DIR = "/.arenabench-cgroup"
#: Idle servers kept (least recently used ones beyond this are ended).
MAX_IDLE_SERVERS = 4
#: Seconds a server may take to import its modules and say it is ready.
START_TIMEOUT_S = 120.0
#: glibc tunables of the server process (inherited by its runs, as memory, not as environment).
SERVER_MALLOC_TUNABLES = "glibc.malloc.hugetlb=1"
#: Where glibc reads, at a process's start, whether transparent huge pages are left to
#: madvise: bound read-only into the server's sandbox (which has no /sys otherwise) and hidden
#: from its runs again, as the server's own folders are.
THP_SETTINGS = "/sys/kernel/mm/transparent_hugepage"

SERVER_SOURCE = Path(__file__).with_name("warm_server.py")
WARM_UP_SOURCE = Path(__file__).with_name("warm_up.py")
#: The stand-alone modules the server loads from source (in this order).
SERVER_MODULES = ("proctools", "launcher", "warm_up")
#: What a Python interpreter's file is called (``python``, ``python3``, ``python3.12``).
KEEPER = str(Path(__file__).with_name("warm_keeper.py"))


class _Waiter:
    """One warm run waited for: its end, its exit status, its run slot."""

    def __init__(self, pipe: RunJob) -> None:
        self.pipe = pipe
        self.done = threading.Event()
        self.rc: int | None = None
        self.slot: Held | None = None  # its run slot, given back as soon as the run has ended

    def ended(self, rc: int | None) -> None:
        self.rc = rc
        if self.slot is not None:
            self.slot.release()
        self.done.set()


class WarmServer:
    """One server process (in its sandbox) and the runs it has under way.

    Parameters
    ----------
    command : Command
        The command whose script it runs (``command.warm`` is set).
    image_path : Path
        The first image (its folder is hidden in the sandbox where it lies in a visible one).
    context : RunPlace
        Its remover (the runs' folders) and run slots.
    """

    def __init__(self, command: Command, image_path: Path, context: RunPlace) -> None:
        assert command.warm is not None
        self.command = command
        self.target = command.warm
        self.context = context
        self.isolate = command.sandboxed
        self.home = make_warm_dir()  # a random name; its owner in a file (stale)
        self.cgroup: str | None = None
        self.keep: list[str] = []
        self._lock = threading.Lock()
        self._waiting: dict[str, _Waiter] = {}
        self.dead = False
        self.proc: subprocess.Popen | None = None
        self.sock: socket.socket | None = None
        try:
            self._start(image_path)
        except BaseException:
            self.close()
            raise

    def _start(self, image_path: Path) -> None:
        command = self.command
        base_work, base_tmp = os.path.join(self.home, "work"), os.path.join(self.home, "tmp")
        for name in BOX_DIRS:  # the server's own folders (each run mounts its box over them)
            os.mkdir(os.path.join(self.home, name))
        python = command.executable or sys.executable
        ours, theirs = socket.socketpair()
        self.sock = ours
        # the folder on its command line names the server in ps (and in the tests)
        server = [python, "-c", SERVER_SOURCE.read_text(), str(theirs.fileno()), self.home]
        if self.isolate:
            if command.cgroup_parent:
                # a random name, not a count of servers: nothing in it tells one server
                # (a first run's, a phase check's) from another
                cg = os.path.join(command.cgroup_parent,
                                  f"{WARM_PREFIX}{os.getpid()}-{secrets.token_hex(6)}")
                os.mkdir(cg)
                self.cgroup = cg
            argv = command.bwrap_argv(self.home, image_path)
            extra = ["--bind", self.home, WARM_DIR]
            # read by the server's glibc at its start only; hidden from the runs again
            extra += ["--ro-bind-try", THP_SETTINGS, THP_SETTINGS]
            if self.cgroup:
                extra += ["--bind", self.cgroup, CGROUP_DIR]
            at = argv.index("--remount-ro")
            argv = argv[:at] + extra + argv[at:] + server
            env = command.env(SANDBOX_DIR, "/tmp")
        else:
            argv, env = server, command.env(base_work, base_tmp)
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
        self.keep = [p for p in command.visible if p == "/tmp" or p.startswith("/tmp/")]
        private = sorted({os.path.dirname(a) for a in command.args
                          if os.path.isabs(a) and os.path.isfile(a)})
        here = Path(__file__).parent
        send_message(ours, {
            "parent_pid": 0 if self.isolate else self.proc.pid, "isolate": self.isolate,
            "sources": {name: (here / f"{name}.py").read_text() for name in SERVER_MODULES},
            "script": self.target.script, "private_dirs": private,
        })
        ours.settimeout(START_TIMEOUT_S)
        try:
            hello = recv_message(ours)
        except OSError as exc:
            hello = {"error": str(exc)}
        ours.settimeout(None)
        if not hello or not hello.get("ready"):
            log_tail = Path(self.home, "server.log").read_bytes()[-300:].decode(errors="replace")
            why = log_tail.strip().splitlines()[-1:] or [(hello or {}).get("error", "no answer")]
            raise RuntimeError(f"the warm server did not start: {why[0]}")
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
                del waiter  # held till the next message, it would keep its pipeline alive
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

    def run(self, pipe: RunJob, image_path: Path) -> Prediction | None:
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
            problem = pipe.command.fill_workdir(work, Path(image_path))
            if problem:
                raise HarnessError(problem)
            return self._run_in(pipe, image_path, token, rundir, work, tmp)
        finally:
            self.context.remover.remove_later(rundir)  # the worker goes on meanwhile

    def _run_in(self, pipe: RunJob, image_path: Path, token: str, rundir: str,
                work: str, tmp: str) -> Prediction | None:
        command = pipe.command
        if self.isolate:
            view = f"{WARM_DIR}/{token}"
            cmd, env = command.argv_for(image_path), command.env(SANDBOX_DIR, "/tmp")
            env["PWD"] = SANDBOX_DIR  # as bubblewrap's --chdir sets it
            cgroup_parent = CGROUP_DIR if self.cgroup else None
        else:
            view = rundir
            cmd, env = command.argv_for(image_path, image_dir=work), command.env(work, tmp)
            cgroup_parent = command.cgroup_parent
        t = self.target
        if t.module:
            target = {"module": t.module, "script": None, "argv": [t.module, *cmd[3:]],
                      "path0": ""}
        else:
            target = {"module": None, "script": t.script, "argv": cmd[1:],
                      "path0": os.path.dirname(os.path.realpath(t.script or ""))}
        # the run's keeper (outside its PID namespace) is one more process of the cgroup
        cfg = command.launch_config(
            exe=cmd[0], argv=cmd, env=env, cwd=f"{view}/work", rundir=view,
            image_path=image_path, cgroup_parent=cgroup_parent,
            extra_procs=int(self.isolate), parent_pid=0,
            warm=WarmLaunch(isolate=self.isolate,
                            hide=[WARM_DIR] + ([CGROUP_DIR] if self.cgroup else []),
                            hide_if_there=[THP_SETTINGS], keep=self.keep))
        waiter = _Waiter(pipe)
        with self._lock:
            if self.dead:
                return None
            self._waiting[token] = waiter
        lim = command.limits
        try:
            if pipe.stopped:  # stopped before its waiter was there for stop() to find
                return Prediction(status="crash", message="interrupted")
            waiter.slot = hold(self.context.slots, lambda: pipe.stopped)
            if waiter.slot is None:
                return Prediction(status="crash", message="interrupted")
            assert self.sock is not None
            try:
                send_message(self.sock, {"op": "run", "id": token, "cfg": cfg.to_dict(),
                                         "target": target})
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
            raw = marshal.loads(Path(rundir, "result.bin").read_bytes())
            result = RunRecord.from_dict(raw)
        except (OSError, ValueError, EOFError, TypeError):
            if pipe.stopped:
                return Prediction(status="crash", message="interrupted")
            # the server or the run's manager failed (the harness's code, out of the run's
            # reach): never the script's verdict; this server ends, the image runs cold
            with self._lock:
                self.dead = True
            return None
        out = Path(rundir, "stdout").read_bytes().decode("utf-8", errors="replace")
        err = Path(rundir, "stderr").read_bytes().decode("utf-8", errors="replace")
        return command.interpret(result, out, err, work)

    def kill(self, token: str) -> None:
        """End one run (its manager kills its processes and removes its directory)."""
        try:
            assert self.sock is not None
            send_message(self.sock, {"op": "kill", "id": token})
        except OSError:
            pass

    def stop(self, pipe: RunJob) -> None:
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


#: The image-folder parts of server keys kept per context (beyond this the cache starts again).
_MAX_FOLDER_PARTS = 4096


class WarmServers:
    """The warm servers of one :class:`~arenabench.eval.runs.context.RunContext`: a
    :class:`~arenabench.eval.runs.command.Runner` of its Python-script pipelines (see the module
    docstring)."""

    def __init__(self, context: RunPlace) -> None:
        self.context = context
        self._lock = threading.Lock()
        self._servers: OrderedDict[tuple, WarmServer] = OrderedDict()
        self._cold: set[tuple] = set()
        self._start_locks: dict[tuple, threading.Lock] = {}
        #: the image-folder part of a server's key, by (command, image folder as named):
        #: whether the folder lies in a visible one is found once
        self._folder_parts: dict[tuple, str] = {}
        self._generation = 0  # close() counts: a server started across a close() ends

    def servers(self) -> list[WarmServer]:
        """The servers running now (least recently used first)."""
        with self._lock:
            return [s for s in self._servers.values() if not s.dead]

    @staticmethod
    def _command_key(command: Command) -> tuple:
        return (command.template, command.base_dir, command.settings, command.sandbox,
                command.executable)

    def _key(self, command: Command, image_path: Path) -> tuple:
        """Servers are shared by the same command, settings and folder; under bubblewrap also
        by the image folder when it lies inside a visible folder (the sandbox hides it)."""
        key = self._command_key(command)
        named = (key, os.path.dirname(os.path.abspath(image_path)))
        with self._lock:
            part = self._folder_parts.get(named)
        if part is None:
            folder = str(Path(os.path.realpath(image_path)).parent)
            hidden = command.sandboxed and any(is_within(folder, v) for v in command.visible)
            part = folder if hidden else ""
            with self._lock:
                if len(self._folder_parts) >= _MAX_FOLDER_PARTS:
                    self._folder_parts.clear()
                self._folder_parts[named] = part
        return (*key, part)

    def _live(self, key: tuple) -> WarmServer | None:
        """The key's running server (marked most recently used), with the lock held."""
        server = self._servers.get(key)
        if server is None or server.dead:
            return None
        self._servers.move_to_end(key)
        return server

    def server_for(self, pipe: RunJob, image_path: Path) -> WarmServer | None:
        """The running server of ``pipe``'s command for this image's folder, started when
        there is none (``None``: the command runs cold, said once)."""
        key = self._key(pipe.command, image_path)
        with self._lock:
            if key in self._cold:
                return None
            server = self._live(key)
            if server is not None:
                return server
            start_lock = self._start_locks.setdefault(key, threading.Lock())
        # one start per key at a time; the runs of other servers go on meanwhile (grade: a
        # team's server starts while the other worker finishes the team before)
        with start_lock:
            with self._lock:
                if key in self._cold:
                    return None
                server = self._live(key)
                if server is not None:
                    return server
                dead = self._servers.pop(key, None)
                generation = self._generation
            if dead is not None:
                dead.close()
            try:
                server = WarmServer(pipe.command, image_path, self.context)
            except (OSError, RuntimeError, ValueError) as exc:
                with self._lock:
                    self._cold.add(key)
                warn_once(f"{exc}; {pipe.name!r} runs with one Python process per image")
                return None
            with self._lock:
                if self._generation != generation:  # the context closed meanwhile
                    ends = [server]
                    server = None
                else:
                    self._servers[key] = server
                    idle = [k for k, s in self._servers.items() if k != key and not s.busy]
                    ends = [self._servers.pop(k)
                            for k in idle[: max(0, len(self._servers) - MAX_IDLE_SERVERS)]]
        for old in ends:
            old.close()
        return server

    def run(self, pipe: RunJob, image_path: Path) -> Prediction | None:
        """Run one image through the command's warm server; ``None`` when it must run cold
        (no server, or the server failed the run: its next run starts a new one).

        Raises
        ------
        HarnessError
            When the run's folder cannot be made or filled.
        """
        server = self.server_for(pipe, image_path)
        return None if server is None else server.run(pipe, image_path)

    def stop(self, pipe: RunJob) -> None:
        """Kill ``pipe``'s running warm runs."""
        with self._lock:
            servers = list(self._servers.values())
        for server in servers:
            server.stop(pipe)

    def close_idle(self, command: Command) -> None:
        """End the idle servers of ``command`` (the end of an evaluation)."""
        prefix = self._command_key(command)
        with self._lock:
            ends = [k for k, s in self._servers.items()
                    if k[: len(prefix)] == prefix and not s.busy]
            servers = [self._servers.pop(k) for k in ends]
        for server in servers:
            server.close()

    def close(self) -> None:
        """End every server (their runs are killed, their folders removed); a later run
        starts its server again."""
        with self._lock:
            self._generation += 1
            servers = list(self._servers.values())
            self._servers.clear()
            self._cold.clear()
        for server in servers:
            server.close()
