"""The fixtures shared by every test module: the run folders of external commands, the
generated sets and the renderer every module reads, and the competition's Python environment,
each made once per run. The tiers are a plugin of their own (tests/tiers.py)."""

from __future__ import annotations

import tempfile

import pytest
from shared_data import SharedSets, shared_root

from arenabench.eval.runs.context import RunContext

# tiers: the tiers' markers, --tier and the budget summary (tests/tiers.py); pytester: the
# tier selection is tested on a toy suite
pytest_plugins = ["tiers", "pytester"]

# ------------------------------------------------------------------------ shared run data


@pytest.fixture(scope="session")
def shared_sets(tmp_path_factory):
    """Generated datasets keyed by (preset, count, seed, GENERATOR_VERSION), rendered once per
    run whichever worker asks first (tests/shared_data.py); read-only: a test that changed one
    fails the run here."""
    sets = SharedSets(shared_root(tmp_path_factory.getbasetemp()) / "shared-sets")
    yield sets
    changed = sets.verify()
    assert changed == [], f"a test wrote into a shared set: {changed[:5]}"


@pytest.fixture(scope="session")
def renderer():
    """One off-screen renderer for every test of this worker that renders in process."""
    from arenabench.generator.rendering.render import Renderer

    with Renderer() as r:
        yield r


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
    made once per run for every worker from the package index exactly as ``arenabench check``
    makes it (a real second virtual environment with the competition's numpy and OpenCV; the
    product's own build lock makes the other workers wait for it and reuse it)."""
    from arenabench.eval.runs.competition_env import competition_python

    cache = shared_root(tmp_path_factory.getbasetemp()) / "competition-cache"
    cache.mkdir(exist_ok=True)
    made = competition_python(cache=cache, progress=False, prog="tests")
    if made.source != "competition":
        pytest.fail(f"the competition environment could not be made: {made.problem}")
    return cache
