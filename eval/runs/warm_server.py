"""The warm interpreter (fork server) of a Python ``--cmd``: the code that runs in the sandbox.

Started by :mod:`arenabench.eval.runs.warm_client` as ``PYTHON -c <this source> FD FOLDER``
with the command's own interpreter, inside the same bubblewrap sandbox as a cold run (or
with ``--sandbox none`` without one). Standard library only, besides the modules it preloads
(``numpy``, ``cv2`` and the standard-library or installed modules that the script's
``import`` statements name, or those of the submission's own modules it imports, found with
:mod:`ast`; the script and the submission's modules are never run here).

Protocol (a socketpair passed as the inherited fd ``FD``): each message is a 4-byte big-endian
length followed by that many bytes of JSON. Harness to server first: the configuration
(``parent_pid``, ``isolate``, ``sources``: the source of ``proctools``, ``launcher`` and
``warm_up`` by name, ``script``, ``private_dirs``). Server to
harness: ``{"ready": true, "isolation": "", "cold": ""}``
once (``isolation`` names a problem with the per-run namespaces, ``cold`` why the command must
run cold after all (:func:`_shadowed`); ``""`` when all is well), then
``{"id": ID, "rc": N}`` when run ``ID`` has ended. Harness to server: ``{"op": "run", "id":
ID, "cfg": {...}, "target": {...}}`` (``cfg`` is a launch configuration of
:mod:`arenabench.eval.runs.launcher`) and ``{"op": "kill", "id": ID}``. End of file on the socket:
every run is killed and the server exits.

For each run a *run manager* (the launcher's role: child subreaper, pids cgroup, limits,
output tails, timeout, killing every process of the run, ``result.bin``) forked from the
server takes the run: a *standby*, forked ahead, that waits in a pids cgroup of its own for its
run (so the run starts in its cgroup by ``fork`` alone: moving a process into a cgroup waits
for an RCU grace period, 10-30 ms), or one forked for it (the first run, and where runs have
no pids cgroup). The server keeps :data:`STANDBYS` standbys and removes a standby's cgroup
once it has ended. The manager forks the *run* itself, which (under bubblewrap) enters new
user, mount, IPC, network and UTS namespaces, binds its private directory at ``/sandbox`` and
its own ``/tmp``, hides the server's folders, drops every capability, and then becomes the
script: ``sys.argv``, environment, working directory and signal dispositions as a fresh
interpreter has them, the script run as ``__main__`` with :mod:`runpy`, interpreter exit
(threads joined, ``atexit``, streams flushed) and its exit status. The server never runs a
script's code itself.
"""

import sys

#: What a fresh interpreter has imported before a script's first line (this source's first
#: statement sees just that): a cold run finds these, not a submission's modules of the same name.
_STARTUP_MODULES = frozenset(sys.modules)

import ast  # noqa: E402
import ctypes  # noqa: E402
import errno  # noqa: E402
import fcntl  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import select  # noqa: E402
import signal  # noqa: E402
import socket  # noqa: E402
import struct  # noqa: E402
import time  # noqa: E402
import types  # noqa: E402

SANDBOX_DIR = "/sandbox"
#: Exit status of a run that ended before its script because the harness could not prepare it
#: (its ``harness_error`` file says why).
HARNESS_ERROR_STATUS = 125
#: :mod:`.proctools` (sent as source by the harness; :func:`main` loads it).
tools = None


class _BecomeRunManager(BaseException):
    """Raised in a freshly forked run manager, to leave the server's loop: with the run's
    ``message``, or (a standby) with its end of the socket pair its run will come on and
    the cgroup parent it enters a cgroup under while it waits."""

    def __init__(self, message=None, *, request=None, cgroup_parent=None):
        super().__init__()
        self.message = message
        self.request = request
        self.cgroup_parent = cgroup_parent


def send_message(sock, obj):
    """One message of the harness <-> server protocol: a 4-byte big-endian length, then JSON
    (the harness side, :mod:`arenabench.eval.runs.warm_client`, uses these two functions too)."""
    data = json.dumps(obj).encode()
    sock.sendall(struct.pack(">I", len(data)) + data)


def _recv_exact(sock, n):
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return bytes(buf)


def recv_message(sock):
    """The next message (a dict), or ``None`` at end of file."""
    head = _recv_exact(sock, 4)
    if head is None:
        return None
    body = _recv_exact(sock, struct.unpack(">I", head)[0])
    return None if body is None else json.loads(body)


def _load_source(source, name):
    """One of the project's stand-alone modules sent as source (``proctools``, ``launcher``,
    ``warm_up``), in :data:`sys.modules` as ``_arenabench_<name>`` (where the launcher finds
    ``proctools``, and dataclasses their module)."""
    mod = types.ModuleType(f"_arenabench_{name}")
    mod.__file__ = f"<arenabench {name}>"
    sys.modules[mod.__name__] = mod
    exec(compile(source, mod.__file__, "exec"), mod.__dict__)
    return mod


#: The submission's own modules read for what they import (parsed, never run): at most this
#: many files, each at most this many bytes, and at most this many distinct module names
#: looked at in all (a submission cannot make a server's start long).
LOCAL_MODULES_MAX, LOCAL_MODULE_BYTES_MAX, IMPORTED_NAMES_MAX = 64, 1 << 20, 512


def _imports_of(path):
    """``(absolute, relative)`` imports of one Python file, found with :mod:`ast` (the file
    is never run): dotted names of ``import a.b`` and ``from a.b import c`` (``a.b``, and
    ``a.b.c`` in case ``c`` is a module), and ``(level, dotted name)`` of relative ones."""
    try:
        with open(path, "rb") as fh:
            source = fh.read(LOCAL_MODULE_BYTES_MAX + 1)
        if len(source) > LOCAL_MODULE_BYTES_MAX:
            return [], []
        tree = ast.parse(source)
    except (OSError, SyntaxError, ValueError, RecursionError, MemoryError):
        return [], []
    absolute, relative = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            absolute += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            subs = [f"{base}.{a.name}" if base else a.name for a in node.names if a.name != "*"]
            if node.level == 0 and base:
                absolute += [base, *subs]
            elif node.level:
                relative += [(node.level, name) for name in ([base] if base else []) + subs]
    return absolute, relative


def _module_file(folders, parts, *, within):
    """``folders/a/b.py`` or ``folders/a/b/__init__.py`` for ``parts`` ``["a", "b"]``, its
    real path, where that lies in one of the folders ``within``."""
    for folder in folders:
        path = os.path.join(folder, *parts)
        for candidate in (path + ".py", os.path.join(path, "__init__.py")):
            if os.path.isfile(candidate):
                real = os.path.realpath(candidate)
                if any(real.startswith(os.path.join(d, "")) for d in within):
                    return real
    return None


def _script_imports(script, private_dirs):
    """Top-level names of the modules the script imports, and those the submission's own
    modules it imports (in ``private_dirs``, then their own, and so on) import: what a run of
    the script will import (an import in a function counts too). The submission's modules are
    read with :mod:`ast`, never run; :func:`_preload` leaves their own names to the run.

    At most :data:`LOCAL_MODULES_MAX` files are read, each at most
    :data:`LOCAL_MODULE_BYTES_MAX` bytes, and :data:`IMPORTED_NAMES_MAX` distinct names looked
    at; what lies beyond is left for the run to import."""
    within = [os.path.realpath(d) for d in private_dirs]
    names, looked, seen, queue = [], set(), set(), [os.path.realpath(script)]
    while queue and len(seen) < LOCAL_MODULES_MAX:
        path = queue.pop(0)
        if path in seen:
            continue
        seen.add(path)
        absolute, relative = _imports_of(path)
        here, found = os.path.dirname(path), []
        for level, name in [(0, n) for n in absolute] + relative:
            key = (level, here if level else "", name)
            if key in looked:
                continue
            if len(looked) >= IMPORTED_NAMES_MAX:
                break
            looked.add(key)
            if level == 0:
                names.append(name.split(".")[0])
                found.append(_module_file(private_dirs, name.split("."), within=within))
                continue
            package = here
            for _ in range(level - 1):
                package = os.path.dirname(package)
            found.append(_module_file([package], name.split("."), within=within))
        queue += [f for f in found if f and f not in seen]
    return list(dict.fromkeys(names))


def _preload(names, private_dirs):
    """Import ``names`` where they come from outside ``private_dirs`` (the submission's own
    folders: their modules are the team's code and are never run by the server; a name that
    one of them holds, such as a submission's own ``cv2.py``, is left for the run to import,
    as a cold run would find the submission's module first).

    Returns the environment variables each import set or changed (cv2 sets
    ``LD_LIBRARY_PATH``), by module name."""
    import importlib.machinery
    import importlib.util

    changes = {}
    for name in names:
        if name in sys.modules or name == "__main__":
            continue
        try:
            if importlib.machinery.PathFinder.find_spec(name, list(private_dirs)) is not None:
                continue
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            continue
        origin = (spec.origin or "") if spec else ""
        if spec is None or any(origin.startswith(d.rstrip("/") + "/") for d in private_dirs):
            continue
        if origin and not origin.endswith((".py", ".so", ".pyc")) and origin != "built-in":
            continue
        before = dict(os.environ)
        try:
            __import__(name)
        except Exception:  # a module that fails here is imported (and fails) in the run
            pass
        changes[name] = {k: v for k, v in os.environ.items() if before.get(k) != v}
        stop_library_threads()
    return changes


def _shadowed(private_dirs):
    """Why this server cannot run the submission as a cold run would (``""`` when it can): a
    module the server has loaded since its start (numpy, cv2, what they import, its own
    helpers) that the submission's folders hold a module of the same name for. A cold run
    imports the submission's module; a warm run would find the installed one loaded."""
    import importlib.machinery

    startup = {name.partition(".")[0] for name in _STARTUP_MODULES}
    loaded = sorted({name.partition(".")[0] for name in list(sys.modules)} - startup)
    theirs = []
    for name in loaded:
        try:
            spec = importlib.machinery.PathFinder.find_spec(name, list(private_dirs))
        except (ImportError, ValueError):
            continue
        if spec is not None and spec.origin not in (None, "namespace"):
            theirs.append(name)
    if not theirs:
        return ""
    return (f"the submission's own {', '.join(theirs[:8])} would be imported by a cold run, "
            "but the warm interpreter has the installed one loaded")


def _threads():
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return 1


def stop_library_threads():
    """Stop the worker threads a library started at import, the way every run's fork does.

    numpy's and OpenCV's OpenBLAS start a worker thread per core beyond the first when
    loaded; idle, each spins for about 0.1 s before it sleeps (about 60 ms of CPU per server
    start, measured on 2 cores). Their fork handlers (``pthread_atfork``) stop them before a
    fork, and they start again only on a later parallel call: a fork and ``_exit`` here
    leaves the server as the first run's fork leaves it, so a run inherits the same state as
    before, sooner.
    """
    if _threads() <= 1:
        return
    import warnings

    with warnings.catch_warnings():  # Python 3.12+: "multi-threaded, use of fork()" (it is
        warnings.simplefilter("ignore", DeprecationWarning)  # only _exit in the child)
        try:
            pid = os.fork()
        except OSError:  # no process to spare: the threads spin a while longer
            return
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)


def _mount(source, target, fstype, flags, data, what):
    """``mount(2)`` through the C library (``OSError`` naming ``what`` when it fails)."""

    def enc(v):
        return v.encode() if isinstance(v, str) else v

    tools.check(tools.LIBC.mount(enc(source), enc(target), enc(fstype), flags, enc(data)), what)


def _enter_private_namespaces(cfg):
    """In the run (single-threaded, just forked): new user, mount, IPC, network, UTS and PID
    namespaces; the run's box (a tmpfs of ``box_bytes``: :func:`proctools.mount_box`) at
    /sandbox, /tmp and /dev/shm, the server's folders hidden, loopback up. Then a fork: the
    child, pid 1 of the new PID namespace (as a cold run's command under ``--as-pid-1``), drops
    every capability and returns to become the script; this process stays outside the run's
    reach as its *keeper* (:func:`_keep_run`) and never returns. The run sees and can signal
    only its own processes, not its run manager, the standbys or the server; when it ends,
    every process it started dies with its PID namespace."""
    t, warm = tools, cfg.warm
    uid, gid = os.getuid(), os.getgid()
    rundir = cfg.rundir
    t.LIBC.prctl(t.PR_SET_DUMPABLE, 1, 0, 0, 0)  # its own /proc/self/*_map stay writable
    home = os.open(rundir, os.O_RDONLY | os.O_DIRECTORY)  # before the server's folders go
    t.check(t.LIBC.unshare(t.CLONE_NEWUSER | t.CLONE_NEWNS | t.CLONE_NEWIPC | t.CLONE_NEWNET
                           | t.CLONE_NEWUTS | t.CLONE_NEWPID), "unshare")
    for name, text in (("setgroups", "deny"), ("uid_map", f"{uid} {uid} 1"),
                       ("gid_map", f"{gid} {gid} 1")):
        with open(f"/proc/self/{name}", "w") as fh:
            fh.write(text)
    _mount(None, "/", None, t.MS_REC | t.MS_PRIVATE, None, "mount --make-rprivate")
    # a cgroup namespace rooted at the run's own cgroup (bubblewrap's --unshare-cgroup-try for
    # a cold run): /proc/self/cgroup and the mount table name no cgroup of the server's
    t.LIBC.unshare(t.CLONE_NEWCGROUP)
    try:
        box = t.mount_box(rundir, cfg.box_bytes)
    except OSError as exc:  # the harness's failure, not the run's: said in its folder
        _harness_error(home, f"cannot prepare the run's folder: {exc}" if exc.errno not in
                       (errno.ENOSPC, errno.EDQUOT) else
                       f"the files copied into the run's folder do not fit in its "
                       f"{cfg.box_bytes} bytes (--max-disk)")
    work = os.open(os.path.join(box, "work"), os.O_RDONLY | os.O_DIRECTORY)
    bind = t.MS_BIND | t.MS_REC
    # read-only folders of the sandbox under /tmp (a submission there) stay visible on top
    # of the run's own /tmp: kept at a mount point in the run's folder meanwhile
    keep = []
    for i, path in enumerate(warm.keep):
        spare = f"{rundir}/keep{i}"
        _mount_point(spare, os.path.isdir(path))
        _mount(path, spare, None, bind, None, f"keep {path}")
        keep.append((spare, path))
    for src, dst in ((f"{box}/work", SANDBOX_DIR), (f"{box}/tmp", "/tmp"),
                     (f"{box}/shm", "/dev/shm")):
        _mount(src, dst, None, bind, None, f"bind {dst}")
    for spare, path in keep:
        _mount_point(path, os.path.isdir(spare))
        _mount(spare, path, None, bind, None, f"bind {path}")
        _mount(None, path, None, t.MS_REMOUNT | t.MS_BIND | t.MS_RDONLY | t.MS_NOSUID
               | t.MS_NODEV, None, f"read-only {path}")
    # the server's folders always; a folder bound for the server only where it was bound
    for hidden in [*warm.hide, *filter(os.path.isdir, warm.hide_if_there)]:
        _mount("tmpfs", hidden, "tmpfs", t.MS_RDONLY | t.MS_NOSUID | t.MS_NODEV, "size=4k",
               f"hide {hidden}")
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            # SIOCSIFFLAGS: IFF_UP | IFF_LOOPBACK | IFF_RUNNING, as bubblewrap does
            fcntl.ioctl(s.fileno(), 0x8914, struct.pack("16sH14x", b"lo", 0x1 | 0x8 | 0x40))
    except OSError:
        pass
    pid = os.fork()
    if pid:
        _keep_run(pid, work, home, cfg.image_name)
    os.close(work)
    os.close(home)
    t.LIBC.prctl(t.PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    os.setsid()  # a session of its own, as bubblewrap's --new-session gives a cold run
    # a /proc of its own PID namespace where the kernel lets one be mounted (not inside a
    # bubblewrap that covered parts of its /proc: then the server's stays, read-only to it)
    t.LIBC.mount(b"proc", b"/proc", b"proc", t.MS_NOSUID | t.MS_NODEV | t.MS_NOEXEC, None)
    _drop_capabilities()
    t.LIBC.prctl(t.PR_SET_DUMPABLE, 0, 0, 0, 0)  # other runs cannot read its memory or fds
    os.chdir(SANDBOX_DIR)


def _harness_error(home, message):
    """End the run before its script starts, saying why in its folder (the run manager reads
    ``harness_error``: a failure of the harness, never scored as the script's)."""
    try:
        fd = os.open("harness_error", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600, dir_fd=home)
        os.write(fd, message.encode(errors="replace")[:4000])
        os.close(fd)
    finally:
        os._exit(HARNESS_ERROR_STATUS)


def _keep_run(pid, work, home, image_name):
    """The run's keeper: wait for the run (pid 1 of its PID namespace), bring its answer and
    the images it left out of its box (:func:`proctools.copy_back`), and exit as it did. Outside
    the run's PID namespace, so the run can neither see nor signal it. Never returns."""
    null = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):  # the run's output pipes stay the run's
        os.dup2(null, fd)
    status = os.waitpid(pid, 0)[1]
    try:
        dst = os.open("work", os.O_RDONLY | os.O_DIRECTORY, dir_fd=home)
        tools.copy_back(work, dst, skip=image_name)
    except OSError:
        pass
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        signal.signal(sig, signal.SIG_DFL)
        os.kill(os.getpid(), sig)
    os._exit(os.waitstatus_to_exitcode(status) & 0xFF)


def _mount_point(path, is_dir):
    if is_dir:
        os.makedirs(path, exist_ok=True)
    else:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        if not os.path.exists(path):
            os.close(os.open(path, os.O_CREAT | os.O_WRONLY, 0o600))


def _drop_capability(cap):
    """Clear one capability from this thread's effective, permitted and inheritable sets (the
    cold launcher's command loses CAP_SYS_PTRACE at its exec; a warm run has no exec)."""
    header = (ctypes.c_uint32 * 2)(0x20080522, 0)  # _LINUX_CAPABILITY_VERSION_3, this thread
    data = (ctypes.c_uint32 * 6)()  # (effective, permitted, inheritable) x 2 words
    tools.check(tools.LIBC.capget(header, data), "capget")
    word, bit = divmod(cap, 32)
    for i in range(3):
        data[3 * word + i] &= ~(1 << bit) & 0xFFFFFFFF
    tools.check(tools.LIBC.capset(header, data), "capset")


def _drop_capabilities():
    header = (ctypes.c_uint32 * 2)(0x20080522, 0)  # _LINUX_CAPABILITY_VERSION_3, this thread
    data = (ctypes.c_uint32 * 6)()  # effective, permitted, inheritable x 2: all zero
    tools.check(tools.LIBC.capset(header, data), "capset")


def _probe_isolation():
    """'' when a run can enter its private namespaces here, else the problem."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(r)
        try:
            t = tools
            t.check(t.LIBC.unshare(t.CLONE_NEWUSER | t.CLONE_NEWNS | t.CLONE_NEWIPC
                                   | t.CLONE_NEWNET | t.CLONE_NEWUTS | t.CLONE_NEWPID),
                    "unshare")
            _mount(None, "/", None, t.MS_REC | t.MS_PRIVATE, None, "mount")
            os._exit(0)
        except BaseException as exc:
            os.write(w, str(exc).encode(errors="replace"))
            os._exit(1)
    os.close(w)
    why = os.read(r, 4096).decode(errors="replace")
    os.close(r)
    os.waitpid(pid, 0)
    return why


def _python_signal_defaults():
    signal.signal(signal.SIGINT, signal.default_int_handler)
    for s in (signal.SIGPIPE, signal.SIGXFSZ):
        signal.signal(s, signal.SIG_IGN)
    for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT, signal.SIGCHLD, signal.SIGUSR1,
              signal.SIGUSR2, signal.SIGALRM):
        signal.signal(s, signal.SIG_DFL)


def _strip_own_frames(tb):
    """``tb`` without its leading frames of the server, the launcher and runpy (frozen in
    Python 3.11+): a cold run's traceback starts at the script."""
    runpy_file = getattr(sys.modules.get("runpy"), "__file__", "")
    own = {"<arenabench launcher>", "<string>", "<frozen runpy>", runpy_file}
    while tb is not None and tb.tb_frame.f_code.co_filename in own:
        tb = tb.tb_next
    return tb


def _exit_code(exc):
    code = exc.code
    if code is None:
        return 0
    if isinstance(code, int):
        return code & 0xFF
    try:
        print(code, file=sys.stderr)
    except Exception:
        pass
    return 1


def become_script(cfg):
    """In the run's process (called by the launcher in place of ``execve``): become the
    script and exit as its interpreter would. Never returns."""
    import runpy

    target = cfg.warm.target
    if cfg.warm.isolate:
        _enter_private_namespaces(cfg)  # drops every capability
    else:  # never ptrace its run manager (nor anything else)
        _drop_capability(tools.CAP_SYS_PTRACE)
    os.environ.clear()
    os.environ.update(cfg.env)
    os.environ.update(cfg.warm.env_changes)  # what the preloaded imports set (cv2)
    _python_signal_defaults()
    for name, reset in (("tempfile", lambda m: setattr(m, "tempdir", None)),
                        ("random", lambda m: m.seed()),
                        ("numpy.random", lambda m: m.seed())):
        if name in sys.modules:
            try:
                reset(sys.modules[name])
            except Exception:
                pass
    sys.argv = list(target["argv"])
    sys.orig_argv = list(cfg.argv)
    sys.path[0] = target["path0"] if target["path0"] else os.getcwd()
    code = 0
    try:
        if target["module"]:
            runpy.run_module(target["module"], run_name="__main__", alter_sys=True)
        else:
            runpy.run_path(target["script"], run_name="__main__")
    except SystemExit as exc:
        code = _exit_code(exc)
    except BaseException as exc:
        # the exception's own traceback is what gets printed: cut there, not only passed
        exc.__traceback__ = _strip_own_frames(exc.__traceback__)
        sys.excepthook(type(exc), exc, exc.__traceback__)
        code = 1
    # interpreter exit: non-daemon threads, atexit, flushed streams
    try:
        import threading

        threading._shutdown()
    except BaseException:
        pass
    try:
        import atexit

        atexit._run_exitfuncs()
    except BaseException:
        pass
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BaseException:
            code = code or 120
    os._exit(code)


def _run_manager(launcher, become, server_pid, env_changes):
    """The forked run manager: the launcher's ``main`` with the script in place of exec.

    A standby (``become.request``) first enters its own run cgroup
    (:func:`proctools.enter_cgroup`), then waits for its run; the run's process is then in
    that cgroup from its ``fork``."""
    for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(s, launcher.on_stop_signal)
    message, own_cgroup, cfg = become.message, None, None
    try:
        tools.prctl(tools.PR_SET_CHILD_SUBREAPER, 1)
        tools.prctl(tools.PR_SET_PDEATHSIG, signal.SIGTERM)
        # as the cold launcher: not ptrace-attachable by the run it manages (which would stop
        # the manager and with it the timeout)
        tools.LIBC.prctl(tools.PR_SET_DUMPABLE, 0, 0, 0, 0)
        if os.getppid() != server_pid:
            if message is not None:
                tools.rmtree(message["cfg"]["rundir"])
            return 128 + signal.SIGTERM
        if message is None:
            own_cgroup = tools.enter_cgroup(become.cgroup_parent)
            with become.request:
                message = recv_message(become.request)
            if message is None:  # the server has ended, or has no run for it
                return 0
            if message["cfg"].get("cgroup_parent") != become.cgroup_parent:
                own_cgroup = None  # a run for another parent: made and entered as usual
        cfg = tools.LaunchConfig.from_dict(message["cfg"])  # read once, here
        cfg.warm.target = message["target"]
        cfg.warm.env_changes = env_changes
        return launcher.run(cfg, become=become_script, own_cgroup=own_cgroup)
    except launcher.Stopped:
        tools.kill_descendants(own_cgroup)
        if cfg is not None:
            tools.rmtree(cfg.rundir)
        return 128 + signal.SIGTERM


#: Standby run managers a server keeps ready (each waits in its own run cgroup).
STANDBYS = 2


class _Runs:
    """The server's run managers, and its standbys: forked ahead, each in a run cgroup of its
    own (moving a process into a cgroup waits for an RCU grace period, 10-30 ms: a standby
    pays it while earlier runs go)."""

    def __init__(self, launcher):
        self.launcher = launcher
        self.poller = select.poll()
        self.runs = {}  # pidfd -> (run id or None, pid, cgroup parent of a standby or None)
        self.by_id = {}
        self.standbys = []  # (pidfd, pid, the server's end of its socket pair, cgroup parent)

    def _watch(self, pid):
        pidfd = os.pidfd_open(pid)
        self.poller.register(pidfd, select.POLLIN)
        return pidfd

    @staticmethod
    def _fork():
        sys.stdout.flush()  # nothing buffered is written twice
        sys.stderr.flush()
        return os.fork()

    def fork_standbys(self, cgroup_parent):
        """Keep :data:`STANDBYS` standbys for ``cgroup_parent`` (runs without a cgroup
        parent get none)."""
        for standby in [s for s in self.standbys if s[3] != cgroup_parent]:
            self.standbys.remove(standby)
            self._end(standby)
        while cgroup_parent and len(self.standbys) < STANDBYS:
            ours, theirs = socket.socketpair()
            try:
                pid = self._fork()
            except OSError:  # no process to spare: runs start as before
                ours.close()
                theirs.close()
                return
            if pid == 0:
                ours.close()
                raise _BecomeRunManager(request=theirs, cgroup_parent=cgroup_parent)
            theirs.close()
            self.standbys.append((self._watch(pid), pid, ours, cgroup_parent))

    def _end(self, standby):
        """End a standby that no run will use (closing its socket: it exits; reaped when its
        pidfd says so)."""
        pidfd, pid, channel, parent = standby
        channel.close()
        self.runs[pidfd] = (None, pid, parent)

    def start(self, message):
        """Hand ``message`` to a standby for its cgroup parent, or fork a manager for it."""
        parent = message["cfg"].get("cgroup_parent")
        while self.standbys:
            standby = self.standbys.pop(0)
            pidfd, pid, channel, s_parent = standby
            try:
                with channel:
                    send_message(channel, message)
            except OSError:  # it has ended: reaped when its pidfd says so
                self._end(standby)
                continue
            self.runs[pidfd] = (message["id"], pid, s_parent)
            self.by_id[message["id"]] = pid
            break
        else:
            pid = self._fork()
            if pid == 0:
                raise _BecomeRunManager(message)
            self.runs[self._watch(pid)] = (message["id"], pid, None)
            self.by_id[message["id"]] = pid
        self.fork_standbys(parent)

    def ended(self, pidfd):
        """Reap the manager of ``pidfd``; its run id (``None`` for a standby) and status."""
        for standby in [s for s in self.standbys if s[0] == pidfd]:  # ended before its run
            self.standbys.remove(standby)
            self._end(standby)
        run_id, pid, parent = self.runs.pop(pidfd)
        self.poller.unregister(pidfd)
        os.close(pidfd)
        self.by_id.pop(run_id, None)
        _, status = os.waitpid(pid, 0)
        if parent:  # a standby's cgroup, empty once it has ended
            _remove_cgroup_dir(tools.cgroup_path(parent, pid))
        return run_id, (-os.WTERMSIG(status) if os.WIFSIGNALED(status)
                        else os.WEXITSTATUS(status))

    def kill(self, run_id):
        pid = self.by_id.get(run_id)
        if pid:
            _terminate(pid)

    def end_all(self):
        """Kill every run and standby and reap them (at end of file on the socket)."""
        for s in self.standbys:
            self._end(s)
        self.standbys = []
        for _, pid, _ in self.runs.values():
            _terminate(pid)
        for pidfd in list(self.runs):
            self.ended(pidfd)

    def inherited_fds(self):
        """What a forked manager closes: the server's pidfds and standby sockets."""
        return [*self.runs, *(fd for s in self.standbys for fd in (s[0], s[2].fileno()))]


def _terminate(pid):
    """SIGTERM to a run manager (one that has ended already is reaped by its pidfd)."""
    try:
        os.kill(pid, signal.SIGTERM)
    except OSError:
        pass


def _remove_cgroup_dir(path):
    for _ in range(20):
        try:
            os.rmdir(path)
            return
        except FileNotFoundError:
            return
        except OSError:  # still busy a moment after its last process: the keeper sweeps it
            time.sleep(0.001)


def _serve(sock, runs):
    """The server's loop: hand each run to a standby manager (or fork one), report its end.
    Returns at end of file on the socket, after killing every run."""
    runs.poller.register(sock.fileno(), select.POLLIN)
    me = os.getpid()
    while True:
        for fd, _ in runs.poller.poll():
            if fd != sock.fileno():  # a manager's (or a standby's) pidfd: it has ended
                run_id, rc = runs.ended(fd)
                if run_id is not None:
                    send_message(sock, {"id": run_id, "rc": rc})
                continue
            message = recv_message(sock)
            if message is None:
                runs.end_all()
                return
            if message.get("op") == "kill":
                runs.kill(message["id"])
                continue
            message["cfg"]["parent_pid"] = me
            runs.start(message)


def main():
    """Entry point: ``python -c <source> FD FOLDER`` (the folder only names it in ps)."""
    sock = socket.socket(fileno=int(sys.argv[1]))
    for s in (signal.SIGINT, signal.SIGHUP, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)  # the harness ends the server by closing the socket
    config = recv_message(sock)
    if config is None:
        return 0
    global tools, _LAUNCHER
    sources = config["sources"]
    tools = _load_source(sources["proctools"], "proctools")
    tools.LIBC.prctl(tools.PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if config["parent_pid"] and os.getppid() != config["parent_pid"]:
        return 0  # the keeper ended before the death signal was set
    del sys.argv[1:]
    if config["isolate"]:
        tools.LIBC.prctl(tools.PR_SET_DUMPABLE, 0, 0, 0, 0)
    launcher = _LAUNCHER = _load_source(sources["launcher"], "launcher")
    private_dirs = config.get("private_dirs", [])
    imported = _script_imports(config["script"], private_dirs) if config.get("script") else []
    changes = _preload(["numpy", "cv2", *imported], private_dirs)
    # what every run imports to become the script and to exit (become_script), and what the
    # preloaded libraries set up on first use (warm_up.py, synthetic data only): once here
    # rather than in every run
    import atexit  # noqa: F401
    import pkgutil  # noqa: F401
    import runpy  # noqa: F401
    import threading  # noqa: F401

    _load_source(sources["warm_up"], "warm_up").warm_up()
    stop_library_threads()
    # a run gets what an import set in the environment where the script imports the module
    # itself (top level; a cold run would have it from that import)
    env_changes = {k: v for name in imported for k, v in changes.get(name, {}).items()}
    isolation = _probe_isolation() if config["isolate"] else ""
    cold = _shadowed(private_dirs)
    # the preloaded objects stay out of the runs' garbage collections: a collection would
    # write to every tracked object and copy the pages a run shares with the server
    import gc

    gc.collect()
    gc.freeze()
    send_message(sock, {"ready": True, "isolation": isolation, "cold": cold,
                        "pid": os.getpid()})
    runs = _Runs(launcher)
    me = os.getpid()
    become = None
    try:
        _serve(sock, runs)
    except _BecomeRunManager as exc:
        become = exc
    if become is None:
        return 0
    # a freshly forked run manager, out of the except block: the script's exceptions have no
    # context from the server's loop (its traceback holds only the script's own frames)
    become.__traceback__ = None
    code = 1
    try:
        sock.close()
        for fd in runs.inherited_fds():
            try:
                os.close(fd)
            except OSError:
                pass
        code = _run_manager(launcher, become, me, env_changes)
    finally:
        os._exit(code)  # a manager never returns into the server's code


if __name__ == "__main__":
    sys.exit(main())
