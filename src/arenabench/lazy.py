"""Lazy package exports: ``from pkg import name`` imports ``name``'s module on first use.

Keeps ``import arenabench.eval`` (and so the pytest plugin) and ``import arenabench.generator``
cheap: nothing heavy (pyrender, matplotlib, dask) loads until a name that needs it is used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, exports: dict[str, str]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` for ``package`` serving ``exports`` lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : dict
        Exported name -> module that defines it, relative to ``package`` (``"evaluation"``).

    Returns
    -------
    callable
        Assign it to the package's ``__getattr__``.
    """

    def __getattr__(name: str) -> Any:
        if name in exports:
            return getattr(importlib.import_module(f"{package}.{exports[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
