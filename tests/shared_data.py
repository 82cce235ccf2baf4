"""Generated datasets shared by every test of a run, content-addressed and built once.

A set is named by what makes its bytes: ``(preset, count, seed, GENERATOR_VERSION)`` and any
``--set`` overrides. The first test (in any pytest-xdist worker) that asks for a set renders
it, under a file lock, into a temporary folder renamed into place when complete; every other
test, in that worker or another, reads the same folder. A set is read-only by contract: at the
end of the session every file of every set this worker handed out is checked against its hash
when it was handed out, and a test that changed one fails the run (``SharedSets.verify``). A
test that writes into its dataset works on a copy of its own (``shutil.copytree``).

The cache lives beside the workers' temporary roots (``tmp_path_factory``'s base folder's
parent under xdist, the base folder itself otherwise), so it goes with the run's temporary
files and never outlives pytest's own retention of them.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import shutil
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from arenabench.fileio import sha256_file
from arenabench.generator.dataset.make import GENERATOR_VERSION


def shared_root(base: Path) -> Path:
    """The folder every worker of this run shares, given one worker's temporary root."""
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``path`` (created) while the block runs."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def fingerprint(folder: Path) -> dict[str, str]:
    """Every file below ``folder``: {relative path: sha256 of its bytes}."""
    return {path.relative_to(folder).as_posix(): sha256_file(path)
            for path in sorted(folder.rglob("*")) if path.is_file()}


class SharedSets:
    """Generated datasets keyed by what makes their bytes (see the module's docstring).

    Parameters
    ----------
    root : Path
        The cache folder, shared by every worker of the run.
    """

    def __init__(self, root: Path) -> None:
        self.root = root
        self._handed: dict[Path, dict[str, str]] = {}

    @staticmethod
    def key(preset: str, count: int, seed: int,
            overrides: Mapping[str, object] | None = None) -> str:
        """The folder name of a set: readable, and unique for its inputs."""
        extra = ""
        if overrides:
            text = json.dumps(dict(sorted(overrides.items())), sort_keys=True)
            extra = "-o" + hashlib.sha256(text.encode()).hexdigest()[:12]
        name = preset if "/" not in preset else hashlib.sha256(preset.encode()).hexdigest()[:12]
        return f"{name}-n{count}-s{seed}{extra}-g{GENERATOR_VERSION}"

    def generated(self, preset: str = "eyrc", *, count: int, seed: int = 0,
                  overrides: Mapping[str, object] | None = None, workers: int = 1) -> Path:
        """The dataset folder of ``count`` scenes of ``preset`` at ``seed`` (rendered once per
        run, by whichever worker asks first). Read it; never write into it."""
        from arenabench.generator.dataset.dataset_writer import generate_dataset

        key = self.key(preset, count, seed, overrides)
        folder = self.root / key
        with file_lock(self.root / f"{key}.lock"):
            if not (folder / "dataset.json").is_file():
                part = self.root / f"{key}.part"
                shutil.rmtree(part, ignore_errors=True)
                made = generate_dataset(part, preset=preset, count=count, seed=seed,
                                        overrides=dict(overrides) if overrides else None,
                                        workers=workers, progress=False)
                if made.interrupted is not None or made.finished != count:
                    raise RuntimeError(f"shared set {key}: only {made.finished} of {count} made")
                part.rename(folder)
        if folder not in self._handed:
            self._handed[folder] = fingerprint(folder)
        return folder

    def verify(self) -> list[str]:
        """The files of the sets handed out that were added, removed or changed since: a test
        wrote into a shared set (empty when none did)."""
        changed = []
        for folder, before in self._handed.items():
            after = fingerprint(folder)
            changed += [str(folder / name) for name in sorted(before.keys() | after.keys())
                        if before.get(name) != after.get(name)]
        return changed
