"""pytest plugin (entry point ``pytest11``): a cached dataset fixture for teams' own tests.

Usage in a team's test suite::

    from arenabench.eval import score

    def test_my_pipeline(arenabench_dataset):
        assert score(my_pipeline, arenabench_dataset).pass_rate >= 0.95

``arenabench_dataset`` (session scope) is the path of a small generated dataset, cached under
pytest's cache folder (``.pytest_cache/d/arenabench/``) and keyed by preset, count, seed and
the generator's version (``GENERATOR_VERSION``: an update that changes the images or the ground
truth renders a new set), so it is rendered once and reused by later runs (under
``-p no:cacheprovider``: in a temporary folder, rendered again each session). Options:
``--arenabench-preset`` (default ``eyrc``; a name or a preset file),
``--arenabench-count`` (default 12), ``--arenabench-seed`` (default 0), or
``--arenabench-dataset DIR`` to use an existing dataset.

This module imports only the standard library and pytest at start-up; the generator is
imported when the fixture is first used.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("arenabench", "arenabench dataset fixture")
    # default None: the generator's default preset, looked up when the fixture is used (the
    # plugin imports no generator at start-up)
    group.addoption("--arenabench-preset", default=None,
                    help="generator preset: a built-in name or a preset file (default: the "
                         "generator's default preset, eyrc)")
    group.addoption("--arenabench-count", type=int, default=12, help="images (default 12)")
    group.addoption("--arenabench-seed", type=int, default=0, help="generator seed (default 0)")
    group.addoption(
        "--arenabench-dataset", default=None, help="use this existing dataset folder instead"
    )


def dataset_key(preset: str, count: int, seed: int) -> str:
    """Cache folder name of a generated dataset: ``<preset>-n<count>-s<seed>-v<generator
    version>`` (imports the generator); a preset file is named by its preset's name and a
    hash of its parameters (:func:`~arenabench.generator.parameters.presets.preset_key`).

    Raises
    ------
    pytest.UsageError
        For an unknown preset or a bad preset file (one line).
    """
    from arenabench.generator.dataset.make import GENERATOR_VERSION
    from arenabench.generator.parameters.presets import preset_key, resolve_preset

    try:
        key = preset_key(resolve_preset(preset))
    except ValueError as exc:
        raise pytest.UsageError(f"--arenabench-preset: {exc}") from None
    return f"{key}-n{count}-s{seed}-v{GENERATOR_VERSION}"


def _generate(out: Path, *, preset: str, count: int, seed: int) -> None:
    from arenabench.generator.commands.generate import main as generate_main

    argv = ["--preset", preset, "--count", str(count), "--seed", str(seed), "--out", str(out)]
    rc = generate_main(argv)
    if rc != 0 or not (out / "manifest.jsonl").is_file():
        raise RuntimeError(f"arenabench generate {' '.join(argv)} failed with exit status {rc}")


@pytest.fixture(scope="session")
def arenabench_dataset(request: pytest.FixtureRequest) -> Path:
    """Path of a small generated dataset (generated once, then reused from pytest's cache)."""
    config = request.config
    given = config.getoption("--arenabench-dataset")
    if given:
        path = Path(given).resolve()
        if not (path / "manifest.jsonl").is_file():
            raise pytest.UsageError(f"--arenabench-dataset {path}: no manifest.jsonl there")
        return path
    preset = config.getoption("--arenabench-preset")
    if preset is None:
        from arenabench.generator.parameters.presets import DEFAULT_PRESET

        preset = DEFAULT_PRESET
    count = config.getoption("--arenabench-count")
    seed = config.getoption("--arenabench-seed")
    cache = getattr(config, "cache", None)  # no attribute under -p no:cacheprovider
    if cache is not None:
        root = cache.mkdir("arenabench")
    else:  # no cache: a temporary folder of this session (generated again next time)
        root = request.getfixturevalue("tmp_path_factory").mktemp("arenabench")
    final = Path(root) / dataset_key(preset, count, seed)
    if (final / "manifest.jsonl").is_file():
        return final
    tmp = Path(root) / f".{final.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    _generate(tmp, preset=preset, count=count, seed=seed)
    try:
        os.replace(tmp, final)
    except OSError:  # another process won the race: use its copy
        shutil.rmtree(tmp, ignore_errors=True)
    return final
