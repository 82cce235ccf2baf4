"""``arenabench generate --scheduler``: a Dask ``LocalCluster`` on loopback renders, this
process writes, and the files are byte-identical to a local run's; resuming works the same;
an unreachable scheduler exits 2 with one line before anything is written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

COUNT, SEED = 4, 11


def _generate(out: Path, *extra: str, env: dict[str, str] | None = None):
    cmd = [sys.executable, "-m", "arenabench", "generate", "--preset", "eyrc", "--count",
           str(COUNT), "--seed", str(SEED), "--out", str(out), "--no-progress", *extra]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})})


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("gen-local") / "local"
    proc = _generate(out, "--workers", "1")
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.integration
def test_cluster_run_writes_the_same_bytes_as_a_local_run(local_run, tmp_path):
    distributed = pytest.importorskip("distributed")
    out = tmp_path / "dask"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        proc = _generate(out, "--scheduler", cluster.scheduler_address)
        assert proc.returncode == 0, proc.stderr
        assert f"{COUNT} rendered" in proc.stdout + proc.stderr
        reference = _files(local_run)
        assert len(reference) == 2 * COUNT + 3  # images, GT, manifest, dataset.json, coco.json
        assert _files(out) == reference
        # an interrupted run resumes on the cluster too
        (out / "images" / "000002.jpg").unlink()  # eyrc writes JPEG
        proc = _generate(out, "--scheduler", cluster.scheduler_address)
        assert proc.returncode == 0 and "1 rendered" in proc.stdout + proc.stderr, proc.stderr
        assert _files(out) == reference


@pytest.mark.integration  # imports Dask
def test_unreachable_scheduler_exits_2_before_writing(tmp_path):
    out = tmp_path / "never"
    proc = _generate(out, "--scheduler", "tcp://127.0.0.1:9",
                     env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"})
    err = proc.stderr.strip()
    assert proc.returncode == 2 and err.startswith("arenabench generate: error: "), err
    assert len(err.splitlines()) == 1 and "127.0.0.1:9" in err, err
    assert not out.exists()
