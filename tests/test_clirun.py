"""tests/clirun.py answers what a real ``arenabench`` process answers: the same exit status,
stdout and stderr, with nothing left behind in the test process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from clirun import run_cli

EXAMPLE = Path(__file__).resolve().parent / "data" / "task1c_image.jpg"


def _process(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "arenabench", *argv], capture_output=True,
                          text=True, timeout=120, cwd=cwd)


@pytest.mark.parametrize("argv", [
    ("eval", ".", "--pipeline", "reference", "--wokers", "2"),   # usage error, exit 2
    ("nosuch",),                                                  # unknown command
    ("--version",),
    ("detect", "--image", str(EXAMPLE)),                          # a file and a summary line
    ("detect", "--image", "missing.png"),                         # bad input, exit 2
])
def test_same_answer_as_a_real_process(argv, tmp_path):
    answer = tmp_path / "obstacles.txt"
    real = _process(*argv, cwd=tmp_path)
    real_file = answer.read_text() if answer.exists() else None
    answer.unlink(missing_ok=True)
    here = run_cli(*argv, cwd=tmp_path)
    assert (here.returncode, here.stdout, here.stderr) == (real.returncode, real.stdout,
                                                           real.stderr)
    assert (answer.read_text() if answer.exists() else None) == real_file


def test_no_state_is_left_behind(tmp_path):
    before = (os.getcwd(), dict(os.environ), signal.getsignal(signal.SIGINT),
              signal.getsignal(signal.SIGTERM))
    run_cli("presets", cwd=tmp_path, env={"ARENABENCH_TEST_VARIABLE": "1"})
    after = (os.getcwd(), dict(os.environ), signal.getsignal(signal.SIGINT),
             signal.getsignal(signal.SIGTERM))
    assert after == before
