"""Pipeline adapters: turn "something that detects obstacles" into a :class:`Prediction` per image.

- :class:`BuiltinPipeline`: ``reference`` / ``seed`` from :mod:`arenabench.pipeline`, in-process.
- :class:`CallablePipeline`: a Python function (or ``"pkg.module:function"``) taking a BGR
  image and returning a mapping or object with ``count``, ``area`` (or ``total_area``) and
  optionally ``marker_ids`` and ``status``.
- :class:`CommandPipeline` (defined in :mod:`arenabench.eval.external`): a team's script run
  as it is graded, e.g. ``python3 map.py --image {image}``: a private directory per image, no
  shell, sandbox, limits and cleanup of every process it starts; ``obstacles.txt`` (or a JSON
  line on stdout) parsed.

No adapter ever raises for a bad pipeline: crashes, timeouts, limits and garbage
become a :class:`Prediction` with status ``crash``, ``timeout``, ``limit`` or ``bad_output``
and a message.
"""

from __future__ import annotations

import importlib
import json
import os
import reprlib
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from arenabench.competition import (
    OutputFormatError,
    check_area,
    check_count,
)
from arenabench.pipeline.config import PROFILES

from .external import EXIT_MARKERS_NOT_FOUND, OUTPUT_MODES, CommandPipeline
from .results import Prediction, tail

__all__ = [
    "BUILTIN_PIPELINES", "EXIT_MARKERS_NOT_FOUND", "OUTPUT_MODES", "BuiltinPipeline",
    "CallablePipeline", "CommandPipeline", "Pipeline", "last_json_line", "make_pipeline",
    "prediction_from_result",
]  # fmt: skip

#: The built-in pipelines are the detection profiles.
BUILTIN_PIPELINES: tuple[str, ...] = PROFILES


class Pipeline(Protocol):
    """What the runner needs of a pipeline."""

    name: str
    in_process: bool

    def run(self, image_path: Path) -> Prediction:
        """Run on one image; never raises for a pipeline's own failure."""
        ...


def _read_image(path: Path) -> Any:
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise OSError(f"could not read image {path}")
    return image


def _get(result: Any, *names: str) -> Any:
    for name in names:
        if isinstance(result, Mapping):
            if name in result:
                return result[name]
        elif hasattr(result, name):
            return getattr(result, name)
    return None


def _short(value: Any) -> str:
    """A bounded repr (a pipeline may return a huge or unprintable object)."""
    try:
        return reprlib.repr(value)[:200]
    except Exception:
        return f"<unprintable {type(value).__name__}>"


def _as_list(ids: Any) -> list[Any]:
    if isinstance(ids, (str, bytes, Mapping)):
        raise OutputFormatError(f"marker ids are not a list of integers: {_short(ids)}")
    try:
        return list(ids)
    except Exception:
        raise OutputFormatError(f"marker ids are not a list of integers: {_short(ids)}") from None


def prediction_from_result(result: Any, *, latency_ms: float, stdout: str = "") -> Prediction:
    """Normalise what an in-process pipeline (or a JSON line) returned.

    Parameters
    ----------
    result : mapping or object
        With ``count``, ``area`` or ``total_area``, optional ``marker_ids`` and ``status``
        (``"ok"`` or ``"markers_not_found"``; default ``"ok"``).
    latency_ms : float
        Measured call time.
    stdout : str
        Output tail to keep.

    Returns
    -------
    Prediction
        Status ``bad_output`` (with a message) when fields are missing or malformed: a count
        or marker id that is not a non-negative integer, an area that is negative or not a
        finite number (NaN, infinity), a boolean or a string where a number belongs.
    """
    def bad(msg: str) -> Prediction:
        return Prediction(
            status="bad_output", message=msg, stdout=tail(stdout), latency_ms=latency_ms
        )

    try:  # a hostile result may raise from attribute access, comparison or repr
        status = _get(result, "status")
        status = "ok" if status is None else status
        count, area = _get(result, "count"), _get(result, "area", "total_area")
        ids = _get(result, "marker_ids", "ids")
        known = isinstance(status, str) and status in ("ok", "markers_not_found")
    except Exception as exc:
        return bad(f"unreadable pipeline result ({type(exc).__name__}: {exc})"[:500])
    if not known:
        return bad(f"unknown status {_short(status)} in pipeline result {_short(result)}")
    try:
        count_v = None if count is None else check_count(count)
        area_v = None if area is None else check_area(area)
        ids_v = (
            None if ids is None
            else tuple(check_count(i, name="marker id") for i in _as_list(ids))
        )
    except OutputFormatError as exc:
        return bad(str(exc))
    if status == "ok" and (count_v is None or area_v is None):
        return bad(f"pipeline result lacks count or area: {_short(result)}")
    return Prediction(
        status=status,
        count=count_v,
        area=area_v,
        marker_ids=ids_v,
        stdout=tail(stdout),
        latency_ms=latency_ms,
        **drawing_from_result(result),
    )


#: Most polygons / points per polygon kept for drawing (more is not a box outline).
MAX_DRAWN_POLYGONS, MAX_POLYGON_POINTS = 100, 400
#: Largest distance (px) of a drawn polygon from the pipeline's contour (a thumbnail shows
#: the 1000 px frame at about 380 px, so 2 px is under one thumbnail pixel).
DRAWN_POLYGON_TOLERANCE_PX = 2.0


def _polygon(points: Any) -> tuple[tuple[float, float], ...] | None:
    import math

    import cv2
    import numpy as np

    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if pts.ndim != 2 or pts.shape[1] != 2 or not 3 <= len(pts) <= 100_000:
        return None
    if not np.isfinite(pts).all() or np.abs(pts).max() > 1e6:
        return None
    if len(pts) > 8:  # contours: keep the outline to within DRAWN_POLYGON_TOLERANCE_PX
        pts = cv2.approxPolyDP(pts.astype(np.float32).reshape(-1, 1, 2),
                               DRAWN_POLYGON_TOLERANCE_PX, True)
        pts = pts.reshape(-1, 2).astype(np.float64)[:MAX_POLYGON_POINTS]
    if len(pts) < 3:
        return None
    return tuple((round(float(x), 1), round(float(y), 1)) for x, y in pts
                 if math.isfinite(x) and math.isfinite(y))


def drawing_from_result(result: Any) -> dict[str, Any]:
    """The :class:`Prediction` drawing fields (``obstacles``, ``obstacles_space``,
    ``homography``) found in what a pipeline returned; empty when there are none.

    Read from, in order: ``obstacles_frame`` (polygons in frame px), ``obstacles_image``
    (polygons in input image px), or ``obstacles`` whose items have a ``contour`` (frame px, as
    :class:`arenabench.pipeline.Detection` and ``arenabench detect --json --contours`` give);
    ``homography`` is the input image px -> frame px matrix. Malformed values are ignored:
    drawing never changes a score.
    """
    out: dict[str, Any] = {}
    polys, space = None, "frame"
    if (found := _get(result, "obstacles_frame")) is not None:
        polys = found
    elif (found := _get(result, "obstacles_image")) is not None:
        polys, space = found, "image"
    elif isinstance(found := _get(result, "obstacles"), (list, tuple)):
        polys = [_get(o, "contour") for o in found]
    if isinstance(polys, (list, tuple)):
        kept = [p for p in (_polygon(q) for q in polys[:MAX_DRAWN_POLYGONS]) if p]
        out["obstacles"], out["obstacles_space"] = tuple(kept), space
    h = _get(result, "homography")
    if h is not None:
        try:
            import numpy as np

            m = np.asarray(h, dtype=np.float64)
            if m.shape == (3, 3) and np.isfinite(m).all() and abs(np.linalg.det(m)) > 1e-12:
                out["homography"] = tuple(tuple(float(v) for v in row) for row in m)
        except (TypeError, ValueError):
            pass
    return out


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
class BuiltinPipeline:
    """The project's own pipeline, ``reference`` or ``seed`` profile, called in-process.

    Parameters
    ----------
    profile : {"reference", "seed"}
    """

    profile: str = "reference"
    in_process: bool = field(default=True, init=False)

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


def load_callable(spec: str) -> Callable[[Any], Any]:
    """Import ``"pkg.module:function"`` (dotted attribute paths allowed after the colon).

    The module is looked for in the current folder first, then on ``sys.path`` (as
    ``python -m`` does), so ``mymod:fn`` finds ``./mymod.py``.

    Raises
    ------
    ValueError
        When ``spec`` is malformed, the module cannot be imported or the attribute is missing
        or not callable.
    """
    module_name, sep, attr = spec.partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"pipeline spec must look like 'pkg.module:function', got {spec!r}")
    saved_path = list(sys.path)
    sys.path.insert(0, os.getcwd())
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(
            f"pipeline {spec!r}: cannot import {module_name!r} (looked in the current folder "
            f"{os.getcwd()} and on sys.path): {exc}"
        ) from None
    finally:
        sys.path[:] = saved_path
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"pipeline {spec!r}: {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"pipeline {spec!r}: {attr!r} is not callable")
    return obj


@dataclass
class CallablePipeline:
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
    in_process: bool = field(default=True, init=False)

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


def last_json_line(stdout: str) -> Any:
    """The last line of ``stdout`` that parses as a JSON object (a command's answer).

    Raises
    ------
    OutputFormatError
        When no line does.
    """
    for line in reversed(stdout.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                return json.loads(line)
            except (json.JSONDecodeError, RecursionError):  # nested too deeply: not an answer
                continue
    raise OutputFormatError(f"no JSON object line on stdout: {stdout.strip()[-200:]!r}")


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
        from arenabench.suggest import did_you_mean

        raise ValueError(
            f"pipeline must be one of {BUILTIN_PIPELINES} or 'pkg.module:function', got "
            f"{spec!r}{did_you_mean(spec, BUILTIN_PIPELINES)}"
        )
    if hasattr(spec, "run") and hasattr(spec, "name"):
        return spec  # type: ignore[return-value]
    if callable(spec):
        return CallablePipeline(spec)
    raise ValueError(f"pipeline must be a name, a callable or a pipeline object, got {spec!r}")
