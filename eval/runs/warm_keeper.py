"""The keeper of one warm server: the server's parent outside the sandbox (standard library
only; run as ``python -I -S warm_keeper.py HARNESS_PID HOME CGROUP FD -- COMMAND...``;
``FD`` is passed on to the command and closed in the keeper).

It asks for SIGTERM when the harness dies (``PR_SET_PDEATHSIG``, even after SIGKILL of the
harness), becomes a child subreaper, starts ``COMMAND`` (bubblewrap with the server inside,
or the server itself with ``--sandbox none``) with ``PR_SET_PDEATHSIG`` = SIGKILL, and when
the command ends or the harness dies: kills it and every process left under it, then removes
the server's folder ``HOME`` and its pids cgroup ``CGROUP`` (``-`` for none) with the runs'
cgroups in it, killing any process still in one (:func:`proctools.kill_cgroup_tree`).

``PR_SET_PDEATHSIG`` is sent when the *thread* that started the keeper ends, and again for
every thread it is handed to after that (a harness killed with SIGKILL ends its threads one
by one): a SIGTERM while the harness is still the keeper's parent is one of those and is
ignored, and the clean-up runs once however many signals follow.
"""

import os
import signal
import sys
import time


class _Stop(Exception):
    pass


_harness = 0
_stopping = False
tools = None  # proctools, loaded by main() from beside this file


def _on_signal(signum, frame):
    global _stopping
    if _stopping:  # cleaning up already
        return
    if signum == signal.SIGTERM and os.getppid() == _harness:
        return  # PR_SET_PDEATHSIG for one of the harness's threads, not for the harness
    _stopping = True
    raise _Stop()


def _load_proctools():
    """``proctools.py`` beside this file (standard library only; the harness, the launcher and
    the warm server share it)."""
    import importlib.util

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "proctools.py")
    spec = importlib.util.spec_from_file_location("_arenabench_proctools", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def _reap_all(deadline_s):
    """Wait for every descendant (killing the rest after ``deadline_s`` seconds)."""
    deadline = time.monotonic() + deadline_s
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid:
            continue
        if time.monotonic() > deadline:
            for p in tools.descendants(os.getpid()):
                try:
                    os.kill(p, signal.SIGKILL)
                except OSError:
                    pass
        time.sleep(0.01)


def main(argv):
    """Entry point (see the module docstring); returns the command's exit status."""
    global _harness, tools
    tools = _load_proctools()
    parent, home, cgroup, fd, cmd = int(argv[1]), argv[2], argv[3], int(argv[4]), argv[6:]
    _harness = parent
    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(s, _on_signal)
    status, pid = 0, 0
    try:
        tools.LIBC.prctl(tools.PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
        tools.LIBC.prctl(tools.PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        if os.getppid() == parent:
            pid = os.fork()
            if pid == 0:
                try:
                    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
                        signal.signal(s, signal.SIG_DFL)
                    tools.LIBC.prctl(tools.PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
                    os.execv(cmd[0], cmd)
                finally:
                    os._exit(127)
            os.close(fd)
            _, status = os.waitpid(pid, 0)
            pid = 0
    except _Stop:  # the harness has ended (or a stop signal): the command goes now
        if pid:
            os.kill(pid, signal.SIGKILL)
            _, status = os.waitpid(pid, 0)
    _reap_all(5.0)  # a command forked but not yet known here is among these
    tools.rmtree(home, tries=50)
    if cgroup != "-":  # the runs' cgroups, and whatever a run left in them, go too
        tools.kill_cgroup_tree(cgroup)
    return os.waitstatus_to_exitcode(status) if status else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
