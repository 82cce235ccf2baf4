"""Run slots (eval/runs/slots.py): no more commands at once than slots, whatever the threads;
real threads, real commands (cold and warm, with bubblewrap where it works here)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import pytest
import toy_arena  # tests/pipelines (pytest's pythonpath)
from hostile_util import wait_for

from arenabench.eval.evaluation import evaluate
from arenabench.eval.runs import CommandPipeline, RunContext
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.eval.runs.sandbox import bwrap_problem
from arenabench.eval.runs.slots import RunSlots

PY = sys.executable
needs_bwrap = pytest.mark.skipif(bwrap_problem() is not None, reason=str(bwrap_problem()))

#: Prints when it ran (CLOCK_MONOTONIC is the machine's, inside a sandbox too) and answers.
TIMED = """\
import sys, time
t0 = time.monotonic()
time.sleep(float(sys.argv[1]))
open("obstacles.txt", "w").write("Aruco ID: [80, 85, 90, 95]\\nObstacles: 0\\nArea: 0\\n")
print(t0, time.monotonic())
"""


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toy") / "toy", n=6, seed=5)


def _timed(tmp_path: Path, sandbox: str, *, warm: bool, sleep: float = 0.4,
           context: RunContext | None = None) -> CommandPipeline:
    script = tmp_path / "timed.py"
    script.write_text(TIMED)
    return CommandPipeline(f"{PY} {script} {sleep}", settings=RunSettings(
        limits=RunLimits(timeout_s=60.0), sandbox=sandbox, warm=warm), context=context)


def _most_at_once(intervals: list[tuple[float, float]]) -> int:
    events = sorted([(t0, 1) for t0, _ in intervals] + [(t1, -1) for _, t1 in intervals])
    most = now = 0
    for _, step in events:  # an end before a start at the same instant
        now += step
        most = max(most, now)
    return most


def _waiting(slots: RunSlots) -> int:
    """Threads waiting in ``slots.take``."""
    return slots.waiting


def test_bad_slot_counts_are_refused_naming_the_value():
    for bad in (0, -1, 1.5, True, None):
        with pytest.raises(ValueError, match="run slots must be a positive integer"):
            RunSlots(bad)  # type: ignore[arg-type]


def test_a_slot_is_handed_to_one_waiter_and_stop_wakes_the_others():
    slots = RunSlots(1)
    assert slots.take(lambda: False)
    got: list[bool] = []
    stopped = threading.Event()
    waiters = [threading.Thread(target=lambda: got.append(slots.take(stopped.is_set)))
               for _ in range(3)]
    for w in waiters:
        w.start()
    assert wait_for(lambda: _waiting(slots) == 3)  # all three wait for the one slot
    assert got == [] and slots.free == 0
    slots.give()
    assert wait_for(lambda: got and _waiting(slots) == 2)
    assert got == [True]  # one took it; two still wait
    stopped.set()
    slots.wake()
    for w in waiters:
        w.join(5)
    assert sorted(got) == [False, False, True] and slots.free == 0
    slots.give()
    with pytest.raises(RuntimeError, match="given back twice"):
        slots.give()


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", [pytest.param("bwrap", marks=needs_bwrap), "none"])
@pytest.mark.parametrize("warm", [True, False], ids=["warm", "cold"])
@pytest.mark.parametrize("workers", [2, 3])
def test_eval_runs_no_more_commands_at_once_than_workers(sandbox, warm, workers, toy, run_tmp,
                                                         tmp_path):
    # evaluate runs workers + 1 threads: without the slots, workers + 1 commands would overlap
    pipe = _timed(tmp_path, sandbox, warm=warm)
    for n in (workers, workers - 1):  # a second evaluation of the pipeline takes its own count
        report = evaluate(pipe, toy, workers=n)
        assert [r.prediction.status for r in report.images] == ["ok"] * 6
        spans = [tuple(map(float, r.prediction.stdout.split())) for r in report.images]
        assert _most_at_once(spans) == n


@pytest.mark.parametrize("warm", [True, False], ids=["warm", "cold"])
def test_stop_ends_the_running_command_and_the_one_waiting_for_its_slot(warm, toy, run_tmp,
                                                                       tmp_path):
    with RunContext(slots=1) as context:
        slots = context.slots
        pipe = _timed(tmp_path, "none", warm=warm, sleep=30.0, context=context)
        images = sorted((toy / "images").iterdir())
        preds: dict[int, object] = {}
        threads = [threading.Thread(target=lambda i=i: preds.__setitem__(
            i, pipe.run(images[i]))) for i in range(2)]
        threads[0].start()
        assert wait_for(lambda: slots.free == 0, timeout=60)  # a warm server starts first
        threads[1].start()
        assert wait_for(lambda: _waiting(slots) == 1, timeout=60)  # the other waits for it
        assert not preds  # one runs (30 s)
        pipe.stop()
        for t in threads:
            t.join()
        # both ended by the stop (not by the 30 s sleep): the run killed, the waiter refused
        assert {p.message for p in preds.values()} == {"interrupted"}
        assert slots.free == 1


@pytest.mark.integration
@pytest.mark.parametrize("warm", [True, False], ids=["warm", "cold"])
def test_grade_runs_no_more_commands_at_once_than_workers(warm, toy, run_tmp, tmp_path):
    from arenabench.eval.grade.grading import GradeUnit, _execute

    (tmp_path / "timed.py").write_text(TIMED)
    settings = RunSettings(limits=RunLimits(timeout_s=60.0), sandbox="none", warm=warm)
    units = [GradeUnit(team=team, submission=str(tmp_path), image=str(image),
                       command=f"{PY} timed.py 0.3", output="obstacles", settings=settings)
             for team in ("a", "b") for image in sorted((toy / "images").iterdir())]
    preds = dict(_execute(units, workers=2, scheduler=None))  # 3 threads
    assert sorted(preds) == list(range(12))
    assert {p.status for p in preds.values()} == {"ok"}
    spans = [tuple(map(float, p.stdout.split())) for p in preds.values()]
    assert _most_at_once(spans) == 2
