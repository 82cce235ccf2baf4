"""The one local process pool (``arenabench.local_pool.local_map``) that ``generate`` and
``sweep`` share: the same results inline and in real spawned workers, a task's error re-raised
in the caller, and no worker left behind when it fails or the caller stops early."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import time

import pytest

from arenabench.local_pool import local_map


def _pid_and_square(x: int) -> tuple[int, int]:
    return os.getpid(), x * x


def _first_at_once(task: tuple[int, str]) -> int:
    """Task 0 returns at once; the others say they started (a file in the folder) and take
    60 s."""
    x, folder = task
    if x:
        open(os.path.join(folder, f"started-{x}"), "w").close()
        time.sleep(60.0)
    return x


def _refuse_three(x: int) -> int:
    if x == 3:
        raise ValueError(f"scene {x} cannot be placed")
    return x


def test_one_worker_runs_in_order_in_this_process():
    out = list(local_map(_pid_and_square, range(5), workers=1))
    assert out == [(os.getpid(), x * x) for x in range(5)]


def test_bad_worker_counts_are_refused():
    for bad in (0, 1.5, -2):
        with pytest.raises(ValueError, match="workers must be an integer >= 1"):
            list(local_map(_pid_and_square, range(3), workers=bad))


@pytest.mark.slow
def test_two_workers_give_the_same_results_in_other_processes():
    out = list(local_map(_pid_and_square, range(8), workers=2))
    assert sorted(sq for _, sq in out) == [x * x for x in range(8)]
    assert os.getpid() not in {pid for pid, _ in out}
    assert not multiprocessing.active_children()


@pytest.mark.slow
def test_a_failing_task_is_raised_here_and_no_worker_is_left():
    with pytest.raises(ValueError, match="scene 3 cannot be placed"):
        list(local_map(_refuse_three, range(6), workers=2))
    assert not multiprocessing.active_children()


@pytest.mark.slow
def test_closing_early_ends_the_workers(tmp_path):
    """Closed while every worker is inside a task (the first result comes at once, its worker
    takes the next task): the workers are ended, not waited for."""
    from hostile_util import wait_for

    results = local_map(_first_at_once, [(x, str(tmp_path)) for x in range(6)], workers=2)
    assert next(results) == 0
    # both workers are inside a 60 s task
    assert wait_for(lambda: len(list(tmp_path.glob("started-*"))) == 2, timeout=60)
    start = time.monotonic()
    results.close()
    assert not multiprocessing.active_children()
    assert time.monotonic() - start < 30.0  # ended, not waited for (the tasks take 60 s)


_CLOSE_WHEN_IDLE = """
import multiprocessing, time
from arenabench.local_pool import local_map
results = local_map(abs, [1, -2], workers=2)
next(results)
next(results)  # both tasks are done: the workers wait for more, one holding the queue's lock
start = time.monotonic()
results.close()
print(round(time.monotonic() - start, 1), len(multiprocessing.active_children()))
"""


@pytest.mark.slow
def test_closing_when_the_workers_are_idle_does_not_hang():
    # an idle worker waits for its next task holding the task queue's read lock; ended there,
    # it never releases it, and Pool.terminate() takes that lock without a timeout (in a
    # process of its own: a hang here would otherwise hang pytest at exit)
    done = subprocess.run([sys.executable, "-c", _CLOSE_WHEN_IDLE], capture_output=True,
                          text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    seconds, left = done.stdout.split()
    assert float(seconds) < 10.0 and left == "0"
