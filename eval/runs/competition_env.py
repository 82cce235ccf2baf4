"""The competition's Python environment: the interpreter competition scripts were written for.

Task 1C scripts were written for (and graded with) numpy 1.26 and OpenCV 4.10; many call
functions OpenCV 5 removed (``cv2.aruco.detectMarkers``). arenabench itself may run on newer
releases, so ``arenabench check`` (by default) and ``eval``/``sweep`` ``--cmd`` (where the
template names :data:`COMPETITION_PLACEHOLDER`) run scripts with an interpreter of their own: a
virtual environment holding exactly :data:`COMPETITION_PINS`, made once per base Python by this
module into the user cache and reused afterwards::

    competition_python(cache=None, progress=True, prog="arenabench check") -> Interpreter

How it is made
--------------
- In ``<cache>/envs/`` (:func:`arenabench.usercache.cache_dir`), in a folder named after
  the base interpreter and the pins (:func:`env_folder`): ``python -m venv`` of the running
  Python, then its own ``pip install --only-binary :all:`` of the pins from the package index
  (pip's own settings apply: ``PIP_INDEX_URL``, ``PIP_FIND_LINKS``, a ``pip.conf``), then a
  probe of the versions it imports; what was made is recorded in :data:`RECORD_FILE` in the
  environment's folder, beside its ``pyvenv.cfg``.
- Atomic: it is built in a temporary sibling folder and renamed into place only once the probe
  confirms the pinned versions; a folder without a valid record is never used (a killed build's
  temporary folder is removed by the next build).
- One build at a time: a blocking lock file ``<name>.lock`` beside it; a command that finds it
  held says so in one line and waits, then reuses what the other command made.
- Where it cannot be made (no package index, no wheel for this Python, no ``venv`` module,
  :data:`~arenabench.limits.COMPETITION_ENV_BUILD_TIMEOUT_S` exceeded) the result is arenabench's
  own interpreter (``source == "fallback"``) and one warning line naming why, the pinned versions
  and the versions that run instead.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from arenabench.cmdtemplate import (
    COMPETITION_PYTHON,
    TemplateError,
    escape,
    placeholders,
    replace_placeholder,
)
from arenabench.eval.runs.proctools import live_processes
from arenabench.interrupts import deferred_stops
from arenabench.limits import COMPETITION_ENV_BUILD_TIMEOUT_S
from arenabench.usercache import cache_dir


@dataclass(frozen=True)
class Pin:
    """One package of the competition's environment, at its exact version.

    Parameters
    ----------
    package : str
        Its name on the package index.
    version : str
        The exact release (``pip install package==version``).
    module : str
        The module it installs, whose ``__version__`` reports it.
    label : str
        Its name in messages.
    """

    package: str
    version: str
    module: str
    label: str

    @property
    def requirement(self) -> str:
        """``package==version``."""
        return f"{self.package}=={self.version}"

    def matches(self, module_version: str | None) -> bool:
        """Whether ``module.__version__`` is this release (OpenCV's ``4.10.0`` for the
        package's ``4.10.0.84``)."""
        return bool(module_version) and (module_version == self.version or
                                         self.version.startswith(f"{module_version}."))


#: The competition's numpy and OpenCV (e-Yantra 2024-25, Task 1C), declared here only.
COMPETITION_PINS: tuple[Pin, ...] = (
    Pin("numpy", "1.26.4", "numpy", "numpy"),
    Pin("opencv-contrib-python-headless", "4.10.0.84", "cv2", "OpenCV"),
)
#: Stands for the competition environment's interpreter in ``check --python`` and in the
#: ``--cmd`` templates of ``eval`` and ``sweep``.
COMPETITION_PLACEHOLDER = "{" + COMPETITION_PYTHON + "}"
#: Stands for the Python running arenabench (the same commands; resolved by the run machinery).
OWN_PYTHON_PLACEHOLDER = "{python}"
#: The record of what was made, in the environment's folder.
RECORD_FILE = "arenabench-env.json"
RECORD_SCHEMA = "arenabench.competition-env/1"

_PROBE = (
    "import sys\n"
    "from json import dumps\n"
    "info = {'python': sys.version.split()[0]}\n"
    "for name in ('numpy', 'cv2'):\n"
    "    try:\n"
    "        info[name] = __import__(name).__version__\n"
    "    except Exception as exc:\n"
    "        info[name + '_error'] = f'{type(exc).__name__}: {exc}'\n"
    "print(dumps(info))\n"
)
#: pip lines shown while the environment is made (the others are kept for the error message).
_SHOWN = re.compile(r"^\s*(Collecting|Processing|Downloading|Using cached|Installing collected|"
                    r"Successfully installed)")
_UNREACHABLE = re.compile(r"NewConnectionError|Connection refused|Failed to establish|"
                          r"Name or service not known|Temporary failure in name resolution|"
                          r"Network is unreachable|ConnectTimeout|timed out", re.I)
#: Variables that would make the new environment's interpreter or pip look elsewhere.
_DROPPED_ENV = ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "PYTHONUSERBASE", "VIRTUAL_ENV",
                "PIP_USER", "PIP_TARGET", "PIP_PREFIX", "PIP_ROOT", "PIP_PYTHON")


class BuildError(RuntimeError):
    """The environment could not be made (the message is one line saying why)."""


@dataclass(frozen=True)
class Interpreter:
    """The interpreter that runs competition scripts, and what it holds.

    Parameters
    ----------
    executable : str
        Absolute path of the interpreter (a virtual environment's ``bin/python`` is not
        resolved).
    source : str
        ``"competition"`` (the competition's environment), ``"fallback"`` (arenabench's own,
        since the competition's could not be made), ``"own"`` (arenabench's own, asked for
        with ``{python}``) or ``"given"`` (named by the user).
    versions : dict
        ``python``, ``numpy``, ``cv2`` as the interpreter imports them (empty: not probed).
    folder : str or None
        The competition environment's folder.
    made : bool
        Whether this command made the environment (else it was reused).
    problem : str or None
        Why the competition's environment is not used (``source == "fallback"``).
    """

    executable: str
    source: str
    versions: dict[str, str] = field(default_factory=dict)
    folder: str | None = None
    made: bool = False
    problem: str | None = None

    def describe_versions(self) -> str:
        """``Python 3.11.7, numpy 1.26.4, OpenCV 4.10.0`` (``?`` for what is unknown)."""
        return versions_text(self.versions)

    def describe_source(self) -> str:
        """What the interpreter is, in words."""
        if self.source == "competition":
            return f"the competition's environment, {self.folder}"
        if self.source == "fallback":
            return (f"arenabench's own {self.executable}: the competition's environment "
                    "could not be made")
        if self.source == "own":
            return f"arenabench's own {self.executable}"
        return self.executable

    def describe(self) -> str:
        """``Python 3.11.7, numpy 1.26.4, OpenCV 4.10.0 (the competition's environment, ...)``."""
        return f"{self.describe_versions()} ({self.describe_source()})"

    def with_versions(self, versions: dict[str, Any]) -> Interpreter:
        """A copy with ``versions`` (``python``, ``numpy``, ``cv2``) as probed."""
        keep = {k: str(versions[k]) for k in ("python", "numpy", "cv2") if versions.get(k)}
        return Interpreter(self.executable, self.source, keep, self.folder, self.made,
                           self.problem)

    def to_dict(self) -> dict[str, Any]:
        """JSON form (``report.json["interpreter"]``): the versions at the top level."""
        doc = asdict(self)
        versions = doc.pop("versions")
        doc.pop("made")
        return {**doc, **{k: versions.get(k) for k in ("python", "numpy", "cv2")}}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Interpreter:
        """Inverse of :meth:`to_dict` (``made`` is not kept: ``False``)."""
        return cls(executable=str(d.get("executable", "")), source=str(d.get("source", "")),
                   versions={k: str(d[k]) for k in ("python", "numpy", "cv2") if d.get(k)},
                   folder=d.get("folder"), problem=d.get("problem"))


def versions_text(versions: dict[str, Any]) -> str:
    """``Python X, numpy Y, OpenCV Z`` of a probe's ``python``, ``numpy``, ``cv2``."""
    return (f"Python {versions.get('python') or '?'}, numpy {versions.get('numpy') or '?'}, "
            f"OpenCV {versions.get('cv2') or '?'}")


def pins_text() -> str:
    """``numpy 1.26.4, OpenCV 4.10.0.84``."""
    return ", ".join(f"{p.label} {p.version}" for p in COMPETITION_PINS)


def own_versions() -> dict[str, str]:
    """The Python, numpy and OpenCV versions of the interpreter running arenabench."""
    out = {"python": platform.python_version()}
    for pin in COMPETITION_PINS:
        try:
            out[pin.module] = __import__(pin.module).__version__
        except Exception:  # reported as unknown
            continue
    return out


# ----------------------------------------------------------------------------- templates


def uses_competition_python(template: str) -> bool:
    """Whether a ``--cmd`` template names :data:`COMPETITION_PLACEHOLDER` (an escaped
    ``{{...}}`` does not)."""
    try:
        return any(COMPETITION_PYTHON in placeholders(a) for a in shlex.split(template))
    except (ValueError, TemplateError):  # the command's own check names the problem
        return False


def substitute_competition_python(template: str, executable: str) -> str:
    """``template`` with :data:`COMPETITION_PLACEHOLDER` replaced by ``executable`` (a path,
    literal text; or :data:`OWN_PYTHON_PLACEHOLDER`, which stays a placeholder), argument by
    argument (a path with spaces stays one argument; the other placeholders stay for the
    runs). A template that cannot be split is returned as it is (the run machinery names that
    problem)."""
    text = executable if executable == OWN_PYTHON_PLACEHOLDER else escape(executable)
    try:
        argv = shlex.split(template)
        return shlex.join(replace_placeholder(a, COMPETITION_PYTHON, text) for a in argv)
    except (ValueError, TemplateError):
        return template


def resolve_competition_python(templates: list[str], *, progress: bool,
                               prog: str) -> tuple[list[str], Interpreter | None]:
    """``templates`` with :data:`COMPETITION_PLACEHOLDER` replaced by the competition
    environment's interpreter (made first when it is missing; arenabench's own where it cannot
    be made), and that interpreter (``None``, and the templates unchanged, when none names
    it). One line on stderr names the interpreter and its versions."""
    if not any(uses_competition_python(t) for t in templates):
        return list(templates), None
    interp = competition_python(progress=progress, prog=prog)
    if interp.source == "competition":  # a fallback's warning line said it all
        print(f"{prog}: {COMPETITION_PLACEHOLDER} is {interp.executable} "
              f"({interp.describe_versions()}, the competition's environment)",
              file=sys.stderr, flush=True)
    return [substitute_competition_python(t, interp.executable) for t in templates], interp


# ----------------------------------------------------------------------------- the cache


def _base_executable() -> str:
    return os.path.realpath(getattr(sys, "_base_executable", None) or sys.executable)


def env_folder(cache: str | os.PathLike[str] | None = None) -> Path:
    """Where the competition environment of this base Python lives:
    ``<cache>/envs/competition-<cache tag>-<hash of the base interpreter and the pins>``."""
    if cache is None:
        cache = cache_dir()
    from arenabench.fileio import dumps_json

    key = dumps_json({"pins": [p.requirement for p in COMPETITION_PINS],
                      "base": _base_executable(), "python": platform.python_version(),
                      "machine": platform.machine()})
    digest = hashlib.sha256(key.encode()).hexdigest()[:10]
    return Path(cache) / "envs" / f"competition-{sys.implementation.cache_tag}-{digest}"


def read_record(folder: Path) -> dict[str, Any] | None:
    """The record of a finished environment in ``folder`` (``None``: not a usable one)."""
    try:
        record = json.loads((folder / RECORD_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if (not isinstance(record, dict) or record.get("schema") != RECORD_SCHEMA
            or record.get("requirements") != [p.requirement for p in COMPETITION_PINS]):
        return None
    if not os.path.exists(folder / "bin" / "python"):  # its base Python was removed
        return None
    return record


@contextlib.contextmanager
def _build_lock(path: Path, *, waiting: Callable[[str], None]) -> Iterator[None]:
    """Hold the exclusive lock ``path`` (created; never removed, so every command locks the
    same file), waiting for another holder; ``waiting(holder)`` is called once before a wait."""
    import fcntl

    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            waiting(" ".join(os.pread(fd, 4096, 0).decode("utf-8", "replace").split()))
            fcntl.flock(fd, fcntl.LOCK_EX)  # a stop signal ends the wait (Interrupted)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}: {shlex.join(sys.argv)[:300]}\n".encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock


def competition_python(
    *, cache: str | os.PathLike[str] | None = None, progress: bool = True,
    prog: str = "arenabench",
) -> Interpreter:
    """The competition environment's interpreter, made first when it is missing.

    Parameters
    ----------
    cache : path-like, optional, keyword-only
        The cache folder (default: :func:`arenabench.usercache.cache_dir`).
    progress : bool, keyword-only
        Show pip's steps while it is made (a first and a last line are always shown).
    prog : str, keyword-only
        The command, at the start of every line printed.

    Returns
    -------
    Interpreter
        ``source`` ``"competition"``, or ``"fallback"`` (arenabench's own interpreter, with
        one warning line printed) where the environment cannot be made.
    """
    folder = env_folder(cache)
    if read_record(folder) is not None:  # made before (renamed into place only when whole)
        return _competition(folder, made=False)
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        with _build_lock(folder.with_name(folder.name + ".lock"),
                         waiting=lambda who: print(
                             f"{prog}: waiting for another command making the competition's "
                             f"environment in {folder} ({who or 'holder unknown'})",
                             file=sys.stderr, flush=True)):
            if read_record(folder) is not None:  # the holder we waited for made it
                return _competition(folder, made=False)
            _build(folder, progress=progress, prog=prog)
        return _competition(folder, made=True)
    except (BuildError, OSError) as exc:
        why = str(exc) if isinstance(exc, BuildError) else f"{type(exc).__name__}: {exc}"
        own = Interpreter(sys.executable, "fallback", own_versions(), str(folder), False, why)
        print(f"{prog}: warning: the competition's environment ({pins_text()}) cannot be made "
              f"in {folder}: {why}; scripts run under arenabench's own "
              f"{own.describe_versions()} instead", file=sys.stderr, flush=True)
        return own


def _competition(folder: Path, *, made: bool) -> Interpreter:
    record = read_record(folder) or {}
    return Interpreter(str(folder / "bin" / "python"), "competition",
                       dict(record.get("versions") or {}), str(folder), made)


def _build(folder: Path, *, progress: bool, prog: str) -> None:
    """Make the environment in a temporary sibling of ``folder`` and rename it into place
    (the caller holds the build lock)."""
    envs = folder.parent
    prefix = f".{folder.name}.tmp-"
    for stale in envs.glob(prefix + "*"):  # a killed build's (we hold the lock)
        shutil.rmtree(stale, ignore_errors=True)
    if folder.exists():  # no valid record: never used; made again
        shutil.rmtree(folder)
    start = time.monotonic()
    print(f"{prog}: making the competition's Python environment ({pins_text()}) from the "
          f"package index into {folder}: once, about a minute", file=sys.stderr, flush=True)
    tmp: Path | None = None
    try:
        with deferred_stops():  # a stop lands before the folder is made or after it is named
            tmp = Path(tempfile.mkdtemp(dir=envs, prefix=prefix))
        python = tmp / "bin" / "python"
        _run([sys.executable, "-m", "venv", str(tmp)], what="python -m venv",
             show=None)
        show = (lambda line: print(f"  pip: {line.strip()}", file=sys.stderr, flush=True)
                ) if progress else None
        _run([str(python), "-m", "pip", "install", "--no-input", "--disable-pip-version-check",
              "--progress-bar", "off", "--only-binary", ":all:",
              *(p.requirement for p in COMPETITION_PINS)], what="pip install", show=show)
        versions = _probe(python)
        record = {
            "schema": RECORD_SCHEMA,
            "requirements": [p.requirement for p in COMPETITION_PINS],
            "versions": versions,
            "base_executable": _base_executable(),
            "made": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "seconds": round(time.monotonic() - start, 1),
        }
        from arenabench.fileio import atomic_write_json

        atomic_write_json(tmp / RECORD_FILE, record)
        os.chmod(tmp, 0o755)  # as python -m venv makes it (mkdtemp's is private)
        os.rename(tmp, folder)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    print(f"{prog}: made it in {time.monotonic() - start:.0f} s ({versions_text(versions)}; "
          f"recorded in {folder / RECORD_FILE})", file=sys.stderr, flush=True)


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in _DROPPED_ENV}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


def _run(argv: list[str], *, what: str, show: Callable[[str], None] | None) -> None:
    """Run a build step; its output is read line by line (``show`` gets pip's step lines).

    Raises
    ------
    BuildError
        One line: the step, and the last error line of its output.
    """
    # a session (and process group) of its own: ``python -m venv`` runs ensurepip, pip runs
    # children of its own, and a stopped build must end them all before its folder is removed
    timed_out = threading.Event()
    proc: subprocess.Popen[str] | None = None
    killer: threading.Timer | None = None
    lines: list[str] = []
    try:
        with deferred_stops():  # a stop lands before the step starts or once it is named
            proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, env=_clean_env(), text=True,
                                    errors="replace", start_new_session=True)
            killer = threading.Timer(COMPETITION_ENV_BUILD_TIMEOUT_S,
                                     lambda: (timed_out.set(), _kill_group(proc.pid)))
            killer.start()
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip())
            del lines[:-200]
            if show is not None and _SHOWN.match(line):
                show(line)
        rc = proc.wait()
    finally:
        if killer is not None:
            killer.cancel()
        if proc is not None:
            if proc.poll() is None:  # interrupted: end the step, and what it started, with us
                _kill_group(proc.pid)
                proc.wait()
            if proc.returncode != 0:  # stopped, timed out or failed: nothing of it left
                _wait_group_gone(proc.pid)
            if proc.stdout is not None:
                proc.stdout.close()
    if rc == 0:
        return
    if timed_out.is_set():
        raise BuildError(f"{what} took longer than {COMPETITION_ENV_BUILD_TIMEOUT_S:.0f} s")
    errors = [x.strip() for x in lines if x.strip().startswith("ERROR:")]
    last = (errors or [x.strip() for x in lines if x.strip()] or [f"exit status {rc}"])[-1]
    if any(_UNREACHABLE.search(x) for x in lines):
        why = f"the package index cannot be reached (offline?): {last}"
    elif "No matching distribution" in last or "Could not find a version" in last:
        why = (f"{last} (offline, or no wheel for Python {platform.python_version()} on "
               f"{platform.machine()})")
    else:
        why = last
    raise BuildError(f"{what}: {why[:400]}")


def _kill_group(pgid: int) -> None:
    with contextlib.suppress(OSError):
        os.killpg(pgid, signal.SIGKILL)


def _wait_group_gone(pgid: int, *, deadline_s: float = 10.0) -> None:
    """Wait until no live process is left in process group ``pgid`` (each is sent SIGKILL
    again), so nothing writes into a folder about to be removed; at most ``deadline_s``."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end and _live_in_group(pgid):
        _kill_group(pgid)
        time.sleep(0.01)


def _live_in_group(pgid: int) -> bool:
    return any(int(fields[2]) == pgid for _, fields in live_processes())


def _probe(python: Path) -> dict[str, str]:
    """The versions the new environment imports; they must be the pinned ones.

    Raises
    ------
    BuildError
        When it imports another version, or nothing.
    """
    try:
        proc = subprocess.run([str(python), "-I", "-c", _PROBE], capture_output=True, text=True,
                              env=_clean_env(), timeout=300)
        info = json.loads(proc.stdout.strip().splitlines()[-1])
    except (OSError, subprocess.SubprocessError, ValueError, IndexError) as exc:
        raise BuildError(f"the new environment does not run: {type(exc).__name__}: "
                         f"{exc}"[:400]) from None
    for pin in COMPETITION_PINS:
        if not pin.matches(info.get(pin.module)):
            got = info.get(pin.module) or info.get(f"{pin.module}_error")
            raise BuildError(f"the new environment imports {pin.module} {got}, not "
                             f"{pin.version}")
    return {k: str(info[k]) for k in ("python", "numpy", "cv2")}
