"""Writes everything a run can read of where and how it was started (one JSON line on
stderr, zlib + base64) and answers a wrong count (so that the phase check re-runs it).

Used by tests/eval/runs/test_run_view.py: a phase check's re-run must see what a first run
sees, so that a script cannot tell them apart.
"""

import base64
import json
import os
import resource
import socket
import sys
import zlib
from pathlib import Path


def _read(path):
    try:
        return Path(path).read_text(errors="replace")
    except OSError as exc:
        return f"<{type(exc).__name__}>"


def _listing(folder):
    try:
        return sorted(os.listdir(folder))
    except OSError as exc:
        return f"<{type(exc).__name__}>"


def _fds():
    out = {}
    for fd in _listing("/proc/self/fd") if isinstance(_listing("/proc/self/fd"), list) else []:
        try:
            out[fd] = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            out[fd] = "?"
    return out


status = dict(line.split(":", 1) for line in _read("/proc/self/status").splitlines()
              if ":" in line)
view = {
    # mount id, parent id and device are the kernel's (global counters); the rest is the table
    "mountinfo": [" ".join(line.split()[3:]) for line in
                  _read("/proc/self/mountinfo").splitlines()],
    "cgroup": _read("/proc/self/cgroup"),
    "environ": sorted(_read("/proc/self/environ").split("\0")),
    "cwd": os.getcwd(),
    "cwd_listing": _listing("."),
    "tmp_listing": _listing(os.environ.get("TMPDIR", "/tmp")),
    "slash_tmp": _listing("/tmp"),
    "dev_shm": _listing("/dev/shm"),
    "root": _listing("/"),
    "argv": sys.argv,
    "orig_argv": getattr(sys, "orig_argv", []),
    "ids": [os.getuid(), os.geteuid(), os.getgid(), os.getegid(), sorted(os.getgroups())],
    "hostname": socket.gethostname(),
    "uname": list(os.uname()),
    "pid": os.getpid(),
    "ppid": os.getppid(),
    "status": {k: status.get(k, "").strip() for k in ("NSpid", "NStgid", "Cpus_allowed_list",
                                                      "Seccomp", "NoNewPrivs", "CapEff")},
    "rlimits": {name: resource.getrlimit(getattr(resource, name))
                for name in sorted(dir(resource)) if name.startswith("RLIMIT_")},
    "fds": _fds(),
    "proc": sorted(p for p in _listing("/proc") if p.isdigit()) if isinstance(
        _listing("/proc"), list) else [],
    "umask": os.umask(0o22),
}
packed = base64.b64encode(zlib.compress(json.dumps(view, sort_keys=True).encode(), 9))
print(packed.decode(), file=sys.stderr)
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\nObstacles: 99\nArea: 0\n")
