"""``arenabench grade``'s preflight: prove the grading setup works before any team runs.

Four checks, each ending the grade before any team is graded (``PreflightError``: one line,
exit 2) when it fails:

1. **Sandbox** (:func:`require_sandbox`): ``grade`` fails closed. Without a working bubblewrap
   it refuses to run untrusted code unless ``--sandbox none`` is given explicitly.
2. **Process limit** (:func:`process_limit`): the same for ``--max-procs``. As root the
   kernel does not enforce ``RLIMIT_NPROC``, so without a pids cgroup (a read-only cgroup
   file system, no pids controller) the limit would be silently absent: refused unless
   ``--max-procs 0`` (no process limit) is given explicitly.
3. **Set** (:func:`check_dataset_seed`): a generated set whose seed is below 2**64 can be
   re-rendered by a submission that brings (or imports) the open-source generator, which then
   reads its own answers. Fail closed: unless ``allow_guessable`` (``--allow-guessable-seed``),
   only a set whose ``dataset.json`` and every GT file record an integer seed of at least
   2**64 is graded.
4. **Command** (:func:`preflight`): the grading command runs, in the same sandbox with the
   same limits and environment as every team, (a) a probe script in the place of the team's
   script that reports the interpreter, numpy, OpenCV (with ``aruco``) and whether arenabench
   itself is importable there, and (b) a known-good submission on the set's first image: the
   built-in reference (arenabench's own detector as a competition script, with its source
   alongside, so it needs only numpy and OpenCV) or ``--reference DIR``. It must answer
   (status ``ok``).

What the preflight saw (:class:`PreflightRecord`) goes into ``leaderboard.json["sandbox"]``
and every team's ``report.json``.
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from arenabench.eval.grade.teams import team_command
from arenabench.eval.runs import owned_dir_prefix
from arenabench.seeds import GUESSABLE_BELOW, is_guessable, seed_problem

if TYPE_CHECKING:
    from arenabench.eval.datasets.reader import Dataset

#: The line by which the probe reports what it found (followed by one JSON object).
PROBE_TAG = "ARENABENCH-PREFLIGHT "

PROBE = r'''"""arenabench grade preflight: what this interpreter offers competition scripts."""
import importlib.util
import sys
from json import dumps  # this runs in the sandbox, without arenabench's JSON helpers

info = {"python": sys.version.split()[0], "executable": sys.executable}
missing = []
try:
    import numpy
    info["numpy"] = numpy.__version__
except Exception as exc:
    missing.append(f"numpy ({type(exc).__name__}: {exc})")
try:
    import cv2
    info["cv2"] = cv2.__version__
    info["aruco"] = hasattr(cv2, "aruco") and hasattr(cv2.aruco, "ArucoDetector")
    if not info["aruco"]:
        missing.append(f"cv2.aruco.ArucoDetector (OpenCV {cv2.__version__} lacks it)")
except Exception as exc:
    missing.append(f"cv2 ({type(exc).__name__}: {exc})")
try:
    info["arenabench_importable"] = importlib.util.find_spec("arenabench") is not None
except Exception:
    info["arenabench_importable"] = False
print("ARENABENCH-PREFLIGHT " + dumps(info), flush=True)
if missing:
    print("missing: " + "; ".join(missing), file=sys.stderr)
    sys.exit(1)
'''

REFERENCE = r'''"""arenabench's reference detector as a competition submission (preflight)."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from arenabench.detect import main  # noqa: E402  (the copy next to this file)

# the image: after --image, else the first argument naming a file (other arguments of the
# grading command are the teams' business)
args = sys.argv[1:]
image = next((b for a, b in zip(args, args[1:]) if a == "--image"), None)
image = image or next((a for a in args if os.path.isfile(a)), "")
sys.exit(main(["--image", image] + EXTRA))
'''


class PreflightError(ValueError):
    """The grading setup does not work (the message is one line naming the cause)."""


@dataclass(frozen=True)
class PreflightRecord:
    """What the preflight saw inside the sandbox.

    Parameters
    ----------
    mode : str
        The sandbox the teams run in (``bwrap`` or ``none``).
    limits : dict
        The run settings (:meth:`RunSettings.to_dict`).
    executable, kind : str or None
        The command's executable and its kind (``venv``, ``conda``, ``pyenv``, ``system``).
    versions : dict
        ``python``, ``numpy``, ``cv2`` (and ``aruco``) as seen inside the sandbox; empty
        when the command is not a Python script (nothing to probe).
    arenabench_importable : bool or None
        Whether ``import arenabench`` finds it inside the sandbox.
    reference : dict
        The known-good submission's run: ``source``, ``image``, ``status``, ``count``,
        ``area`` (no timing: a re-run that grades nothing writes the same leaderboard).
    process_limit : str or None
        How ``--max-procs`` is enforced (:func:`process_limit`): ``"pids cgroup"``,
        ``"RLIMIT_NPROC"`` or ``"none (--max-procs 0: no process limit)"``.
    """

    mode: str
    limits: dict[str, Any]
    executable: str | None = None
    kind: str | None = None
    versions: dict[str, Any] = field(default_factory=dict)
    arenabench_importable: bool | None = None
    reference: dict[str, Any] = field(default_factory=dict)
    process_limit: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return asdict(self)


def require_sandbox(mode: str) -> str:
    """The sandbox ``grade`` runs teams in: fail closed.

    Returns ``"bwrap"`` when bubblewrap works, ``"none"`` only when asked for explicitly.

    Raises
    ------
    PreflightError
        For ``auto`` or ``bwrap`` without a working bubblewrap (one line: how to install it
        or opt out).
    """
    from arenabench.eval.runs import bwrap_problem

    if mode == "none":
        return "none"
    problem = bwrap_problem()
    if problem is None:
        return "bwrap"
    raise PreflightError(
        f"--sandbox {mode}: {problem}; grade runs untrusted code only in a sandbox: install "
        "bubblewrap (apt-get install bubblewrap) or pass --sandbox none to grade WITHOUT one")


#: :attr:`PreflightRecord.process_limit` of ``--max-procs 0``.
NO_PROCESS_LIMIT = "none (--max-procs 0: no process limit)"


def process_limit(max_procs: int) -> str:
    """How the teams' runs are held to ``max_procs`` processes: fail closed.

    Returns ``"pids cgroup"`` (a pids cgroup per run can be made here), ``"RLIMIT_NPROC"``
    (not root: the kernel enforces it) or :data:`NO_PROCESS_LIMIT` for ``max_procs`` 0.

    Raises
    ------
    PreflightError
        As root where no pids cgroup can be made (one line: why, and ``--max-procs 0``).
    """
    from arenabench.eval.runs import pids_cgroup_parent

    if max_procs == 0:
        return NO_PROCESS_LIMIT
    if pids_cgroup_parent() is not None:
        return "pids cgroup"
    if os.getuid() != 0:
        return "RLIMIT_NPROC"
    raise PreflightError(
        f"--max-procs {max_procs}: cannot be enforced here: no pids cgroup can be created "
        "(the cgroup file system is read-only or has no pids controller) and RLIMIT_NPROC "
        "does not bind root; make /sys/fs/cgroup writable (pids controller) or grade as "
        "another user, or pass --max-procs 0 to grade with NO process limit")


#: The end of every refusal of :func:`check_dataset_seed`.
_SEED_HINT = ("grade takes only a set whose every recorded seed is an integer of at least "
              f"2**{GUESSABLE_BELOW.bit_length() - 1} (a submission may re-render any other "
              "set and read its answers): generate the hidden set with 'arenabench generate "
              "--seed random', or pass --allow-guessable-seed")


def _meta_seed(doc: Any) -> tuple[Any, str | None]:
    """The seed ``dataset.json`` records (top level and ``args``), and why it proves
    nothing (``None``: it proves the set unguessable)."""
    if not isinstance(doc, dict):
        return None, "not a JSON object"
    recorded = [doc[k] for k in ("seed",) if k in doc]
    if isinstance(doc.get("args"), dict) and "seed" in doc["args"]:
        recorded.append(doc["args"]["seed"])
    for seed in recorded or [None]:
        if (problem := seed_problem(seed)) is not None:
            return seed, problem
    return recorded[0], None


def _gt_seeds(data: Dataset) -> tuple[Path, Any] | None:
    """The GT file (as named for the user) and seed of an image whose GT's seed does not
    prove the set unguessable (the weakest one), or ``None``."""
    from arenabench.eval.datasets.reader import DatasetSamples

    samples = data.samples
    if data.facts is not None:
        if data.facts.weakest_seed is None or not is_guessable(data.facts.weakest_seed[1]):
            return None
        index, seed = data.facts.weakest_seed
    else:  # a Dataset made by hand: look at every GT
        found = next(((i, s.gt.seed) for i, s in enumerate(samples)
                      if is_guessable(s.gt.seed)), None)
        if found is None:
            return None
        index, seed = found
    if isinstance(samples, DatasetSamples):
        return samples.gt_file(index), seed
    return samples[index].gt_path, seed


def check_dataset_seed(data: Dataset, *, allow_guessable: bool) -> int | None:
    """Refuse a set whose seed is not proven unguessable: fail closed.

    Every place that records the seed must hold an integer of at least 2**64
    (:func:`arenabench.seeds.seed_problem`): ``dataset.json`` (its ``seed`` and
    ``args.seed``; a missing, unreadable or garbled file proves nothing) and every GT file's
    ``seed`` (gathered by :func:`~arenabench.eval.datasets.reader.load_dataset` while it
    validates them).

    Returns
    -------
    int or None
        The set's seed, when proven (``None`` when ``allow_guessable`` let an unproven one
        through).

    Raises
    ------
    PreflightError
        One line naming the file and the seed found there (or why it could not be read),
        unless ``allow_guessable``.
    """
    from arenabench.eval.datasets.reader import read_dataset_meta

    meta = data.meta if data.meta is not None else read_dataset_meta(data.root)
    where: Path = meta.path
    seed, problem = (None, meta.problem) if meta.problem else _meta_seed(meta.doc)
    if problem is None and (weak := _gt_seeds(data)) is not None:
        where, problem = weak[0], seed_problem(weak[1])
    if problem is None:
        return seed
    if allow_guessable:
        return None
    raise PreflightError(f"{where}: {problem}: {_SEED_HINT}")


def _script_args(template: str) -> list[str]:
    """The ``{submission}/...`` parts of the template's arguments (the team's files)."""
    out = []
    for arg in shlex.split(template):
        if arg.startswith("{submission}/"):
            out.append(arg[len("{submission}/"):])
    return out


def _write_as(folder: Path, template: str, text: str) -> bool:
    """Write ``text`` as every ``.py`` file the template names in the submission; whether
    there was one."""
    wrote = False
    for rel in _script_args(template):
        if rel.endswith(".py") and ".." not in Path(rel).parts:
            path = folder / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            wrote = True
    return wrote


def builtin_reference(folder: Path, template: str, *, output: str) -> bool:
    """Lay out the built-in reference submission in ``folder``: arenabench's detector (its
    source copied alongside: nothing of this installation needed) as every ``.py`` file the
    template names. Returns whether the template names one (else nothing to lay out)."""
    import arenabench

    src = Path(arenabench.__file__).parent
    extra = ["--json"] if output == "json" else []
    if not _write_as(folder, template, REFERENCE.replace("EXTRA", repr(extra))):
        return False
    shutil.copytree(src, folder / "arenabench",
                    ignore=shutil.ignore_patterns("__pycache__", "generator", "eval", "*.pyc"))
    return True


def relative_interpreter_problem(template: str, option: str = "--cmd") -> str | None:
    """Why a relative interpreter in a grading command cannot be checked here, as one line
    (``None``: the interpreter is absolute, a placeholder or looked up on ``PATH``).

    Relative paths in the command resolve from each team's folder, so ``venv/bin/python`` is
    each team's own interpreter; the preflight's known-good submission has none there."""
    try:
        exe = shlex.split(template)[0]
    except (ValueError, IndexError):
        return None  # the run machinery names that problem
    if "/" not in exe or os.path.isabs(exe) or "{" in exe:
        return None
    return (f"{option}: executable {exe!r} is a relative path, and relative paths resolve from "
            f"each team's folder (SUBMISSIONS/TEAM/{exe}), so the preflight's known-good "
            "submission has no interpreter there to check: name the interpreter by its "
            "absolute path")


def probe_interpreter(
    template: str,
    *,
    image: str | os.PathLike[str],
    make_pipeline: Callable[..., Any],
    mode: str,
    record: PreflightRecord,
    option: str = "--cmd",
    command_name: str = "the grading command",
) -> PreflightRecord:
    """Run the probe script in the place of the command's script, plainly (no warm server,
    so a broken interpreter is named by its own error), with the command's settings.

    Parameters
    ----------
    template : str
        The command, its script named ``{submission}/NAME.py``.
    image : path-like
        Any file: the run's copy of the image (the probe does not read it).
    make_pipeline : callable
        ``(command, submission_dir, *, warm=True) -> CommandPipeline``.
    mode : str
        The sandbox mode (for messages).
    record : PreflightRecord
        What is known so far; the probe adds ``executable``, ``kind``, ``versions`` and
        ``arenabench_importable``.
    option : str
        The option that names the interpreter (for messages).
    command_name : str
        What the command is called in messages.

    Returns
    -------
    PreflightRecord
        Unchanged when the template names no Python script (nothing to probe).

    Raises
    ------
    PreflightError
        One line naming the cause: the interpreter cannot run or lacks numpy, OpenCV or aruco.
    """
    from arenabench.eval.runs import interpreter_folders

    with tempfile.TemporaryDirectory(prefix=owned_dir_prefix("arenabench-preflight-")) as tmp:
        probe_dir = Path(tmp, "probe")
        probe_dir.mkdir()
        if not _write_as(probe_dir, template, PROBE):
            return record
        try:
            pipe = make_pipeline(team_command(template, probe_dir), str(probe_dir), warm=False)
        except ValueError as exc:  # names the probe's folder: say where paths resolve from
            raise PreflightError(relative_interpreter_problem(template, option)
                                 or str(exc)) from None
        with pipe:  # its own run context: ended here
            record = replace(record, executable=pipe.command.executable)
            if record.executable:
                record = replace(record, kind=interpreter_folders(record.executable).kind)
            pred = pipe.run(Path(image))
    info = _probe_info(pred.stdout)
    if info is None or pred.status in ("crash", "timeout", "limit"):
        why = (pred.stderr.strip().splitlines() or [pred.message])[-1]
        if why.startswith("missing: "):
            raise PreflightError(
                f"preflight: {record.executable or template.split()[0]} in the "
                f"sandbox lacks {why[len('missing: '):]}: competition scripts need "
                "numpy and OpenCV with aruco (install them into that interpreter, or "
                f"name another with {option})")
        raise PreflightError(
            f"preflight: {command_name} cannot run a Python script in the "
            f"sandbox ({mode}): {pred.status}: {why[:300]}")
    return replace(
        record, versions={k: info.get(k) for k in ("python", "numpy", "cv2", "aruco")},
        arenabench_importable=bool(info.get("arenabench_importable")))


def preflight(
    template: str,
    *,
    image: str | os.PathLike[str],
    make_pipeline: Callable[..., Any],
    mode: str,
    limits: dict[str, Any],
    output: str = "obstacles",
    reference: str | os.PathLike[str] | None = None,
) -> PreflightRecord:
    """Run the probe and a known-good submission through the grading command.

    Parameters
    ----------
    template : str
        The grading command (``{submission}``, ``{image}``, ``{python}``).
    image : path-like
        The image the reference runs on (the set's first).
    make_pipeline : callable
        ``(command, submission_dir, *, warm=True) -> CommandPipeline`` exactly as a team's is
        made (``warm=False``: one interpreter per run, whatever the settings say).
    mode : str
        The sandbox mode (for the record).
    limits : dict
        The run settings (for the record).
    output : {"obstacles", "json"}
        How the command answers.
    reference : path-like, optional
        A known-good submission folder (default: the built-in reference).

    Raises
    ------
    PreflightError
        One line naming the cause: the interpreter cannot run, lacks a module, the sandbox
        fails, or the reference gives no answer.
    """
    if problem := relative_interpreter_problem(template):
        raise PreflightError(problem)
    record = probe_interpreter(template, image=image, make_pipeline=make_pipeline, mode=mode,
                               record=PreflightRecord(mode=mode, limits=dict(limits)))
    with tempfile.TemporaryDirectory(prefix=owned_dir_prefix("arenabench-preflight-")) as tmp:
        if reference is not None:
            ref_dir, source = Path(reference).resolve(), str(Path(reference).resolve())
        else:
            ref_dir, source = Path(tmp, "reference"), "built-in"
            ref_dir.mkdir()
            if not builtin_reference(ref_dir, template, output=output):
                return replace(record, reference={"source": "none (the command names no "
                                                  "Python script: pass --reference DIR)"})
        with make_pipeline(team_command(template, ref_dir), str(ref_dir)) as pipe:
            pred = pipe.run(Path(image))
        ref = {"source": source, "image": Path(image).name, "status": pred.status,
               "count": pred.count, "area": pred.area}
        if pred.status != "ok":
            why = (pred.stderr.strip().splitlines() or [pred.message])[-1]
            raise PreflightError(
                f"preflight: the {source} reference submission gets no answer through the "
                f"grading command in the sandbox ({mode}): {pred.status}: "
                f"{(pred.message or why)[:300]}")
        return replace(record, reference=ref)


def _probe_info(stdout: str) -> dict[str, Any] | None:
    for line in reversed((stdout or "").splitlines()):
        if line.startswith(PROBE_TAG):
            try:
                info = json.loads(line[len(PROBE_TAG):])
            except ValueError:
                return None
            return info if isinstance(info, dict) else None
    return None
