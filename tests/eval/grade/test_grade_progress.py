"""What grade says while it works: the preflight and a line every few seconds
even while nothing finishes (a hanging team), an estimate only once it means something and
without the work of a team given up on, and after an interrupt what each unfinished team has
left to do."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import threading

import pytest
import toy_arena
from hostile_util import wait_for
from procs_limit import GRADE_ARGS

from arenabench.progress import PLAIN_STEP_SECONDS, PlainProgress, drop

HANG = "import time\ntime.sleep(600)\n"
WRONG = ('from pathlib import Path\n'
         'Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 9\\n'
         'Area: 1.0\\n")\n')


def test_no_estimate_from_a_slow_first_unit_and_none_for_work_given_up():
    now, buf = [0.0], io.StringIO()
    bar = PlainProgress(800, desc="grade", unit="run", file=buf, clock=lambda: now[0])
    now[0] = 300.0  # a hanging team's first timeout, five minutes in
    bar.update(1)
    assert bar.eta() is None and "eta" not in buf.getvalue()  # 1 of 800 says nothing yet
    drop(bar, 199)  # that team is given up on: its other images never run
    assert bar.total == 601
    for _ in range(300):  # the other teams' runs, two a second for two and a half minutes
        now[0] += 0.5
        bar.update(1)
    eta = bar.eta()  # 300 runs left at the recent two a second
    assert eta is not None and eta == pytest.approx(150, abs=2)
    bar.close()


@pytest.mark.integration
def test_a_hanging_team_does_not_silence_grade(tmp_path):
    toy = toy_arena.write_toy_dataset(tmp_path / "toy", n=2, seed=1)
    (tmp_path / "subs" / "hangs").mkdir(parents=True)
    (tmp_path / "subs" / "hangs" / "map.py").write_text(HANG)
    proc = subprocess.Popen(
        [sys.executable, "-m", "arenabench", "grade", str(toy), str(tmp_path / "subs"),
         "--out", str(tmp_path / "out"), "--cmd",
         f"{sys.executable} {{submission}}/map.py --image {{image}}", "--timeout", "300",
         "--workers", "1", "--sandbox", "none", "--allow-guessable-seed", *GRADE_ARGS],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    said: list[str] = []
    reader = threading.Thread(target=lambda: said.extend(proc.stdout), daemon=True)
    try:
        reader.start()
        # the first progress line, while the first image still hangs (its timeout is 300 s)
        first = None
        for line in proc.stderr:
            if line.startswith("grade: "):
                first = line
                break
        assert first is not None and first.startswith("grade: 0/2 run (0 %)"), first
        assert any(x.startswith("preflight: done in") for x in said), said
        assert said[0].startswith("preflight: ")  # the first thing it says
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert PLAIN_STEP_SECONDS <= 10  # "within seconds"


@pytest.mark.integration
def test_an_interrupt_while_a_team_is_scored_says_its_images_are_all_run(shared_sets,
                                                                         tmp_path):
    data = shared_sets.generated("eyrc", count=2, seed=11)
    (tmp_path / "subs" / "wrong").mkdir(parents=True)
    (tmp_path / "subs" / "wrong" / "map.py").write_text(WRONG)
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-m", "arenabench", "grade", str(data), str(tmp_path / "subs"),
         "--out", str(tmp_path / "out"), "--cmd",
         f"{sys.executable} {{submission}}/map.py --image {{image}}", "--workers", "1",
         "--report-workers", "1", "--sandbox", "none", "--no-progress",
         "--allow-guessable-seed", *GRADE_ARGS],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "TMPDIR": str(tmpdir)})
    try:
        # its two images are run and wrong: the phase check re-renders them (its folder)
        assert wait_for(lambda: any(p.name.startswith("arenabench-phase-")
                                    for p in tmpdir.iterdir()) or proc.poll() is not None,
                        timeout=300)
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert ("wrong: not finished: all 2 images run (kept), its scoring, phase check and "
            "reports not done" in out), out
