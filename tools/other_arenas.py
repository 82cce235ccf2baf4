"""``arenabench twin`` on real images of other arenas (the acceptance shelf of
docs/twin-tutorial.md, "Real images of other arenas"): for each image its exit status, time,
peak memory, the markers it was built on, the verdict with the figures off and the causes, as a
Markdown table. The images are not in the repository (their sources state no licence): the
tutorial says where each comes from and how to fetch it::

    .venv/bin/python tools/other_arenas.py IMAGE [IMAGE ...] --out /tmp/shelf
    .venv/bin/python tools/other_arenas.py /tmp/hb/arena.jpg --extra=--texture=/tmp/hb/arena.jpg \\
        --extra=--arena-size=2,2 --out /tmp/shelf-texture
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path


def run(image: Path, out: Path, extra: list[str]) -> dict:
    """One twin, as a user runs it; what it said."""
    folder = out / image.stem
    folder.parent.mkdir(parents=True, exist_ok=True)
    log = out / f"{image.stem}.log"
    t = time.monotonic()
    with open(log, "w") as fh:
        proc = subprocess.Popen([sys.executable, "-m", "arenabench", "twin", str(image),
                                 "--out", str(folder), "--no-progress", *extra],
                                stdout=fh, stderr=fh)
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own peak memory
    code = os.waitstatus_to_exitcode(status)
    row = {"image": image.name, "exit": code, "seconds": round(time.monotonic() - t, 1),
           "peak_gb": round(usage.ru_maxrss / 1e6, 2)}
    doc_path = folder / "twin.json"
    if code in (0, 6) and doc_path.exists():
        doc = json.loads(doc_path.read_text())
        m = doc["markers"]
        row.update(markers=f"{m['dictionary']} {m['ids']} (+{len(m.get('others', []))} others)",
                   verdict=doc["verdict"]["verdict"],
                   off="; ".join(f"{o['figure']} {o['value']}" for o in doc["verdict"]["off"]),
                   causes="; ".join(c["text"] for c in doc["verdict"]["causes"]),
                   squares=doc["figures"]["mad"]["markers"], whole=doc["figures"]["whole"])
    else:
        row["said"] = (log.read_text().strip().splitlines() or [""])[-1]
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("images", nargs="+", type=Path)
    p.add_argument("--out", type=Path, required=True, help="folder for the twins")
    p.add_argument("--extra", action="append", default=[],
                   help="an argument passed on to every twin (repeat; --extra=--arena-size=2,2)")
    args = p.parse_args(argv)
    extra = [a for e in args.extra for a in e.split("=", 1)] if args.extra else []
    print("| image | exit | s | peak GB | markers | verdict | off | causes / said |")
    print("|---|---|---|---|---|---|---|---|")
    for image in args.images:
        r = run(image, args.out, extra)
        print(f"| {r['image']} | {r['exit']} | {r['seconds']} | {r['peak_gb']} | "
              f"{r.get('markers', '-')} | {r.get('verdict', '-')} | {r.get('off', '-')} | "
              f"{r.get('causes', r.get('said', ''))} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
