"""What a pipeline answered, as a :class:`~arenabench.eval.scoring.results.Prediction`.

Used by the in-process adapters (:mod:`arenabench.eval.pipelines`) and by the external
command runner (:mod:`arenabench.eval.runs.command`, cold and warm runs alike); it runs nothing.

- :func:`prediction_from_result`: a mapping or object (an in-process pipeline's return value,
  or a command's JSON line) with ``count``, ``area`` (or ``total_area``), optional
  ``marker_ids`` and ``status``, and the drawing fields (:func:`drawing_from_result`).
- :func:`last_json_line`: a command's answer in ``--output json`` mode.
- :func:`prediction_from_run`: what one finished external run (its launcher's result, stdout,
  stderr and working directory) comes to, with thumbnails of the images the run left in its
  working directory (:mod:`arenabench.eval.runs.run_images`; cold and warm runs alike).

Outcome of an external run (:func:`prediction_from_run`)
--------------------------------------------------------
``timeout`` (message ``timed out after T s ...``); ``limit`` when the run failed after
hitting a limit, the message starting with which: ``memory limit (--memory-limit 2G) ...``,
``process limit (--max-procs 64) ...``, ``file size limit (--max-file-size 64M) ...``;
``crash`` (non-zero exit other than :data:`~arenabench.competition.EXIT_MARKERS_NOT_FOUND`,
or a signal); ``markers_not_found`` (that exit status); ``bad_output`` (no or unparseable
``obstacles.txt``, one larger than :data:`OBSTACLES_MAX_BYTES` or not a regular file, no
JSON line); else ``ok``.
"""

from __future__ import annotations

import itertools
import json
import os
import reprlib
import signal
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from arenabench.cliopts import format_size
from arenabench.competition import (
    EXIT_MARKERS_NOT_FOUND,
    OBSTACLES_FILE,
    OutputFormatError,
    check_area,
    check_count,
    check_marker_id,
    parse_obstacles_txt,
)
from arenabench.eval.scoring.results import HarnessError, Prediction, tail
from arenabench.limits import MAX_MARKER_ID

from .limits import RunLimits
from .run_images import collect_run_images

#: A timed-out run that waited for a CPU (runnable, not running) for at least this share of
#: its timeout was *starved*: the machine, not the pipeline, made it late. Measured from the
#: scheduler's own account of the run's threads (``/proc/PID/task/TID/schedstat``).
STARVED_SHARE = 0.25
#: Times a starved run is run again before its timeout is kept (marked ``starved``).
STARVED_RETRIES = 2

#: How a command answers: ``obstacles.txt`` in its working directory, or a JSON line on stdout.
OUTPUT_MODES: tuple[str, ...] = ("obstacles", "json")
#: Largest ``obstacles.txt`` read; a larger one is ``bad_output``.
OBSTACLES_MAX_BYTES = 64 * 1024

_MEMORY_SIGNS = ("MemoryError", "std::bad_alloc", "Cannot allocate memory", "out of memory",
                 "Out of memory", "failed to map segment", "cannot allocate")
_FSIZE_SIGNS = ("File too large",)
_NPROC_SIGNS = ("Resource temporarily unavailable", "BlockingIOError", "fork: retry")


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


#: Most marker ids an answer may list: every id of the largest ArUco dictionary once.
MAX_ANSWER_MARKER_IDS = MAX_MARKER_ID + 1


def _as_list(ids: Any) -> list[Any]:
    """The first :data:`MAX_ANSWER_MARKER_IDS` items of ``ids`` (an endless iterable is not
    drained), or :class:`OutputFormatError` when there are more or it is not a list."""
    if isinstance(ids, (str, bytes, Mapping)):
        raise OutputFormatError(f"marker ids are not a list of integers: {_short(ids)}")
    try:
        out = list(itertools.islice(iter(ids), MAX_ANSWER_MARKER_IDS + 1))
    except Exception:
        raise OutputFormatError(f"marker ids are not a list of integers: {_short(ids)}") from None
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
                   f"attributes): {type(result).__name__} {_short(result)}")
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
            else tuple(check_marker_id(i) for i in _as_list(ids))
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


def read_small(path: Path, limit: int, *, name: str = OBSTACLES_FILE) -> bytes:
    """Read a regular file of at most ``limit`` bytes without following links or blocking.

    Raises
    ------
    OutputFormatError
        When it is not a regular file or is larger than ``limit`` (the message names the file
        as ``name``).
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as exc:
        raise OutputFormatError(f"{name} cannot be read: {exc.strerror}") from None
    st = os.fstat(fd)  # before fdopen, which refuses a directory with IsADirectoryError
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise OutputFormatError(f"{name} is {kind}")
    with os.fdopen(fd, "rb") as fh:
        if st.st_size > limit:
            raise OutputFormatError(
                f"{name} is {st.st_size} bytes, more than the {limit} allowed"
            )
        return fh.read(limit + 1)[:limit]


def limit_hit(result: dict, stderr: str, *, limits: RunLimits, pids_cgroup: bool) -> str | None:
    """Which limit a failed run hit, as the message's start (``None``: none).

    ``pids_cgroup``: whether the run had a pids cgroup (without one, the process limit is
    ``RLIMIT_NPROC`` and shows only in what the command printed).
    """
    rc, last = result["rc"], stderr[-4000:]
    if result.get("pids_limit_hit") or (
        not pids_cgroup and limits.max_procs and any(s in last for s in _NPROC_SIGNS)
    ):
        return f"process limit (--max-procs {limits.max_procs}) reached"
    if rc in (-signal.SIGXFSZ, 128 + signal.SIGXFSZ) or any(s in last for s in _FSIZE_SIGNS):
        return f"file size limit (--max-file-size {format_size(limits.max_file_size)}) reached"
    if any(s in last for s in _MEMORY_SIGNS):
        return f"memory limit (--memory-limit {format_size(limits.memory_bytes)}) reached"
    return None


def prediction_from_run(result: dict, stdout: str, stderr: str, workdir: str, *, output: str,
                        limits: RunLimits, pids_cgroup: bool) -> Prediction:
    """The :class:`Prediction` of one finished external run (see the module docstring).

    Parameters
    ----------
    result : dict
        The launcher's (or warm server's) result: ``rc``, ``latency_ms``, ``timed_out``,
        optional ``error``, ``harness_error``, ``pids_limit_hit`` and ``wait_ms``.
    stdout, stderr : str
        What the command printed (the kept tails).
    workdir : str
        The run's working directory (where ``obstacles.txt`` is read, and the images the run
        left there: :func:`~arenabench.eval.runs.run_images.collect_run_images`).
    output : {"obstacles", "json"}, keyword-only
        How the command answers (:data:`OUTPUT_MODES`).
    limits : RunLimits, keyword-only
        The run's limits (named in ``limit`` and ``timeout`` messages).
    pids_cgroup : bool, keyword-only
        Whether the run had a pids cgroup (:func:`limit_hit`).

    Raises
    ------
    HarnessError
        When the launcher could not prepare the run (``harness_error``): not the command's
        failure.
    """
    if result.get("harness_error"):
        raise HarnessError(result["harness_error"][:500])
    rc, latency = result["rc"], float(result["latency_ms"])
    keep = {"stdout": tail(stdout), "stderr": tail(stderr), "latency_ms": latency,
            "run_images": collect_run_images(workdir)}
    if result.get("error"):
        return Prediction(status="crash", message=result["error"][:500], **keep)
    failed = result["timed_out"] or rc not in (0, EXIT_MARKERS_NOT_FOUND)
    which = limit_hit(result, stderr, limits=limits, pids_cgroup=pids_cgroup)
    last = stderr.strip().splitlines()[-1:] or [""]
    if which and (failed or result.get("pids_limit_hit")):
        return Prediction(status="limit", message=f"{which}: {last[0][:300]}".rstrip(": "),
                          **keep)
    if result["timed_out"]:
        msg = f"timed out after {limits.timeout_s:g} s (all its processes killed)"
        wait_s = float(result.get("wait_ms") or 0.0) / 1e3
        if wait_s >= STARVED_SHARE * limits.timeout_s:
            return Prediction(status="timeout", starved=True, message=(
                f"{msg}; starved: it waited {wait_s:.1f} s for a CPU (the machine was busy)"),
                **keep)
        return Prediction(status="timeout", message=msg, **keep)
    if rc not in (0, EXIT_MARKERS_NOT_FOUND):
        why = f"killed by signal {-rc}" if rc < 0 else f"exit status {rc}"
        return Prediction(
            status="crash", message=f"{why}: {last[0][:300]}".rstrip(": "), **keep
        )
    try:
        if output == "json":
            parsed_json: Any = last_json_line(stdout)
            if rc == EXIT_MARKERS_NOT_FOUND and isinstance(parsed_json, dict):
                parsed_json.setdefault("status", "markers_not_found")
            pred = prediction_from_result(parsed_json, latency_ms=latency, stdout=stdout)
            return Prediction(**{**pred.__dict__, "stderr": tail(stderr),
                                 "run_images": keep["run_images"]})
        path = Path(workdir) / OBSTACLES_FILE
        if not os.path.lexists(path):
            if rc == EXIT_MARKERS_NOT_FOUND:
                return Prediction(status="markers_not_found",
                                  message=f"exit status {EXIT_MARKERS_NOT_FOUND}", **keep)
            return Prediction(
                status="bad_output",
                message=f"{OBSTACLES_FILE} was not written to the working directory",
                **keep,
            )
        text = read_small(path, OBSTACLES_MAX_BYTES).decode("utf-8", errors="replace")
        parsed = parse_obstacles_txt(text)
    except OutputFormatError as exc:
        if rc == EXIT_MARKERS_NOT_FOUND:
            return Prediction(status="markers_not_found", message=str(exc), **keep)
        return Prediction(status="bad_output", message=str(exc)[:500], **keep)
    return Prediction(
        status="markers_not_found" if rc == EXIT_MARKERS_NOT_FOUND else "ok",
        count=parsed.count,
        area=parsed.area,
        marker_ids=tuple(parsed.marker_ids),
        message=(f"exit status {EXIT_MARKERS_NOT_FOUND}: markers not found"
                 if rc == EXIT_MARKERS_NOT_FOUND else ""),
        **keep,
    )
