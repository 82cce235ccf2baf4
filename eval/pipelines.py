"""Pipeline adapters: turn "something that detects obstacles" into a :class:`Prediction` per image.

- :class:`BuiltinPipeline`: ``reference`` / ``seed`` from :mod:`arenabench.pipeline`, in-process.
- :class:`CallablePipeline`: a Python function (or ``"pkg.module:function"``) taking a BGR
  image and returning a mapping or object with ``count``, ``area`` (or ``total_area``) and
  optionally ``marker_ids`` and ``status``.
- :class:`~arenabench.eval.runs.pipeline.CommandPipeline` (in its own module): a team's script run
  as it is graded, e.g. ``python3 map.py --image {image}``: a private directory per image, no
  shell, sandbox, limits and cleanup of every process it starts; ``obstacles.txt`` (or a JSON
  line on stdout) parsed.

What a pipeline returned becomes a :class:`Prediction` in :mod:`arenabench.eval.scoring.answers`.

No adapter ever raises for a bad pipeline: crashes, timeouts, limits and garbage
become a :class:`Prediction` with status ``crash``, ``timeout``, ``limit`` or ``bad_output``
and a message.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from arenabench.eval.scoring.answers import prediction_from_result
from arenabench.eval.scoring.results import Prediction, tail
from arenabench.pipeline.config import PROFILES

__all__ = [
    "BUILTIN_PIPELINES", "BuiltinPipeline", "CallablePipeline", "Pipeline", "call_on_image",
    "load_callable", "make_pipeline", "pipeline_name_problem", "signature_problem",
]  # fmt: skip

#: The built-in pipelines are the detection profiles.
BUILTIN_PIPELINES: tuple[str, ...] = PROFILES


class Pipeline(Protocol):
    """What the evaluation loop needs of a pipeline, whatever kind it is (the loop never asks
    which): in-process (:class:`BuiltinPipeline`, :class:`CallablePipeline`), in killable child
    processes (:class:`~arenabench.eval.runs.isolated.IsolatedCallablePipeline`) or an external
    command (:class:`~arenabench.eval.runs.pipeline.CommandPipeline`)."""

    name: str
    #: Runs in this process (a process pool may run it in its workers instead).
    in_process: bool

    def run(self, image_path: Path) -> Prediction:
        """Run on one image; never raises for a pipeline's own failure."""
        ...

    def threads(self, workers: int) -> int:
        """Threads the loop runs for ``workers`` images at once (called once, first)."""
        ...

    def stop(self) -> None:
        """Kill what runs now; later runs return at once (a stop signal)."""
        ...

    def close(self) -> None:
        """The end of the loop's use: end what the pipeline holds (servers, processes)."""
        ...


class InProcess:
    """What an in-process pipeline answers of :class:`Pipeline` beyond :meth:`run`: a thread
    per worker, nothing to stop or to end."""

    in_process = True

    def threads(self, workers: int) -> int:
        """One thread per worker."""
        return workers

    def stop(self) -> None:
        """Nothing runs outside the caller's threads."""

    def close(self) -> None:
        """Nothing to end."""


def _read_image(path: Path) -> Any:
    """The image as ``cv2.imread(path, IMREAD_COLOR)`` gives it, read only if it is a regular
    file (a FIFO in its place never blocks)."""
    import cv2
    import numpy as np

    from arenabench.imageio import ImageLoadError, read_image_bytes

    try:
        data = read_image_bytes(path)
    except ImageLoadError as exc:
        raise OSError(f"could not read image {exc}") from None
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise OSError(f"could not read image {path}")
    return image


def _call_in_process(func: Callable[[Any], Any], image_path: Path) -> Prediction:
    try:
        image = _read_image(image_path)
    except OSError as exc:
        return Prediction(status="crash", message=str(exc))
    return call_on_image(func, image)


def call_on_image(func: Callable[[Any], Any], image: Any) -> Prediction:
    """Call an in-process pipeline on a BGR image already in memory (never raises for the
    pipeline's own failures; the latency excludes any image decoding)."""
    start = time.perf_counter()
    try:
        result = func(image)
    except Exception as exc:  # a bad pipeline must never kill the harness
        latency = (time.perf_counter() - start) * 1000.0
        return Prediction(
            status="crash",
            message=f"{type(exc).__name__}: {exc}"[:500],
            stderr=tail(traceback.format_exc()),
            latency_ms=latency,
        )
    latency = (time.perf_counter() - start) * 1000.0
    return prediction_from_result(result, latency_ms=latency)


@dataclass
class BuiltinPipeline(InProcess):
    """The project's own pipeline, ``reference`` or ``seed`` profile, called in-process.

    Parameters
    ----------
    profile : {"reference", "seed"}
    """

    profile: str = "reference"

    def __post_init__(self) -> None:
        if self.profile not in BUILTIN_PIPELINES:
            raise ValueError(f"profile must be one of {BUILTIN_PIPELINES}, got {self.profile!r}")
        self._func: Callable[[Any], Any] | None = None

    @property
    def name(self) -> str:
        """Pipeline name as written in reports."""
        return self.profile

    def _load(self) -> Callable[[Any], Any]:
        if self._func is None:
            from arenabench.pipeline import DetectConfig, detect

            config = DetectConfig(profile=self.profile)
            self._func = lambda image: detect(image, config)
        return self._func

    def run(self, image_path: Path) -> Prediction:
        """Detect on one image."""
        return _call_in_process(self._load(), image_path)

    def run_image(self, image: Any) -> Prediction:
        """Detect on a BGR image in memory."""
        return call_on_image(self._load(), image)


def _dotted(name: str) -> bool:
    return bool(name) and all(part.isidentifier() for part in name.split("."))


def _spec_hint(module_name: str, attr: str) -> str:
    """How to name a pipeline given as a file path (``../ci/mypipe.py:detect``)."""
    path = Path(module_name)
    module = path.stem if path.suffix == ".py" else path.name
    where = ("" if str(path.parent) == "." else
             f" and run from {path.parent} (or put {path.parent} on PYTHONPATH)")
    return (f": the part before ':' is a module name, not a file: name it "
            f"'{module}:{attr}'{where}")


def signature_problem(func: Callable[..., Any]) -> str | None:
    """Why ``func`` cannot be called with one image, from its signature (``None`` when it can,
    or when Python cannot tell: a built-in without a signature)."""
    import inspect

    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return None
    try:
        sig.bind(object())
    except TypeError:
        name = getattr(func, "__qualname__", None) or type(func).__name__
        return f"{name}{sig} cannot be called with one image"
    return None


def load_callable(spec: str) -> Callable[[Any], Any]:
    """Import ``"pkg.module:function"`` (dotted attribute paths allowed after the colon).

    The module is looked for in the current folder first, then on ``sys.path`` (as
    ``python -m`` does), so ``mymod:fn`` finds ``./mymod.py``. A file path before the colon
    (``../ci/mypipe.py:detect``) is refused with the spec to use instead.

    Raises
    ------
    ValueError
        When ``spec`` is malformed, the module cannot be imported (or fails while it is), or
        the attribute is missing, not callable, or cannot take one argument (its signature).
    """
    module_name, sep, attr = spec.partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"pipeline spec must look like 'pkg.module:function', got {spec!r}")
    if "/" in module_name or module_name.endswith(".py"):  # a file, not a module
        raise ValueError(f"pipeline {spec!r}{_spec_hint(module_name, attr)}")
    if not _dotted(module_name):
        raise ValueError(f"pipeline {spec!r}: {module_name!r} is not a module name (dotted "
                         "Python identifiers)")
    if not _dotted(attr):
        raise ValueError(f"pipeline {spec!r}: {attr!r} is not a (dotted) Python name")
    saved_path = list(sys.path)
    sys.path.insert(0, os.getcwd())
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(
            f"pipeline {spec!r}: cannot import {module_name!r} (looked in the current folder "
            f"{os.getcwd()} and on sys.path): {exc}"
        ) from None
    except (Exception, SystemExit) as exc:  # the module itself fails while it is imported
        raise ValueError(f"pipeline {spec!r}: importing {module_name!r} failed: "
                         f"{type(exc).__name__}: {exc}"[:500]) from None
    finally:
        sys.path[:] = saved_path
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"pipeline {spec!r}: {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"pipeline {spec!r}: {attr!r} is not callable")
    problem = signature_problem(obj)
    if problem:
        raise ValueError(f"pipeline {spec!r}: {problem}")
    return obj


def pipeline_name_problem(spec: str) -> str | None:
    """Why ``spec`` names no pipeline (not a built-in and no ``pkg.module:function``), with a
    "did you mean", or ``None``."""
    if spec in BUILTIN_PIPELINES or ":" in spec:
        return None
    from arenabench.suggest import did_you_mean

    return (f"pipeline must be one of {BUILTIN_PIPELINES} or 'pkg.module:function', got "
            f"{spec!r}{did_you_mean(spec, BUILTIN_PIPELINES)}")


@dataclass
class CallablePipeline(InProcess):
    """A Python function ``f(image_bgr) -> mapping | object`` called in-process.

    Parameters
    ----------
    func : callable or str
        The function, or ``"pkg.module:function"`` to import.
    name : str, optional
        Name in reports (default: the spec or the function's qualified name).
    """

    func: Callable[[Any], Any] | str
    name: str = ""

    def __post_init__(self) -> None:
        if isinstance(self.func, str):
            self.name = self.name or self.func
            self.func = load_callable(self.func)
        elif not callable(self.func):
            raise ValueError(f"func must be callable or 'pkg.module:function', got {self.func!r}")
        else:
            mod = getattr(self.func, "__module__", "?")
            self.name = self.name or f"{mod}:{getattr(self.func, '__qualname__', 'func')}"

    def run(self, image_path: Path) -> Prediction:
        """Call the function on one image."""
        assert callable(self.func)
        return _call_in_process(self.func, image_path)

    def run_image(self, image: Any) -> Prediction:
        """Call the function on a BGR image in memory."""
        assert callable(self.func)
        return call_on_image(self.func, image)


class _Adapted(InProcess):
    """A pipeline object of the caller's with ``run`` and ``name`` only: the rest of
    :class:`Pipeline` as an in-process one has it."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.name = str(inner.name)
        self.in_process = bool(getattr(inner, "in_process", True))

    def run(self, image_path: Path) -> Prediction:
        """The caller's ``run``."""
        return self.inner.run(image_path)


def make_pipeline(
    spec: str | Callable[[Any], Any] | Pipeline,
) -> Pipeline:
    """Build a pipeline from ``"reference"``, ``"seed"``, ``"pkg.module:function"``, a
    callable or a ready pipeline object.

    Raises
    ------
    ValueError
        When ``spec`` is none of these.
    """
    if isinstance(spec, str):
        if spec in BUILTIN_PIPELINES:
            return BuiltinPipeline(spec)
        if ":" in spec:
            return CallablePipeline(spec)
        raise ValueError(pipeline_name_problem(spec))
    if hasattr(spec, "run") and hasattr(spec, "name"):
        if all(callable(getattr(spec, m, None)) for m in ("threads", "stop", "close")):
            return spec  # type: ignore[return-value]
        return _Adapted(spec)
    if callable(spec):
        return CallablePipeline(spec)
    raise ValueError(f"pipeline must be a name, a callable or a pipeline object, got {spec!r}")
