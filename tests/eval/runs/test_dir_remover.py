"""Finished runs' folders are removed off the run path (eval/runs/remover.py): every folder
handed over is gone once waited for, when its run context ends, and at once in a worker
process that leaves with ``os._exit``; two removers share nothing."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import pytest

from arenabench.eval.runs.remover import MAX_PENDING, FolderRemover


def _folder(root: Path, name: str, files: int = 20) -> Path:
    d = root / name / "work"
    d.mkdir(parents=True)
    for i in range(files):
        (d / f"{i}.txt").write_text("x" * 100)
    return root / name


def test_every_folder_handed_over_is_gone_once_waited_for(tmp_path):
    remover = FolderRemover()
    folders = [_folder(tmp_path, f"run{i}") for i in range(3 * MAX_PENDING)]
    for f in folders:  # more than may wait at once: some are removed inline
        remover.remove_later(str(f))
    assert remover.wait(timeout=30)
    assert list(tmp_path.iterdir()) == []
    assert remover.pending == 0
    assert remover.close(timeout=30)


def test_a_missing_folder_is_no_error(tmp_path):
    remover = FolderRemover()
    remover.remove_later(str(tmp_path / "never-made"))
    assert remover.wait(timeout=30)
    remover.close()


def test_a_closed_remover_starts_again_and_two_share_nothing(tmp_path):
    first, second = FolderRemover(), FolderRemover()
    first.remove_later(str(_folder(tmp_path, "a")))
    assert first.close(timeout=30) and not (tmp_path / "a").exists()
    first.remove_later(str(_folder(tmp_path, "b")))  # after close: its thread starts again
    assert first.wait(timeout=30) and not (tmp_path / "b").exists()
    assert second.pending == 0  # nothing of the first's is the second's
    first.close()
    second.close()


def _remove_in_worker(path: str) -> bool:
    FolderRemover().remove_later(path)
    return os.path.exists(path)


def test_a_multiprocessing_worker_removes_its_folder_before_returning(tmp_path):
    folder = _folder(tmp_path, "run")
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        still_there = pool.apply(_remove_in_worker, (str(folder),))
    assert still_there is False and not folder.exists()


@pytest.mark.integration
def test_the_end_of_a_run_context_waits_for_pending_removals(tmp_path):
    # many files per folder, so that the remover thread is still at work when the block
    # ends: without the wait, the daemon thread would die with the script, folders left
    folders = [_folder(tmp_path, f"run{i}", files=400) for i in range(MAX_PENDING)]
    code = ("import sys\nfrom arenabench.eval.runs import RunContext\n"
            "with RunContext(cgroup_parent=None) as runs:\n"
            "    for p in sys.argv[1:]:\n        runs.remover.remove_later(p)\n")
    done = subprocess.run([sys.executable, "-c", code, *map(str, folders)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert [f for f in folders if f.exists()] == []
