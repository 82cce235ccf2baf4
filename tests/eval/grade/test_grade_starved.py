"""A busy grading machine never sinks an honest team: a run starved of CPU is the
harness's failure, never one of the team's timeouts nor a step towards giving up on it.

A team that needs about a second of CPU per image (it pins itself to one CPU, as a solution
tuned for a one-core judge might) is starved on purpose: twelve busy processes, each in a
session (an autogroup) of its own, pinned to the same CPU, leave it about a thirteenth of it.
Its runs then time out waiting for that CPU; grade runs each again, and when they starve every
time it stops with the harness's exit status and one line, having recorded nothing of the team.
Run again on the idle machine, the same command resumes, and the team's verdicts equal those of
an idle grade from the start.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import toy_arena
from procs_limit import GRADE_ARGS

from arenabench.exitcodes import ExitCode

pytestmark = pytest.mark.integration

CPU = min(os.sched_getaffinity(0))
#: About a second of CPU on one pinned CPU, then an answer (right on some toy images).
STEADY_TEAM = f"""\
import os, time
from pathlib import Path
os.sched_setaffinity(0, {{{CPU}}})
start = time.process_time()
while time.process_time() - start < 1.0:
    pass
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 2\\nArea: 1.0\\n")
"""
BURN = f"import os\nos.sched_setaffinity(0, {{{CPU}}})\nwhile True:\n    pass\n"
#: The timeout: the team's second of CPU fits in it even beside a few other busy processes
#: on its CPU, and a thirteenth of the CPU (13 s) does not.
TIMEOUT = "6"


def _grade(toy: Path, subs: Path, out: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "arenabench", "grade", str(toy), str(subs), "--out", str(out),
         "--cmd", f"{sys.executable} {{submission}}/map.py --image {{image}}",
         "--workers", "1", "--report-workers", "1", "--formats", "json", "--timeout", TIMEOUT,
         "--give-up-after", "1", "--sandbox", "none", "--no-warm", "--no-progress",
         "--allow-guessable-seed", *GRADE_ARGS],
        capture_output=True, text=True, timeout=900)


def _verdicts(out: Path) -> list[dict]:
    report = json.loads((out / "teams" / "steady" / "report.json").read_text())
    return [{k: v for k, v in image.items() if k not in ("latency_ms", "stdout_tail",
                                                         "stderr_tail")}
            for image in report["images"]]


def test_a_starved_team_is_never_timed_out_and_its_verdicts_equal_an_idle_grades(tmp_path):
    toy = toy_arena.write_toy_dataset(tmp_path / "toy", n=3, seed=1)
    subs = tmp_path / "subs"
    (subs / "steady").mkdir(parents=True)
    (subs / "steady" / "map.py").write_text(STEADY_TEAM)
    idle = _grade(toy, subs, tmp_path / "idle")
    assert idle.returncode == 0, idle.stderr
    burners = [subprocess.Popen([sys.executable, "-c", BURN], start_new_session=True)
               for _ in range(12)]
    try:
        busy = _grade(toy, subs, tmp_path / "busy")
    finally:
        for b in burners:
            b.kill()
            b.wait()
    assert busy.returncode == ExitCode.HARNESS, (busy.returncode, busy.stdout, busy.stderr)
    errors = [line for line in busy.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1 and "starved of CPU" in errors[0], busy.stderr
    assert "in each of 3 runs" in errors[0] and "run the same command again" in errors[0]
    # nothing of the team was scored: no timeout, no giving up (--give-up-after 1)
    assert not (tmp_path / "busy" / "teams" / "steady" / "report.json").exists()
    partial = tmp_path / "busy" / "teams" / "steady" / "partial-results.jsonl"
    assert not partial.exists() or '"timeout"' not in partial.read_text()
    resumed = _grade(toy, subs, tmp_path / "busy")  # the same command, the machine idle
    assert resumed.returncode == 0, resumed.stderr
    assert _verdicts(tmp_path / "busy") == _verdicts(tmp_path / "idle")
    assert all(v["category"] != "timeout" for v in _verdicts(tmp_path / "idle"))
