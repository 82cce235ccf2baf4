"""Fixtures shared by the test modules of external commands."""

from __future__ import annotations

import tempfile

import pytest

from arenabench.eval.runs.context import RunContext


@pytest.fixture()
def run_tmp(tmp_path, monkeypatch):
    """The folder the runs' private directories (and warm servers' folders) go to, checked
    empty afterwards: whatever the test ran, its run contexts are closed by then."""
    d = tmp_path / "runs"
    d.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(d))
    yield d
    assert list(d.iterdir()) == [], "a server's or run's directory was left behind"


@pytest.fixture()
def runs(run_tmp):
    """A run context for the test's pipelines (``runs.command(...)``), closed at its end,
    before :func:`run_tmp` checks its folder."""
    with RunContext() as context:
        yield context


@pytest.fixture(scope="session")
def competition_cache(tmp_path_factory):
    """A cache folder (``ARENABENCH_CACHE_DIR``) holding the competition's Python environment,
    made once per test session from the package index exactly as ``arenabench check`` makes it
    (a real second virtual environment with the competition's numpy and OpenCV)."""
    from arenabench.eval.runs.competition_env import competition_python

    cache = tmp_path_factory.mktemp("competition-cache")
    made = competition_python(cache=cache, progress=False, prog="tests")
    if made.source != "competition":
        pytest.fail(f"the competition environment could not be made: {made.problem}")
    return cache
