"""Wall time of warm runs one after another, and what moving a process into a cgroup costs
(docs/warm-interpreter.md, "Standby run managers").

``chain``: one command's warm runs one at a time (the default: the bench's ``map.py``) on the
first N images of a set; wall ms per image over the loop, the runs' own latency (start to exit
of the script) and the whole machine's busy CPU ms per image (``/proc/stat``, both cores).

``floor``: the least one process per image can cost. CPU ms per image of the script run with
``runpy`` in this process, and in a child forked from this process for each image (after the
imports and warm-up a warm server does; no sandbox, run manager or harness; the child's exit
and address-space teardown counted, and this process's ``fork``).

``cgroup-move``: a child writes itself into ``cgroup.procs`` of a fresh pids cgroup, 30 times,
back to back and with 50 ms between moves (needs a writable pids cgroup folder).

    .venv/bin/python tools/warm_run_path.py chain IMAGES_DIR [N] [--cmd CMD]
    .venv/bin/python tools/warm_run_path.py floor IMAGES_DIR [N] [--script MAP_PY]
    .venv/bin/python tools/warm_run_path.py cgroup-move
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path


def _busy_s() -> float:
    with open("/proc/stat") as fh:
        v = [int(x) for x in fh.readline().split()[1:]]
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


def chain(images: list[Path], cmd: str) -> None:
    """Print wall, latency and busy CPU ms per image of warm runs one after another."""
    from arenabench.eval.runs import CommandPipeline, RunSettings

    pipe = CommandPipeline(cmd, settings=RunSettings(warm=True))
    first = pipe.run(images[0])  # starts the server
    if first.status != "ok":
        raise SystemExit(f"the first run failed: {first.status}: {first.message}")
    b0, t0, latency = _busy_s(), time.perf_counter(), 0.0
    for image in images[1:]:
        latency += pipe.run(image).latency_ms
    t1, b1 = time.perf_counter(), _busy_s()
    pipe.close()  # its own run context: the server ends
    n = len(images) - 1
    print(f"{n} warm runs: wall {1000 * (t1 - t0) / n:.1f} ms per image, run latency "
          f"{latency / n:.1f} ms, machine busy {1000 * (b1 - b0) / n:.1f} CPU ms per image")


def floor(images: list[Path], script: Path) -> None:
    """Print CPU ms per image of ``script`` in this process and in a fork of it per image."""
    import contextlib
    import gc
    import io
    import json
    import resource
    import runpy
    import sys
    import tempfile

    import cv2  # noqa: F401  (what a warm server preloads)
    import numpy  # noqa: F401

    from arenabench.eval.runs import warm_up

    warm_up()
    gc.freeze()
    sys.path.insert(0, str(script.parent))

    def once(image: Path) -> None:
        sys.argv = [str(script), "--image", str(image)]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
            runpy.run_path(str(script), run_name="__main__")

    def children_cpu() -> float:
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    os.chdir(tempfile.mkdtemp(prefix="arenabench-floor-"))
    # in one process: a child of its own runs every image (this process runs no script, so
    # that each fork below starts from the state a warm server's runs start from)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        once(images[0])  # the script's own imports
        took = []
        for image in images:
            t = time.process_time()
            once(image)
            took.append(time.process_time() - t)
        os.write(w, json.dumps(took).encode())
        os._exit(0)
    os.close(w)
    with os.fdopen(r) as fh:
        inproc = json.loads(fh.read())
    os.waitpid(pid, 0)
    forked = []
    for image in images:
        t, c = time.process_time(), children_cpu()
        pid = os.fork()
        if pid == 0:
            once(image)
            os._exit(0)
        os.waitpid(pid, 0)
        forked.append(time.process_time() - t + children_cpu() - c)
    a, b = 1000 * statistics.median(inproc), 1000 * statistics.median(forked)
    print(f"{len(images)} images: in this process {a:.1f} CPU ms per image (median), in a fork "
          f"per image {b:.1f} ({b / a:.2f}x)")


def cgroup_move() -> None:
    """Print the median and maximum time of a process's move into a fresh pids cgroup."""
    from arenabench.eval.runs import pids_cgroup_parent

    parent = pids_cgroup_parent()
    if parent is None:
        raise SystemExit("no writable pids cgroup here")
    base = os.path.join(parent, f"arenabench-move-{os.getpid()}")
    os.mkdir(base)
    try:
        for pause in (0.0, 0.05):
            took = []
            for i in range(30):
                time.sleep(pause)
                group = os.path.join(base, f"g{pause}-{i}")
                os.mkdir(group)
                r, w = os.pipe()
                pid = os.fork()
                if pid == 0:
                    t = time.perf_counter()
                    with open(os.path.join(group, "cgroup.procs"), "w") as fh:
                        fh.write("0")
                    os.write(w, repr(time.perf_counter() - t).encode())
                    os._exit(0)
                os.close(w)
                took.append(1000 * float(os.read(r, 64)))
                os.close(r)
                os.waitpid(pid, 0)
                os.rmdir(group)
            print(f"{pause * 1000:.0f} ms between moves: median {statistics.median(took):.2f} "
                  f"ms, max {max(took):.2f} ms")
    finally:
        os.rmdir(base)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    c = sub.add_parser("chain")
    c.add_argument("images", type=Path)
    c.add_argument("n", type=int, nargs="?", default=60)
    c.add_argument("--cmd", default=None)
    f = sub.add_parser("floor")
    f.add_argument("images", type=Path)
    f.add_argument("n", type=int, nargs="?", default=60)
    f.add_argument("--script", type=Path, default=None)
    sub.add_parser("cgroup-move")
    args = parser.parse_args()
    if args.what == "cgroup-move":
        cgroup_move()
        return
    from arenabench.eval.bench.items import SCRIPT_PATH

    images = sorted(p for p in args.images.iterdir() if p.suffix in (".png", ".jpg"))[: args.n]
    if len(images) < 2:
        raise SystemExit(f"{args.images}: fewer than 2 images")
    if args.what == "floor":
        floor(images, (args.script or SCRIPT_PATH).resolve())
        return
    chain(images, args.cmd or f"{{python}} {SCRIPT_PATH} --image {{image}}")


if __name__ == "__main__":
    main()
