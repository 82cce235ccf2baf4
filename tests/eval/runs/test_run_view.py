"""A phase check's re-run sees what a first run sees: a script cannot tell them
apart, so it cannot choose its own phase labels.

A probe (tests/pipelines/view_probe.py) writes everything a run can read of where and how it
was started: the mount table, its cgroups, environment, working directory and the listings of
its folders, its argv, ids, host name, pids, limits, open files. A first run (one pipeline, as
``eval`` and ``grade`` run an image) and a phase check's re-run (a new pipeline, as ``grade``
makes one for the check) must see the same, warm and cold; what may differ is drawn at random
anew for every server or run (a folder's name) or is the kernel's global count (the inode
number of a pipe), never a count of servers or a process's id.
"""

from __future__ import annotations

import base64
import difflib
import json
import os
import re
import sys
import zlib

import pytest
from paths import TESTS

from arenabench.eval.datasets.reader import load_dataset
from arenabench.eval.phase_check import check_phases
from arenabench.eval.runs import CommandPipeline
from arenabench.eval.runs.command import Command
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.eval.runs.sandbox import bwrap_problem
from arenabench.eval.scoring.metrics import score_sample

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(bwrap_problem() is not None, reason=str(bwrap_problem()))]

PROBE = TESTS / "pipelines" / "view_probe.py"
#: What may differ between two runs' views: names drawn at random (a warm server's folder, a
#: warm run's folder in it) and the kernel's global inode count of a pipe.
RANDOM = [
    (re.compile(r"arenabench-warm-[A-Za-z0-9_]{8}\b"), "arenabench-warm-<random>"),
    (re.compile(r"/\.arenabench-warm/[0-9a-f]{24}/"), "/.arenabench-warm/<random>/"),
    (re.compile(r"pipe:\[\d+\]"), "pipe:[<kernel count>]"),
]


def _pipeline(warm: bool) -> CommandPipeline:
    settings = RunSettings(limits=RunLimits(timeout_s=120.0), sandbox="bwrap", warm=warm)
    return CommandPipeline(f"{sys.executable} {PROBE} --image {{image}}", settings=settings)


@pytest.fixture()
def whole_stderr(monkeypatch):
    """The runs' whole stderr, by prediction (a prediction keeps the last 2,000 characters;
    the view is longer): read where the command interprets its finished run."""
    seen: dict[int, str] = {}
    interpret = Command.interpret

    def keeping(self, result, stdout, stderr, workdir):
        prediction = interpret(self, result, stdout, stderr, workdir)
        seen[id(prediction)] = stderr
        return prediction

    monkeypatch.setattr(Command, "interpret", keeping)
    return seen


def _view(prediction, whole_stderr) -> dict:
    assert prediction.status == "ok", (prediction.status, prediction.message, prediction.stderr)
    packed = whole_stderr[id(prediction)].strip().splitlines()[-1]
    return json.loads(zlib.decompress(base64.b64decode(packed)))


def _normalised(view: dict) -> str:
    text = json.dumps(view, sort_keys=True, indent=1)
    for pattern, word in RANDOM:
        text = pattern.sub(word, text)
    return text


@pytest.fixture(scope="module")
def one_scene(shared_sets):
    return load_dataset(shared_sets.generated("eyrc", count=1, seed=45)).samples[0]


@pytest.mark.parametrize("warm", [True, False], ids=["warm", "cold"])
def test_a_phase_rerun_sees_what_a_first_run_sees(one_scene, run_tmp, whole_stderr, warm):
    first_pipe = _pipeline(warm)
    try:
        first = first_pipe.run(one_scene.image_path)
    finally:
        first_pipe.close()
    result = score_sample(one_scene, first, tolerance=0.05, area_reference="visible")
    assert not result.passed and result.category == "wrong_count"  # so the check re-runs it
    seen = []
    phase_pipe = _pipeline(warm)  # grade's phase check: a pipeline (and server) of its own

    def run(path):
        prediction = phase_pipe.run(path)
        seen.append(_view(prediction, whole_stderr))
        return prediction

    try:
        checked = check_phases([result], [one_scene.gt], run, phases=2, tolerance=0.05,
                               area_reference="visible")
    finally:
        phase_pipe.close()
    assert checked[0].phase is not None and checked[0].phase.runs == 2
    first_view = _view(first, whole_stderr)
    assert first_view["mountinfo"] and first_view["environ"] and first_view["cgroup"]
    if warm and "\t" in first_view["status"]["NSpid"]:
        # /proc is the server's: as root, bubblewrap covers parts of its /proc and the kernel
        # refuses a run one of its own; the run's server-side pid counts the server's runs
        # (docs/warm-interpreter.md): left out here, and named by the grade's preflight
        assert os.geteuid() == 0
        for v in [first_view, *seen]:
            v.pop("proc"), v["status"].pop("NSpid"), v["status"].pop("NStgid")
    for again in seen:
        diff = list(difflib.unified_diff(_normalised(first_view).splitlines(),
                                         _normalised(again).splitlines(), "first run",
                                         "phase run", lineterm="", n=1))
        assert not diff, "\n".join(diff)
    # what differed was drawn anew (a new server's folder), and names no process of ours
    raw = json.dumps(first_view) + json.dumps(seen)
    # as a number of its own (the pid 8388 is in 8388608, an 8 MiB limit)
    assert not re.search(rf"(?<!\d){os.getpid()}(?!\d)", raw), os.getpid()
    if warm:
        names = {m for v in [first_view, *seen]
                 for m in RANDOM[0][0].findall(json.dumps(v["mountinfo"]))}
        assert len(names) == 2, names  # the first run's server and the phase check's
        assert "/.." in first_view["cgroup"] or re.search(r":/\n", first_view["cgroup"])
