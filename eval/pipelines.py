"""Pipeline adapters: turn "something that detects obstacles" into a :class:`Prediction` per image.

- :class:`BuiltinPipeline`: ``reference`` / ``seed`` from :mod:`arenabench.pipeline`, in-process.
- :class:`CallablePipeline`: a Python function (or ``"pkg.module:function"``) taking a BGR
  image and returning a mapping or object with ``count``, ``area`` (or ``total_area``) and
  optionally ``marker_ids`` and ``status``.
- :class:`CommandPipeline`: a team's script run as it is graded, e.g.
  ``python3 map.py --image {image}``: fresh temporary working directory per image, no shell,
  a timeout that kills the whole process group, ``obstacles.txt`` (or a JSON line on stdout)
  parsed.

No adapter ever raises for a bad pipeline: crashes, timeouts and garbage become a
:class:`Prediction` with status ``crash``, ``timeout`` or ``bad_output`` and a message.
"""

from __future__ import annotations

import importlib
import json
import os
import reprlib
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from arenabench.competition import (
    OBSTACLES_FILE,
    OutputFormatError,
    check_area,
    check_count,
    parse_obstacles_txt,
)

from .records import Prediction, tail

BUILTIN_PIPELINES: tuple[str, ...] = ("reference", "seed")
OUTPUT_MODES: tuple[str, ...] = ("obstacles", "json")
#: Exit status by which ``arenabench detect`` (and any command) says "markers not found".
EXIT_MARKERS_NOT_FOUND = 3


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
    )


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

    Raises
    ------
    ValueError
        When ``spec`` is malformed, the module cannot be imported or the attribute is missing
        or not callable.
    """
    module_name, sep, attr = spec.partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"pipeline spec must look like 'pkg.module:function', got {spec!r}")
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(f"pipeline {spec!r}: cannot import {module_name!r}: {exc}") from None
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


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _decode(data: bytes | None) -> str:
    return (data or b"").decode("utf-8", errors="replace")


def _json_line(stdout: str) -> Any:
    for line in reversed(stdout.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                return json.loads(line)
            except (json.JSONDecodeError, RecursionError):  # nested too deeply: not an answer
                continue
    raise OutputFormatError(f"no JSON object line on stdout: {stdout.strip()[-200:]!r}")


@dataclass
class CommandPipeline:
    """An external command, run once per image the way competition scripts are graded.

    Parameters
    ----------
    template : str
        Command line, split with :func:`shlex.split` (no shell). In every argument
        ``{image}`` becomes the image's absolute path and ``{python}`` the running Python
        interpreter; substitution is per argument, so paths with spaces survive.
    timeout_s : float
        Wall-clock limit per image (default 60 s); on expiry the whole process group is
        killed and the image is a ``timeout``.
    output : {"obstacles", "json"}
        Read ``obstacles.txt`` from the working directory, or the last JSON object line on
        stdout.
    env : mapping, optional
        Extra environment variables for the command.
    name : str, optional
        Name in reports (default: the template).
    base_dir : str, optional
        Folder that relative paths in the template are relative to (default: the current
        directory when the pipeline is created).

    Notes
    -----
    Each image runs in a fresh :func:`tempfile.mkdtemp` directory (removed afterwards), in
    its own session (``start_new_session=True``). Exit status 0 means "answer written";
    exit status 3 means markers not found; any other non-zero exit is a ``crash``.
    """

    template: str
    timeout_s: float = 60.0
    output: str = "obstacles"
    env: Mapping[str, str] | None = None
    name: str = ""
    base_dir: str = field(default_factory=os.getcwd)
    in_process: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        if not self.timeout_s > 0:
            raise ValueError(f"timeout_s must be > 0, got {self.timeout_s!r}")
        if self.output not in OUTPUT_MODES:
            raise ValueError(f"output must be one of {OUTPUT_MODES}, got {self.output!r}")
        try:
            self._argv = shlex.split(self.template)
        except ValueError as exc:
            raise ValueError(f"template cannot be split into arguments: {exc}") from None
        if not self._argv:
            raise ValueError(f"template must not be empty, got {self.template!r}")
        self.name = self.name or self.template

    def argv(self, image_path: Path) -> list[str]:
        """The argument list for one image.

        Arguments that name an existing file or folder relative to ``base_dir`` (``map.py``)
        are made absolute, since the command runs in a fresh temporary directory.
        """
        image = str(Path(image_path).resolve())
        out = []
        for arg in self._argv:
            if "{" not in arg and not arg.startswith("-") and not os.path.isabs(arg):
                candidate = Path(self.base_dir, arg)
                if candidate.exists():
                    arg = str(candidate.resolve())
            out.append(arg.replace("{image}", image).replace("{python}", sys.executable))
        return out

    def run(self, image_path: Path) -> Prediction:
        """Run the command on one image in a fresh working directory."""
        workdir = tempfile.mkdtemp(prefix="arenabench-run-")
        env = dict(os.environ)
        env.update(self.env or {})
        start = time.perf_counter()
        try:
            try:
                proc = subprocess.Popen(
                    self.argv(image_path),
                    cwd=workdir,
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    start_new_session=True,
                    env=env,
                )
            except OSError as exc:
                return Prediction(status="crash", message=f"cannot start command: {exc}")
            timed_out = False
            try:
                out_b, err_b = proc.communicate(timeout=self.timeout_s)
            except subprocess.TimeoutExpired:
                timed_out = True
                _kill_group(proc)
                try:
                    out_b, err_b = proc.communicate(timeout=10)
                except subprocess.TimeoutExpired:  # a grandchild escaped the group
                    proc.kill()
                    out_b, err_b = b"", b""
            latency = (time.perf_counter() - start) * 1000.0
            _kill_group(proc)  # leftovers of a command that exited
            return self._interpret(proc.returncode, timed_out, out_b, err_b, workdir, latency)
        finally:
            shutil.rmtree(workdir, ignore_errors=True)

    def _interpret(
        self,
        rc: int,
        timed_out: bool,
        out_b: bytes | None,
        err_b: bytes | None,
        workdir: str,
        latency: float,
    ) -> Prediction:
        stdout, stderr = _decode(out_b), _decode(err_b)
        keep = {"stdout": tail(stdout), "stderr": tail(stderr), "latency_ms": latency}
        if timed_out:
            msg = f"timed out after {self.timeout_s:g} s (process group killed)"
            return Prediction(status="timeout", message=msg, **keep)
        if rc not in (0, EXIT_MARKERS_NOT_FOUND):
            last = stderr.strip().splitlines()[-1:] or [""]
            why = f"killed by signal {-rc}" if rc < 0 else f"exit status {rc}"
            return Prediction(
                status="crash", message=f"{why}: {last[0][:300]}".rstrip(": "), **keep
            )
        try:
            if self.output == "json":
                result: Any = _json_line(stdout)
                if rc == EXIT_MARKERS_NOT_FOUND and isinstance(result, dict):
                    result.setdefault("status", "markers_not_found")
                pred = prediction_from_result(result, latency_ms=latency, stdout=stdout)
                return Prediction(**{**pred.__dict__, "stderr": tail(stderr)})
            path = Path(workdir) / OBSTACLES_FILE
            if not path.is_file():
                if rc == EXIT_MARKERS_NOT_FOUND:
                    return Prediction(status="markers_not_found", message="exit status 3", **keep)
                return Prediction(
                    status="bad_output",
                    message=f"{OBSTACLES_FILE} was not written to the working directory",
                    **keep,
                )
            parsed = parse_obstacles_txt(path.read_text(encoding="utf-8", errors="replace"))
        except OutputFormatError as exc:
            if rc == EXIT_MARKERS_NOT_FOUND:
                return Prediction(status="markers_not_found", message=str(exc), **keep)
            return Prediction(status="bad_output", message=str(exc)[:500], **keep)
        return Prediction(
            status="markers_not_found" if rc == EXIT_MARKERS_NOT_FOUND else "ok",
            count=parsed.count,
            area=parsed.area,
            marker_ids=tuple(parsed.marker_ids),
            message="exit status 3: markers not found" if rc == EXIT_MARKERS_NOT_FOUND else "",
            **keep,
        )


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
        raise ValueError(
            f"pipeline must be one of {BUILTIN_PIPELINES} or 'pkg.module:function', got {spec!r}"
        )
    if hasattr(spec, "run") and hasattr(spec, "name"):
        return spec  # type: ignore[return-value]
    if callable(spec):
        return CallablePipeline(spec)
    raise ValueError(f"pipeline must be a name, a callable or a pipeline object, got {spec!r}")


def quote_command(argv: list[str]) -> str:
    """Shell-quoted rendering of an argument list (for messages only)."""
    return shlex.join(argv)
