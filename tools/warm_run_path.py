"""Wall time of warm runs one after another, and what moving a process into a cgroup costs
(docs/warm-interpreter.md, "Standby run managers").

``chain``: one command's warm runs one at a time (the default: the bench's ``map.py``) on the
first N images of a set; wall ms per image over the loop, the runs' own latency (start to exit
of the script) and the whole machine's busy CPU ms per image (``/proc/stat``, both cores).

``cgroup-move``: a child writes itself into ``cgroup.procs`` of a fresh pids cgroup, 30 times,
back to back and with 50 ms between moves (needs a writable pids cgroup folder).

    .venv/bin/python tools/warm_run_path.py chain IMAGES_DIR [N] [--cmd CMD]
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
    from arenabench.eval import warm_client
    from arenabench.eval.external import CommandPipeline
    from arenabench.eval.run_limits import RunSettings

    pipe = CommandPipeline(cmd, settings=RunSettings(warm=True))
    first = pipe.run(images[0])  # starts the server
    if first.status != "ok":
        raise SystemExit(f"the first run failed: {first.status}: {first.message}")
    b0, t0, latency = _busy_s(), time.perf_counter(), 0.0
    for image in images[1:]:
        latency += pipe.run(image).latency_ms
    t1, b1 = time.perf_counter(), _busy_s()
    pipe.close()
    warm_client.close_all()
    n = len(images) - 1
    print(f"{n} warm runs: wall {1000 * (t1 - t0) / n:.1f} ms per image, run latency "
          f"{latency / n:.1f} ms, machine busy {1000 * (b1 - b0) / n:.1f} CPU ms per image")


def cgroup_move() -> None:
    """Print the median and maximum time of a process's move into a fresh pids cgroup."""
    from arenabench.eval.sandbox import pids_cgroup_parent

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
    sub.add_parser("cgroup-move")
    args = parser.parse_args()
    if args.what == "cgroup-move":
        cgroup_move()
        return
    from arenabench.eval.bench import SCRIPT_PATH

    images = sorted(p for p in args.images.iterdir() if p.suffix in (".png", ".jpg"))[: args.n]
    if len(images) < 2:
        raise SystemExit(f"{args.images}: fewer than 2 images")
    chain(images, args.cmd or f"{{python}} {SCRIPT_PATH} --image {{image}}")


if __name__ == "__main__":
    main()
