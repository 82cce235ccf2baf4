"""The local process pools (``arenabench.local_pool``): ``local_map`` that ``generate`` and
``sweep`` share gives the same results inline and in real spawned workers, re-raises a task's
error in the caller, and leaves no worker behind when it fails or the caller stops early;
``local_pool`` and ``local_executor`` end their workers the same way; no other module starts
worker processes of its own."""

from __future__ import annotations

import ast
import multiprocessing
import os
import subprocess
import sys
import time

import pytest
from paths import ROOT

from arenabench.local_pool import (
    START_METHOD,
    end_executor,
    local_executor,
    local_map,
    local_pool,
)


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


@pytest.mark.integration
def test_two_workers_give_the_same_results_in_other_processes():
    out = list(local_map(_pid_and_square, range(8), workers=2))
    assert sorted(sq for _, sq in out) == [x * x for x in range(8)]
    assert os.getpid() not in {pid for pid, _ in out}
    assert not multiprocessing.active_children()


@pytest.mark.integration
def test_a_failing_task_is_raised_here_and_no_worker_is_left():
    with pytest.raises(ValueError, match="scene 3 cannot be placed"):
        list(local_map(_refuse_three, range(6), workers=2))
    assert not multiprocessing.active_children()


@pytest.mark.integration
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


@pytest.mark.integration
def test_closing_when_the_workers_are_idle_does_not_hang():
    # an idle worker waits for its next task holding the task queue's read lock; ended there,
    # it never releases it, and Pool.terminate() takes that lock without a timeout (in a
    # process of its own: a hang here would otherwise hang pytest at exit)
    done = subprocess.run([sys.executable, "-c", _CLOSE_WHEN_IDLE], capture_output=True,
                          text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    seconds, left = done.stdout.split()
    assert float(seconds) < 10.0 and left == "0"


def process_starts(source: str) -> list[str]:
    """``line: code`` of each call that makes worker processes or picks their start method:
    ``get_context(...)``, ``ProcessPoolExecutor(...)``, ``...Pool(...)``, ``...Process(...)``
    other than a context's (``ctx.Process``: the method comes from :func:`spawn_context`)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        owner = ast.unparse(func.value) if isinstance(func, ast.Attribute) else ""
        if name in ("get_context", "ProcessPoolExecutor", "Pool") or (
                name == "Process" and owner in ("multiprocessing", "mp")):
            found.append(f"{node.lineno}: {ast.unparse(node)[:60]}")
    return found


def test_every_process_pool_comes_from_local_pool():
    own = ROOT / "src" / "arenabench" / "local_pool.py"
    offences = [f"{path.relative_to(ROOT)}:{hit}"
                for path in sorted(p for pkg in ("src/arenabench", "generator", "eval")
                                   for p in (ROOT / pkg).rglob("*.py") if p != own)
                for hit in process_starts(path.read_text(encoding="utf-8"))]
    assert not offences, "\n".join(offences)


def test_the_checker_sees_each_way_to_start_workers():
    code = ("ctx = multiprocessing.get_context('spawn')\npool = ctx.Pool(2)\n"
            "ex = ProcessPoolExecutor(max_workers=2)\np = multiprocessing.Process(target=f)\n"
            "q = spawn_context().Process(target=f)\n")
    assert len(process_starts(code)) == 4


def _pid(_: object) -> int:
    return os.getpid()


def _start_and_wait(folder: str) -> int:
    open(os.path.join(folder, f"started-{os.getpid()}"), "w").close()
    time.sleep(60.0)
    return 0


@pytest.mark.integration
def test_local_pool_joins_its_workers_after_the_block_and_ends_them_after_an_error(tmp_path):
    with local_pool(2) as pool:
        pids = set(pool.map(_pid, range(4), chunksize=1))
        assert os.getpid() not in pids and pool._ctx.get_start_method() == START_METHOD
    assert not multiprocessing.active_children()
    with pytest.raises(KeyError, match="stop here"):
        with local_pool(2) as pool:
            for _ in range(2):
                pool.apply_async(_start_and_wait, (str(tmp_path),))
            from hostile_util import wait_for

            assert wait_for(lambda: len(list(tmp_path.glob("started-*"))) == 2, timeout=60)
            raise KeyError("stop here")  # both workers are inside a 60 s task
    assert not multiprocessing.active_children()


@pytest.mark.integration
def test_end_executor_ends_a_busy_worker(tmp_path):
    from hostile_util import wait_for

    pool = local_executor(2)
    busy = pool.submit(_start_and_wait, str(tmp_path))
    queued = [pool.submit(_pid, i) for i in range(8)]
    assert wait_for(lambda: list(tmp_path.glob("started-*")), timeout=60)
    end_executor(pool)
    assert not multiprocessing.active_children()
    # the 60 s task was ended, not waited for: it never gave its result
    assert not (busy.done() and busy.exception() is None)
    assert wait_for(lambda: all(f.done() for f in queued))  # cancelled or run, none waits


def test_local_executor_refuses_a_bad_worker_count():
    for bad in (0, 1.5):
        with pytest.raises(ValueError, match="workers must be an integer >= 1"):
            local_executor(bad)
