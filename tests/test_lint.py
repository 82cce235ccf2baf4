"""The code base stays ruff-clean: `make test` fails on a lint error."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _ruff() -> list[str]:
    """The ruff command: this interpreter's ``-m ruff`` where the package is importable (a
    virtual environment that reuses another's site-packages has no ``ruff`` script of its
    own), else the ``ruff`` on PATH or beside the interpreter."""
    if importlib.util.find_spec("ruff") is not None:
        return [sys.executable, "-m", "ruff"]
    exe = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    if not Path(exe).exists():
        pytest.fail("ruff is not installed: it is in the 'test' extra (pip install -e '.[test]')")
    return [exe]


def test_ruff_clean():
    proc = subprocess.run([*_ruff(), "check", str(ROOT)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
