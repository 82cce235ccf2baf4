"""The user cache folder of arenabench: twin sets and reports of ``arenabench check``, the
competition's Python environment, and texture images kept by their content."""

from __future__ import annotations

import os
from pathlib import Path

#: Environment variable naming the cache folder (default: ``$XDG_CACHE_HOME/arenabench``, else
#: ``~/.cache/arenabench``).
CACHE_ENV = "ARENABENCH_CACHE_DIR"


def cache_dir() -> Path:
    """The user cache folder of arenabench (see :data:`CACHE_ENV`)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "arenabench"
