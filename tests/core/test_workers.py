"""One worker module: the state registry, the llvmpipe cap, the core count."""

import os
import subprocess
import sys
import threading

import pytest

from arenabench import workers


def test_process_state_is_made_once_and_shared_by_threads():
    made = []

    def factory():
        made.append(1)
        return object()

    key = ("test", "process")
    values = []
    threads = [threading.Thread(target=lambda: values.append(workers.process_state(key, factory)))
               for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(made) == 1 and len({id(v) for v in values}) == 1


def test_thread_state_is_one_per_thread():
    key = ("test", "thread")
    here = workers.thread_state(key, object)
    assert workers.thread_state(key, object) is here
    there = []
    t = threading.Thread(target=lambda: there.append(workers.thread_state(key, object)))
    t.start()
    t.join()
    assert there[0] is not here


def test_llvmpipe_threads_share_the_cores():
    cores = workers.usable_cores()
    assert cores == len(os.sched_getaffinity(0))
    assert workers.llvmpipe_threads(1) == cores
    assert workers.llvmpipe_threads(cores * 4) == 1
    with pytest.raises(ValueError, match="workers"):
        workers.llvmpipe_threads(0)


def test_init_worker_sets_lp_num_threads_unless_set(monkeypatch):
    monkeypatch.setenv("LP_NUM_THREADS", "")  # restored (or removed) afterwards
    monkeypatch.delenv("LP_NUM_THREADS")
    workers.init_worker(3)
    assert os.environ["LP_NUM_THREADS"] == "3"
    workers.init_worker(5)
    assert os.environ["LP_NUM_THREADS"] == "3"


def test_init_worker_outside_a_pool_keeps_the_exit_status():
    """Its fast-exit hook belongs to pool workers: called in a main process (as a test does),
    the process must still exit with its own status (else a failing pytest run exits 0)."""
    code = ("import sys; from arenabench import workers; workers.init_worker(2, None); "
            "sys.exit(7)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 7


def test_task_records_pickle():
    import pickle

    from arenabench.eval.evaluation import PipelineRun
    from arenabench.generator.dataset.dataset_writer import RenderTask

    for task in (RenderTask(args={"preset": "eyrc", "overrides": {}}, seed=0, index=3, out="x"),
                 PipelineRun(spec="reference", image_path="a.png")):
        assert pickle.loads(pickle.dumps(task)) == task
