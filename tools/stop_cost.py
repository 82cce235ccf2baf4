"""What a stop costs: CPU seconds and wall seconds from a SIGINT to the command's exit.

    .venv/bin/python tools/stop_cost.py --runs 3
    .venv/bin/python tools/with_burners.py --burners 2 -- .venv/bin/python tools/stop_cost.py

Each case starts a real command (``python -m arenabench ...``), waits for an event that says
it is working (files written, or a script's first run), sends SIGINT, and measures until the
command has exited: wall seconds, and the CPU seconds the command and every process under it
spent in that time (from /proc before the signal and the exit's resource usage after it). On an
idle machine the wall time is about the CPU time (or the waits the stop makes); on a busy one
the wall time grows with the load, the CPU time does not: a stop that spends much CPU is what
a loaded machine makes late.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TICK = os.sysconf("SC_CLK_TCK")
ROOT = Path(__file__).resolve().parent.parent


def _tree_cpu(pid: int) -> float:
    """CPU seconds of ``pid`` and every live process under it, and of the children each has
    already reaped (cutime, cstime)."""
    parents: dict[int, int] = {}
    stats: dict[int, list[str]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            parents[int(entry)] = int(fields[1])
            stats[int(entry)] = fields
    total, frontier, seen = 0.0, [pid], set()
    while frontier:
        p = frontier.pop()
        if p in seen or p not in stats:
            continue
        seen.add(p)
        f = stats[p]
        total += sum(int(x) for x in f[11:15]) / TICK  # utime stime cutime cstime
        frontier += [c for c, pp in parents.items() if pp == p]
    return total


def _wait(ready, proc: subprocess.Popen, timeout: float = 600.0) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        if proc.poll() is not None:
            raise SystemExit(f"exited early: {proc.communicate()}")
        if time.monotonic() > deadline:
            raise SystemExit("no progress")
        time.sleep(0.05)


def _cases(tmp: Path) -> dict[str, tuple[list[str], object]]:
    hang = tmp / "hang.py"
    hang.write_text("import time\nopen('started', 'w')\ntime.sleep(300)\n")
    marks = tmp / "marks"
    marks.mkdir()
    script = tmp / "map.py"
    script.write_text(f"import os, time\nopen(os.path.join({str(marks)!r}, 'run'), 'w').close()\n"
                      "time.sleep(300)\n")
    toy = tmp / "toy"
    subprocess.run([sys.executable, "-c", "import sys, toy_arena; "
                    "toy_arena.write_toy_dataset(__import__('pathlib').Path(sys.argv[1]), n=3)",
                    str(toy)], check=True,
                   env={**os.environ, "PYTHONPATH": str(ROOT / "tests" / "pipelines") + ":"
                        + str(ROOT / "tests")})
    out = tmp / "out"
    return {
        "generate --workers 2": (
            ["generate", "--preset", "eyrc", "--count", "150", "--seed", "3", "--out",
             str(out / "gen2"), "--workers", "2", "--no-progress"],
            lambda: len(list((out / "gen2" / "gt").glob("*.json"))) >= 3),
        "generate --workers 1": (
            ["generate", "--preset", "eyrc", "--count", "150", "--seed", "3", "--out",
             str(out / "gen1"), "--workers", "1", "--no-progress"],
            lambda: len(list((out / "gen1" / "gt").glob("*.json"))) >= 3),
        "sweep --pipeline reference": (
            ["sweep", "--preset", "eyrc", "--vary", "camera.tilt_deg=0:20:10", "--per-point",
             "60", "--seed", "3", "--pipeline", "reference", "--keep-images", "--out",
             str(out / "sweep"), "--workers", "2", "--no-progress", "--no-plots"],
            lambda: len(list((out / "sweep" / "gt").glob("*.json"))) >= 3),
        "eval --cmd (a hanging script)": (
            ["eval", str(toy), "--cmd", f"{sys.executable} {script} {{image}}", "--workers",
             "1", "--sandbox", "none", "--no-progress", "--out", str(out / "eval")],
            lambda: (marks / "run").exists()),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stop_cost", description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=1, help="runs of each case (default 1)")
    args = parser.parse_args(argv)
    print(f"load {os.getloadavg()[0]:.1f}; {os.cpu_count()} cores")
    print(f"{'case':34} {'wall s':>7} {'cpu s':>7} {'exit':>5}")
    for run in range(args.runs):
        with tempfile.TemporaryDirectory() as tmp:
            for name, (argv_, ready) in _cases(Path(tmp)).items():
                if run and "eval" in name:
                    (Path(tmp) / "marks" / "run").unlink(missing_ok=True)
                proc = subprocess.Popen([sys.executable, "-m", "arenabench", *argv_],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                        text=True)
                _wait(ready, proc)
                before = _tree_cpu(proc.pid)
                t0 = time.monotonic()
                proc.send_signal(signal.SIGINT)
                _, status, usage = os.wait4(proc.pid, 0)
                wall = time.monotonic() - t0
                cpu = usage.ru_utime + usage.ru_stime - before
                proc.returncode = os.waitstatus_to_exitcode(status)
                print(f"{name:34} {wall:7.2f} {cpu:7.2f} {proc.returncode:5d}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
