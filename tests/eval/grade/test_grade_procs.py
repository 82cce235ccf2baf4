"""``--max-procs`` fails closed in ``grade``: as root, where no pids cgroup can be
created, the kernel does not enforce RLIMIT_NPROC, so ``grade`` stops before any team runs
(exit 2, one line naming ``--max-procs 0``); ``--max-procs 0`` is no process limit, said so in
the leaderboard's sandbox record; ``eval --cmd`` keeps its warning.

The cgroup file system is taken away for real: the command runs in a private mount namespace
(``unshare --mount``) with an empty tmpfs over /sys/fs/cgroup."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from procs_limit import GRADE_ARGS, PY_CMD

from arenabench.eval.grade.preflight import NO_PROCESS_LIMIT, PreflightError, process_limit
from arenabench.eval.runs.limits import RunLimits

ANSWER = """\
from pathlib import Path
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\nArea: 1.0\\n")
"""
FORKS = """\
import os, sys
from pathlib import Path
kids = []
for _ in range(8):  # 9 processes at once: refused by a pids.max of 0..8, not by 'max'
    pid = os.fork()
    if pid == 0:
        import time
        time.sleep(0.5)
        os._exit(0)
    kids.append(pid)
for pid in kids:
    os.waitpid(pid, 0)
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\nArea: 1.0\\n")
"""


def _no_cgroups_argv() -> list[str] | None:
    """The prefix that runs a command with no cgroup file system, or ``None`` (why: skip)."""
    unshare = shutil.which("unshare")
    if os.getuid() != 0 or unshare is None:
        return None
    probe = subprocess.run([unshare, "--mount", "--propagation", "private", "sh", "-c",
                            "mount -t tmpfs none /sys/fs/cgroup"], capture_output=True,
                           timeout=30)
    if probe.returncode != 0:
        return None
    return [unshare, "--mount", "--propagation", "private", "sh", "-c",
            'mount -t tmpfs none /sys/fs/cgroup && exec "$@"', "sh"]


NO_CGROUPS = _no_cgroups_argv()
needs_root_unshare = pytest.mark.skipif(
    NO_CGROUPS is None,
    reason="needs root and 'unshare --mount' (to hide the cgroup file system for real)")


def _env() -> dict[str, str]:
    return {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}


def _cli(*args: str, prefix: list[str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([*(prefix or []), sys.executable, "-m", "arenabench", *args],
                          capture_output=True, text=True, env=_env(), timeout=600)


@pytest.fixture(scope="module")
def one_image(shared_sets):
    return shared_sets.generated("eyrc", count=1, seed=3)


def _teams(root: Path, script: str = ANSWER) -> Path:
    for name in ("a", "b"):
        (root / name).mkdir(parents=True)
        (root / name / "map.py").write_text(script)
    return root


def test_max_procs_0_is_no_limit_and_negative_is_refused():
    assert process_limit(0) == NO_PROCESS_LIMIT
    assert RunLimits(max_procs=0).max_procs == 0
    with pytest.raises(ValueError, match="max_procs"):
        RunLimits(max_procs=-1)


def test_process_limit_names_how_it_is_enforced_here():
    try:
        how = process_limit(64)
    except PreflightError as exc:  # root without a pids cgroup: the refusal, one line
        assert os.getuid() == 0 and "--max-procs 0" in str(exc) and "\n" not in str(exc)
        return
    assert how == ("RLIMIT_NPROC" if os.getuid() != 0 else "pids cgroup")


def _grade_argv(dataset: Path, subs: Path, out: Path) -> list[str]:
    return [str(dataset), str(subs), "--out", str(out), "--cmd", PY_CMD, "--sandbox", "none",
            "--allow-guessable-seed", "--no-progress", "--formats", "json"]


@pytest.mark.integration
@needs_root_unshare
def test_grade_without_a_pids_cgroup_stops_before_any_team(one_image, tmp_path):
    out = tmp_path / "out"
    proc = _cli("grade", *_grade_argv(one_image, _teams(tmp_path / "subs"), out),
                prefix=NO_CGROUPS)
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, err[-3000:])
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "--max-procs 64: cannot be enforced here" in err and "--max-procs 0" in err, err
    assert not out.exists()  # no team graded, nothing half-written


@pytest.mark.integration
@needs_root_unshare
def test_grade_with_max_procs_0_proceeds_without_a_pids_cgroup(one_image, tmp_path):
    out = tmp_path / "out"
    proc = _cli("grade", *_grade_argv(one_image, _teams(tmp_path / "subs"), out),
                "--max-procs", "0", "--formats", "json,html", prefix=NO_CGROUPS)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "--max-procs" not in proc.stderr  # no process limit asked for: nothing to warn of
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["sandbox"]["process_limit"] == NO_PROCESS_LIMIT
    assert doc["sandbox"]["limits"]["max_procs"] == 0
    assert sorted(t["team"] for t in doc["teams"]) == ["a", "b"]
    assert all(t["n"] == 1 and not t["failures"].get("crash") for t in doc["teams"]), doc
    assert f"process limit {NO_PROCESS_LIMIT}" in (out / "leaderboard.html").read_text()


@pytest.mark.integration
@needs_root_unshare
def test_eval_without_a_pids_cgroup_keeps_the_warning(one_image, tmp_path):
    team = _teams(tmp_path / "subs") / "a"
    proc = _cli("eval", str(one_image), "--cmd", f"{sys.executable} {team}/map.py --image "
                "{image}", "--sandbox", "none", "--no-progress", prefix=NO_CGROUPS)
    assert proc.returncode == 0, proc.stderr[-3000:]
    warnings = [line for line in proc.stderr.splitlines() if "WARNING" in line]
    assert len(warnings) == 1 and "--max-procs cannot be enforced" in warnings[0], proc.stderr


@pytest.mark.integration
def test_grade_records_how_the_limit_is_enforced(one_image, tmp_path):
    subs = _teams(tmp_path / "subs")
    out = tmp_path / "out"
    proc = _cli("grade", *_grade_argv(one_image, subs, out), *GRADE_ARGS)
    assert proc.returncode == 0, proc.stderr[-3000:]
    box = json.loads((out / "leaderboard.json").read_text())["sandbox"]
    expected = process_limit(box["limits"]["max_procs"])
    assert box["process_limit"] == expected


@pytest.mark.integration
def test_max_procs_0_lets_a_run_fork(one_image, tmp_path):
    # with a pids cgroup, 0 must become 'max' (a pids.max of 0 would refuse every fork)
    script = tmp_path / "forks.py"
    script.write_text(FORKS)
    out = tmp_path / "out"
    proc = _cli("eval", str(one_image), "--cmd", f"{sys.executable} {script} --image {{image}}",
                "--sandbox", "none", "--no-progress", "--max-procs", "0", "--out", str(out),
                "--formats", "json")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "WARNING" not in proc.stderr, proc.stderr
    image = json.loads((out / "report.json").read_text())["images"][0]
    assert image["category"] in (None, "wrong_count", "area_off"), image
