"""A pipeline's answer read into a :class:`~arenabench.eval.scoring.results.Prediction`.

Used by the in-process adapters (:mod:`arenabench.eval.in_process`), the isolated callables
and the external commands (:mod:`arenabench.eval.runs`); it runs nothing.

- :func:`prediction_from_result`: a mapping or object (an in-process pipeline's return value,
  or a command's JSON line) with ``count``, ``area`` (or ``total_area``), optional
  ``marker_ids`` and ``status``, and the drawing fields (:func:`drawing_from_result`);
- :func:`not_a_mapping`: what no pipeline returns (a trial call's refusal);
- :func:`last_json_line`: a command's answer in ``--output json`` mode.
"""

from __future__ import annotations

import itertools
import json
import reprlib
from collections.abc import Mapping
from typing import Any

from arenabench.competition import (
    OutputFormatError,
    check_area,
    check_count,
    check_marker_id,
)
from arenabench.limits import MAX_MARKER_ID

from .results import Prediction, tail


def _get(result: Any, *names: str) -> Any:
    for name in names:
        if isinstance(result, Mapping):
            if name in result:
                return result[name]
        elif hasattr(result, name):
            return getattr(result, name)
    return None


def short_repr(value: Any) -> str:
    """A bounded repr (a pipeline may return a huge or unprintable object)."""
    try:
        return reprlib.repr(value)[:200]
    except Exception:
        return f"<unprintable {type(value).__name__}>"


#: Most marker ids an answer may list: every id of the largest ArUco dictionary once.
MAX_ANSWER_MARKER_IDS = MAX_MARKER_ID + 1


def _as_list(ids: Any) -> list[Any]:
    """The first :data:`MAX_ANSWER_MARKER_IDS` items of ``ids`` (an endless iterable is not
    drained), or :class:`OutputFormatError` when there are more or it is not a list."""
    if isinstance(ids, (str, bytes, Mapping)):
        raise OutputFormatError(f"marker ids are not a list of integers: {short_repr(ids)}")
    try:
        out = list(itertools.islice(iter(ids), MAX_ANSWER_MARKER_IDS + 1))
    except Exception:
        raise OutputFormatError(
            f"marker ids are not a list of integers: {short_repr(ids)}") from None
    if len(out) > MAX_ANSWER_MARKER_IDS:
        raise OutputFormatError(f"more than {MAX_ANSWER_MARKER_IDS} marker ids, more than any "
                                "ArUco dictionary holds")
    return out


#: What a pipeline's result can never be: it is a mapping, or an object with attributes.
_NOT_MAPPINGS = (str, bytes, bytearray, int, float, complex, list, tuple, set, frozenset,
                 range, type(None))


def not_a_mapping(result: Any) -> bool:
    """Whether ``result`` cannot be a pipeline's result: a number, a string, a sequence or
    set, ``None``, or a NumPy array or scalar (``(2, 72000.0)`` has a ``count`` method, not a
    count)."""
    return isinstance(result, _NOT_MAPPINGS) or type(result).__module__ == "numpy"


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
        or marker id that is not a non-negative integer or is beyond any scene
        (:func:`~arenabench.competition.check_count`,
        :func:`~arenabench.competition.check_marker_id`), more marker ids than any dictionary
        holds, an area that is negative or not a finite number (NaN, infinity), a boolean or
        a string where a number belongs.
    """
    def bad(msg: str) -> Prediction:
        return Prediction(
            status="bad_output", message=msg, stdout=tail(stdout), latency_ms=latency_ms
        )

    if not_a_mapping(result):
        return bad("the result is not a mapping (a dict, or an object with count and area "
                   f"attributes): {type(result).__name__} {short_repr(result)}")
    try:  # a hostile result may raise from attribute access, comparison or repr
        status = _get(result, "status")
        status = "ok" if status is None else status
        count, area = _get(result, "count"), _get(result, "area", "total_area")
        ids = _get(result, "marker_ids", "ids")
        known = isinstance(status, str) and status in ("ok", "markers_not_found")
    except Exception as exc:
        return bad(f"unreadable pipeline result ({type(exc).__name__}: {exc})"[:500])
    if not known:
        return bad(f"unknown status {short_repr(status)} in pipeline result {short_repr(result)}")
    try:
        count_v = None if count is None else check_count(count)
        area_v = None if area is None else check_area(area)
        ids_v = (
            None if ids is None
            else tuple(check_marker_id(i) for i in _as_list(ids))
        )
    except OutputFormatError as exc:
        return bad(str(exc))
    if status == "ok" and (count_v is None or area_v is None):
        return bad(f"pipeline result lacks count or area: {short_repr(result)}")
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
