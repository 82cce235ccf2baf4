"""Finished runs' folders are removed off the run path (eval/dir_remover.py): every folder
handed over is gone once waited for, at the harness's exit, and at once in a worker process
that leaves with ``os._exit``."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

from arenabench.eval.runs import remover as dir_remover
from arenabench.eval.runs.remover import MAX_PENDING, remove_later, wait_removed


def _folder(root: Path, name: str, files: int = 20) -> Path:
    d = root / name / "work"
    d.mkdir(parents=True)
    for i in range(files):
        (d / f"{i}.txt").write_text("x" * 100)
    return root / name


def test_every_folder_handed_over_is_gone_once_waited_for(tmp_path):
    folders = [_folder(tmp_path, f"run{i}") for i in range(3 * MAX_PENDING)]
    for f in folders:  # more than may wait at once: some are removed inline
        remove_later(str(f))
    assert wait_removed(timeout=30)
    assert list(tmp_path.iterdir()) == []
    assert dir_remover._busy == 0


def test_a_missing_folder_is_no_error(tmp_path):
    remove_later(str(tmp_path / "never-made"))
    assert wait_removed(timeout=30)


def _remove_in_worker(path: str) -> bool:
    remove_later(path)
    return os.path.exists(path)


def test_a_multiprocessing_worker_removes_its_folder_before_returning(tmp_path):
    folder = _folder(tmp_path, "run")
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        still_there = pool.apply(_remove_in_worker, (str(folder),))
    assert still_there is False and not folder.exists()


def test_the_harness_exit_waits_for_pending_removals(tmp_path):
    # many files per folder, so that the remover thread is still at work when the script
    # returns: without the exit hook, the daemon thread would die with folders left
    folders = [_folder(tmp_path, f"run{i}", files=400) for i in range(MAX_PENDING)]
    code = ("import sys\nfrom arenabench.eval.runs.remover import remove_later\n"
            "for p in sys.argv[1:]:\n    remove_later(p)\n")
    done = subprocess.run([sys.executable, "-c", code, *map(str, folders)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert [f for f in folders if f.exists()] == []
