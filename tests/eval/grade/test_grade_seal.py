"""What grade keeps between runs is sealed (eval/grade/seal.py): a team's state or a kept
result edited by hand is never trusted; a kept-results file that is not a regular file (a
FIFO, a folder) is refused in one line, never opened for a blocking read."""

from __future__ import annotations

import json
import os
import sys

import pytest
import toy_arena
from clirun import run_cli
from procs_limit import GRADE_ARGS

from arenabench.eval.grade.partial import PARTIAL_FILE

pytestmark = pytest.mark.integration

TEAM = ('from pathlib import Path\n'
        'Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\n'
        'Area: 1.0\\n")\n')


def _grade(data, subs, out):
    return run_cli("grade", str(data), str(subs), "--out", str(out), "--cmd",
                   f"{sys.executable} {{submission}}/map.py --image {{image}}", "--workers",
                   "1", "--formats", "json", "--allow-guessable-seed", "--no-progress",
                   "--sandbox", "none", *GRADE_ARGS)


@pytest.fixture()
def graded(tmp_path):
    data = toy_arena.write_toy_dataset(tmp_path / "toy", n=2, seed=1)
    (tmp_path / "subs" / "a").mkdir(parents=True)
    (tmp_path / "subs" / "a" / "map.py").write_text(TEAM)
    out = tmp_path / "out"
    first = _grade(data, tmp_path / "subs", out)
    assert first.returncode == 0, first.stderr
    return data, tmp_path / "subs", out


def test_a_state_edited_by_hand_is_graded_again(graded):
    data, subs, out = graded
    before = json.loads((out / "leaderboard.json").read_text())["teams"]
    state_file = out / "teams" / "a" / "grade-state.json"
    state = json.loads(state_file.read_text())
    state["summary"]["pass_rate"], state["summary"]["n_passed"] = 1.0, state["summary"]["n"]
    state_file.write_text(json.dumps(state))
    again = _grade(data, subs, out)
    assert again.returncode == 0, again.stderr
    assert "a: graded (" in again.stdout and "already graded" not in again.stdout
    after = json.loads((out / "leaderboard.json").read_text())["teams"]
    strip = [{k: v for k, v in t.items() if k != "latency_ms_median"} for t in (before, after)
             for t in t]
    assert strip[0] == strip[1]


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_kept_results_that_are_not_a_file_are_refused_in_one_line(graded, kind):
    data, subs, out = graded
    (out / "teams" / "a" / "grade-state.json").unlink()  # as an interrupted grade leaves it
    kept = out / "teams" / "a" / PARTIAL_FILE
    os.mkfifo(kept) if kind == "fifo" else kept.mkdir()
    r = _grade(data, subs, out)
    errors = [x for x in r.stderr.splitlines() if "error:" in x]
    assert r.returncode == 2 and len(errors) == 1, r.stderr
    assert PARTIAL_FILE in errors[0] and "remove it" in errors[0]
