"""Grade many teams' submissions on one dataset: run, score, report, rank; resumable.

Every (team, image) pair is one unit: the team's command run once on one image, exactly as
``arenabench eval --cmd`` runs it. Units go to a local thread pool (the work happens in
subprocesses) or to a Dask cluster (:func:`arenabench.cluster.cluster_map`); a team's
reports are written as soon as its last unit is back, followed by a small state file. A
later run skips a team whose state file says it was graded on the same dataset (SHA-256 of
``manifest.jsonl``), the same submission bytes (:func:`submission_hash`) and the same
grading options, so an interrupted grade resumes where it stopped and a finished one does
not run again; a team stopped half-way keeps its finished images' results
(:mod:`arenabench.eval.grade.partial`) and runs only the others. A team whose runs time out
``give_up_after`` times in a row is given up (:mod:`arenabench.eval.grade.give_up`). Out
folder layout::

    OUT/leaderboard.json  leaderboard.csv  leaderboard.html
    OUT/teams/TEAM/report.json  results.csv  report.md  report.html  junit.xml
    OUT/teams/TEAM/feedback.md  feedback.html  (for the team: no hidden image, no GT)
    OUT/teams/TEAM/grade-state.json          (written last, atomically)
    OUT/teams/TEAM/partial-results.jsonl     (while the team is not finished)

A submission's crash, hang, garbage or trickery only ever fails its own images; an error of
the grader itself on one team (say, a report that cannot be written) is reported and the
other teams go on.
"""

from __future__ import annotations

import json
import math
import os
import shlex
import sys
import threading
import time
from collections.abc import Callable, Generator, Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from arenabench import __version__
from arenabench.cliopts import GIVE_UP_AFTER_RULE, formats_problem
from arenabench.cmdtemplate import (
    GRADE_PLACEHOLDERS,
    GRADE_REFUSED,
    template_problem,
)
from arenabench.eval.datasets.reader import AREA_REFERENCES, Dataset, DatasetSamples, load_dataset
from arenabench.eval.runs import OUTPUT_MODES, CommandPipeline, RunContext, RunSettings
from arenabench.eval.scoring.metrics import DEFAULT_TOLERANCE
from arenabench.eval.scoring.results import HarnessError, Prediction, Summary
from arenabench.fileio import (
    OutputPathError,
    atomic_write_json,
    check_report_dir,
    dumps_json,
    sha256_bytes,
    sha256_file,
)
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE
from arenabench.interrupts import (
    as_done,
    checkpoint,
    deferred_stops,
    result_of,
    worker_task,
)
from arenabench.limits import DEFAULT_GIVE_UP_AFTER
from arenabench.local_pool import end_executor, local_executor
from arenabench.workers import init_worker, process_state, usable_cores

from ..evaluation import build_report
from ..reports import FORMATS, write_reports
from ..reports.feedback_report import FEEDBACK_FILES, write_feedback
from ..scoring.metrics import score_sample
from .give_up import GiveUp, first_timeout_run, settle, timeout_run
from .leaderboard import LeaderboardRow, leaderboard_dict, rank_rows
from .leaderboard_report import LEADERBOARD_FILES, write_leaderboard
from .partial import PARTIAL_FILE, PartialLog, read_partial
from .seal import SEAL, intact, sealed
from .submissions import SubmissionsError, Team, find_teams, submission_hash
from .teams import DEFAULT_COMMAND, TEAM_ENV, team_command

STATE_FILE = "grade-state.json"
STATE_SCHEMA = "arenabench.grade-state/1"
TEAMS_DIR = "teams"


@dataclass(frozen=True)
class GradeOptions:
    """How every team is run and scored; a change means every team is graded again.

    Parameters
    ----------
    command : str
        Command template: ``{submission}`` (the team folder's absolute path), ``{image}``,
        ``{python}``; relative paths are resolved from the team folder.
    output : {"obstacles", "json"}
        How the command answers (as ``arenabench eval --output``).
    tolerance : float
        Largest passing ``|area_rel_err|``.
    area_reference : str
        GT area compared with (a key of ``AREA_REFERENCES``).
    settings : RunSettings
        Limits and sandbox of every run.
    formats : tuple of str
        Report files written per team (keys of ``FORMATS``); not part of the fingerprint,
        but a team whose files are missing is graded again.
    phases : int
        Phase check of each team's failing images (:mod:`arenabench.eval.phase_check`):
        sub-pixel phases re-rendered per failure, the team's command re-run on each; 0 = off.
    give_up_after : int
        Timeouts in a row, in image order, after which a team's later images are not run
        and are recorded as timeouts, skipped (:mod:`arenabench.eval.grade.give_up`); 0 =
        never.
    """

    command: str = DEFAULT_COMMAND
    output: str = "obstacles"
    tolerance: float = DEFAULT_TOLERANCE
    area_reference: str = DEFAULT_AREA_REFERENCE
    settings: RunSettings = field(default_factory=RunSettings)
    formats: tuple[str, ...] = tuple(FORMATS)
    phases: int = 0
    give_up_after: int = DEFAULT_GIVE_UP_AFTER

    def __post_init__(self) -> None:
        GIVE_UP_AFTER_RULE.check(self.give_up_after, name="give_up_after")
        if self.output not in OUTPUT_MODES:
            raise ValueError(f"output must be one of {OUTPUT_MODES}, got {self.output!r}")
        if not (math.isfinite(self.tolerance) and self.tolerance >= 0):
            raise ValueError(f"tolerance must be a finite number >= 0, got {self.tolerance!r}")
        if self.area_reference not in AREA_REFERENCES:
            raise ValueError(f"area_reference must be one of {sorted(AREA_REFERENCES)}, "
                             f"got {self.area_reference!r}")
        problem = formats_problem(self.formats, tuple(FORMATS))
        if problem:
            raise ValueError(f"formats: {problem}")
        try:
            argv = shlex.split(self.command)
        except ValueError as exc:
            raise ValueError(f"command cannot be split into arguments: {exc}") from None
        if not argv:
            raise ValueError(f"command must not be empty, got {self.command!r}")
        problem = template_problem(self.command, GRADE_PLACEHOLDERS, refused=GRADE_REFUSED)
        if problem:
            raise ValueError(f"command {self.command!r}: {problem}")

    def to_dict(self) -> dict[str, Any]:
        """What is fingerprinted and written into ``leaderboard.json["options"]``."""
        return {
            "command": self.command,
            "output": self.output,
            "tolerance": self.tolerance,
            "area_reference": self.area_reference,
            "run": self.settings.to_dict(),
            "arenabench": __version__,
            **({"phase_check": self.phases} if self.phases else {}),
            "give_up_after": self.give_up_after,
        }

    def fingerprint(self) -> str:
        """SHA-256 of :meth:`to_dict` in canonical JSON."""
        return sha256_bytes(dumps_json(self.to_dict()).encode())


@dataclass(frozen=True)
class GradeUnit:
    """One team's command on one image (what a worker runs)."""

    team: str
    submission: str
    image: str
    command: str
    output: str
    settings: RunSettings


@dataclass
class GradeResult:
    """What :func:`grade` did.

    Attributes
    ----------
    rows : list of LeaderboardRow
        Ranked, best first.
    graded, skipped : list of str
        Teams run now / found already graded.
    errors : dict
        Team -> why the grader could not finish it (such teams are not ranked).
    files : dict
        Leaderboard file name -> path.
    systemic : str or None
        One line when most teams fail alike (:func:`systemic_failure`): the grading setup,
        not the teams, is then the likely cause.
    """

    rows: list[LeaderboardRow]
    graded: list[str]
    skipped: list[str]
    errors: dict[str, str]
    files: dict[str, Path]
    systemic: str | None = None


def _team_pipeline(
    command: str, *, settings: RunSettings, output: str, team: str, base_dir: str,
    context: RunContext | None = None,
) -> CommandPipeline:
    """The team's :class:`CommandPipeline`: ``settings`` plus :data:`TEAM_ENV` (in
    ``context``, else in a context of its own that its ``close()`` ends)."""
    settings = replace(settings, env={**settings.env, **TEAM_ENV})
    return CommandPipeline(command, settings=settings, output=output, name=team,
                           base_dir=base_dir, context=context)


def _worker_context() -> RunContext:
    """The run context of a cluster worker's process: its warm servers serve the units it
    gets, for as long as it lives (they end with it)."""
    return process_state(("grade-run-context",), RunContext)


def run_unit(unit: GradeUnit, pipe: CommandPipeline | None = None) -> Prediction:
    """Run one team's command on one image; every failure of the team's command is a
    :class:`Prediction`.

    ``pipe`` is the team's pipeline when the caller made it (to be able to stop it).

    Raises
    ------
    HarnessError
        When the grader itself cannot run the image (its own error is never scored as the
        team's: the grade stops, and a rerun resumes).
    """
    try:
        if pipe is None:  # a cluster worker's unit
            pipe = _team_pipeline(unit.command, settings=unit.settings, output=unit.output,
                                  team=unit.team, base_dir=unit.submission,
                                  context=_worker_context())
        return pipe.run(Path(unit.image))
    except HarnessError:
        raise
    except Exception as exc:
        raise HarnessError(f"grader: {type(exc).__name__}: {exc}"[:500]) from exc


# ----------------------------------------------------------------------------- state


def _read_state(team_dir: Path) -> dict[str, Any] | None:
    try:
        state = json.loads((team_dir / STATE_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(state, dict) or state.get("schema") != STATE_SCHEMA:
        return None
    if not intact(state):  # edited by hand (or from another machine): graded again
        return None
    return {k: v for k, v in state.items() if k != SEAL}


def _state_valid(state: dict[str, Any] | None, expect: dict[str, str], team_dir: Path,
                 formats: Sequence[str]) -> bool:
    if state is None or any(state.get(k) != v for k, v in expect.items()):
        return False
    if not all((team_dir / FORMATS[f]).is_file() for f in formats):
        return False
    if not all((team_dir / name).is_file() for name in FEEDBACK_FILES.values()):
        return False
    try:
        Summary.from_dict(state["summary"])
    except (KeyError, TypeError, ValueError):
        return False
    return True


def _report_link(team: str, formats: Sequence[str]) -> str:
    name = FORMATS["html"] if "html" in formats else FORMATS[formats[0]]
    return f"{TEAMS_DIR}/{team}/{name}"


def _row(team: str, state: dict[str, Any]) -> LeaderboardRow:
    return LeaderboardRow(team=team, summary=Summary.from_dict(state["summary"]),
                          report=state["report"], submission_sha256=state["submission_sha256"])


# ----------------------------------------------------------------------------- execution


class _LocalRuns:
    """The units running in this process's threads, so that an interrupt (or giving up on a
    team) can stop them."""

    def __init__(self, context: RunContext) -> None:
        self._lock = threading.Lock()
        self._live: dict[int, CommandPipeline] = {}  # unit position -> its pipeline
        self._dropped: set[int] = set()
        self._stopped = False
        self.context = context

    def run(self, position: int, unit: GradeUnit) -> Prediction:
        with self._lock:
            if position in self._dropped:
                return _NOT_RUN
        try:
            pipe = _team_pipeline(unit.command, settings=unit.settings, output=unit.output,
                                  team=unit.team, base_dir=unit.submission,
                                  context=self.context)
        except Exception as exc:  # the grader's failure, never the team's
            raise HarnessError(f"grader: {type(exc).__name__}: {exc}"[:500]) from exc
        with self._lock:
            if self._stopped:
                return Prediction(status="crash", message="interrupted")
            if position in self._dropped:
                return _NOT_RUN
            self._live[position] = pipe
        try:
            return run_unit(unit, pipe)
        finally:
            with self._lock:
                self._live.pop(position, None)

    def drop(self, positions: Iterable[int]) -> None:
        """These units are not wanted any more: not started, or stopped when running."""
        with self._lock:
            positions = set(positions) - self._dropped
            self._dropped |= positions
            live = [pipe for p, pipe in self._live.items() if p in positions]
        for pipe in live:
            pipe.stop()

    def stop(self) -> None:
        """Kill every running command; later units return at once."""
        with self._lock:
            self._stopped = True
            live = list(self._live.values())
        for pipe in live:
            pipe.stop()


#: What a unit dropped before it ran returns (never used: its image has its result already).
_NOT_RUN = Prediction(status="crash", message="not run")


class _Threads:
    """The units on local threads: their results as they come back (iterate), and at a stop
    the results already back but not handed over yet (:meth:`ready`)."""

    def __init__(self, units: list[GradeUnit], workers: int, runs: _LocalRuns) -> None:
        self._runs = runs
        # one thread more than runs at once: it prepares the next image while the runs go,
        # and starts it the moment a run's slot frees (run_slots)
        self._pool = ThreadPoolExecutor(max_workers=runs.context.threads(workers),
                                        thread_name_prefix="arenabench-grade")
        self._futures = {self._pool.submit(runs.run, i, u): i for i, u in enumerate(units)}
        self._handed: set[Future] = set()
        self._at_stop: list[tuple[int, Prediction]] | None = None
        self._gen = self._results()

    def _results(self) -> Generator[tuple[int, Prediction], None, None]:
        try:
            for fut in as_done(self._futures):
                checkpoint()
                self._handed.add(fut)
                yield self._futures[fut], fut.result()
        except BaseException:  # a stop (here or in the caller): what ended before it is kept
            self._at_stop = self.ready()
            raise
        finally:
            self._runs.stop()  # no-op after the last unit; on a stop, ends the running ones
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._runs.context.close()  # the warm servers end, the runs' folders go

    def __iter__(self) -> Iterator[tuple[int, Prediction]]:
        return self._gen

    def ready(self) -> list[tuple[int, Prediction]]:
        """Results back but not handed over yet (their runs finished before a stop)."""
        if self._at_stop is not None:
            return self._at_stop
        return [(i, fut.result()) for fut, i in self._futures.items()
                if fut.done() and fut not in self._handed and not fut.cancelled()
                and fut.exception() is None]

    def close(self) -> None:
        self._gen.close()


class _Execution:
    """The grade's units, on local threads or a Dask cluster: their results as they come back
    (iterate), and :meth:`drop` for units no longer wanted (a team given up)."""

    def __init__(self, units: list[GradeUnit], *, workers: int | None, client: Any) -> None:
        self._dropped: set[int] = set()
        self._runs: _LocalRuns | None = None
        self._threads: _Threads | None = None
        self._results: Iterator[tuple[int, Prediction]]
        if client is not None:
            from arenabench.cluster import cluster_map

            self._results = cluster_map(run_unit, units, client,
                                        drop=self._dropped.__contains__)
        else:
            n = min(workers or usable_cores(), max(1, len(units)))
            self._runs = _LocalRuns(RunContext(slots=n))
            self._threads = _Threads(units, n, self._runs)
            self._results = iter(self._threads)

    def __iter__(self) -> Iterator[tuple[int, Prediction]]:
        return self._results

    def ready(self) -> list[tuple[int, Prediction]]:
        """At a stop: the results back but not handed over yet (local threads; none from a
        cluster), before :meth:`close`."""
        if self._threads is None:
            return []
        return [(i, p) for i, p in self._threads.ready() if i not in self._dropped]

    def drop(self, positions: Iterable[int]) -> None:
        """Units not wanted any more: never started, stopped when running (local threads),
        cancelled when still pending (a cluster); their results are never used."""
        positions = list(positions)
        self._dropped.update(positions)
        if self._runs is not None:
            self._runs.drop(positions)

    def close(self) -> None:
        """Stop and cancel what is still running or pending."""
        if self._threads is not None:
            self._threads.close()
        else:
            self._results.close()  # type: ignore[attr-defined]


def _execute(units: list[GradeUnit], *, workers: int | None, scheduler: Any) -> _Execution:
    return _Execution(units, workers=workers, client=scheduler)


def check_out_dir(out: Path, submissions: Path,
                  dataset: str | os.PathLike[str] | None = None) -> None:
    """Refuse an output folder inside the submissions or the dataset, a system folder, or
    one holding something else than an earlier grade
    (:func:`arenabench.fileio.check_report_dir`).

    Raises
    ------
    ValueError
        Naming ``--out`` and the problem.
    """
    inputs: list[tuple[str, str | os.PathLike[str]]] = [("SUBMISSIONS", submissions)]
    if dataset is not None:
        inputs.append(("DATASET", dataset))
    try:
        check_report_dir(out, own=(TEAMS_DIR, *LEADERBOARD_FILES),
                         what="'arenabench grade' output (teams/)", inputs=inputs)
    except OutputPathError as exc:
        raise ValueError(f"--out {out}: {exc}") from None


def grade(
    dataset: str | os.PathLike[str] | Dataset,
    submissions: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    options: GradeOptions | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    report_workers: int | None = None,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
    allow_guessable_seed: bool = False,
    reference: str | os.PathLike[str] | None = None,
) -> GradeResult:
    """Grade every team folder in ``submissions`` on ``dataset`` and write the leaderboard.

    Before any team runs: the sandbox must work unless ``options.settings.sandbox`` is
    ``"none"`` (fail closed), a generated set's seed must not be guessable, and the preflight
    (:mod:`arenabench.eval.grade.preflight`) must pass.

    Parameters
    ----------
    dataset : path-like or Dataset
        The (hidden) dataset.
    submissions : path-like
        One folder per team; the folder's name is the team's.
    out : path-like
        Output folder (see the module docstring for its layout).
    options : GradeOptions, optional, keyword-only
        Command, scoring and run settings (default: the competition's command).
    workers : int, optional, keyword-only
        Commands run at once here (default: the machine's cores).
    scheduler : str or distributed.Client, optional, keyword-only
        ``tcp://HOST:PORT`` of a Dask cluster to run the units on instead; the dataset and
        the submissions must be at the same paths on every worker.
    report_workers : int, optional, keyword-only
        Processes here that write the teams' reports while the commands go on (default: the
        machine's cores when HTML reports are written, else 1: in this process).
    progress : bool, keyword-only
        Progress over units on stderr (:mod:`arenabench.progress`).
    log : callable, optional, keyword-only
        Receives one line per team (graded, skipped or failed).
    allow_guessable_seed : bool, keyword-only
        Grade a set whose seed is not proven unguessable: one that some file records as
        below 2**64 (a submission can re-render it), or as anything but an integer, or not
        at all (:func:`arenabench.eval.grade.preflight.check_dataset_seed`).
    reference : path-like, optional, keyword-only
        A known-good submission for the preflight (default: the built-in reference).

    Returns
    -------
    GradeResult

    Raises
    ------
    DatasetError, SubmissionsError, ValueError
        Before anything runs, for a bad dataset, submissions folder, output folder or option.
    PreflightError
        (a ``ValueError``) Before any team runs: no sandbox, a guessable seed, or a grading
        command that cannot run the reference submission.
    OSError
        When the scheduler cannot be reached (before anything is written).
    """
    opts = options or GradeOptions()
    for name, value in (("workers", workers), ("report_workers", report_workers)):
        if value is not None and (int(value) != value or value < 1):
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    from .preflight import check_dataset_seed, preflight, process_limit, require_sandbox

    data = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    check_dataset_seed(data, allow_guessable=allow_guessable_seed)
    teams = find_teams(submissions)
    root = Path(out).resolve()
    check_out_dir(root, Path(submissions), data.root)
    mode = require_sandbox(opts.settings.sandbox)
    procs = process_limit(opts.settings.limits.max_procs)
    opts = replace(opts, settings=replace(opts.settings, sandbox=mode))
    digests: dict[str, str] = {}
    refused: dict[str, str] = {}  # a submission that cannot be fingerprinted is not graded
    base = Path(submissions).resolve()
    for t in teams:
        if (problem := t.problem(base)) is not None:  # before anything of it is read
            refused[t.name] = problem
            continue
        try:
            digests[t.name] = submission_hash(t.path)
        except SubmissionsError as exc:
            refused[t.name] = str(exc)
    say = log or (lambda line: None)
    say(f"preflight: the grading command's sandbox and interpreter, and a known-good "
        f"submission, on {Path(data.samples[0].image_path).name} ({mode} sandbox)")
    started = time.monotonic()
    record = preflight(
        opts.command, image=data.samples[0].image_path, mode=mode,
        limits=opts.settings.to_dict(), output=opts.output, reference=reference,
        make_pipeline=lambda cmd, base, warm=True: _team_pipeline(
            cmd, settings=replace(opts.settings, warm=opts.settings.warm and warm),
            output=opts.output, team="preflight", base_dir=base))
    record = replace(record, process_limit=procs)
    say(f"preflight: done in {time.monotonic() - started:.1f} s")
    if record.arenabench_importable:
        print("arenabench grade: WARNING: arenabench is importable inside the sandbox (the "
              "grading interpreter has it): a submission can run the generator; the set's "
              "seed must stay unguessable (--seed random)", file=sys.stderr, flush=True)
    sandbox = record.to_dict()
    seen = {k: sandbox[k] for k in ("mode", "executable", "versions", "arenabench_importable")}
    expect_common = {
        "dataset_manifest_sha256": sha256_file(data.root / "manifest.jsonl"),
        "options_sha256": opts.fingerprint(),
        "sandbox_sha256": sha256_bytes(dumps_json(seen).encode()),
    }
    client = None
    if scheduler is not None:  # reach the cluster before writing anything
        from arenabench.cluster import connect

        client = connect(scheduler)
    try:
        return _grade(data, teams, root, opts, expect_common, workers=workers, client=client,
                      report_workers=report_workers, progress=progress,
                      emit=log or (lambda line: None), digests=digests, sandbox=sandbox,
                      refused=refused)
    finally:
        if client is not None and client is not scheduler:
            client.close()


@dataclass
class _TeamRun:
    """One team being graded: its images' results so far (run now, kept from an earlier run,
    or not run), and where they are kept meanwhile (``partial-results.jsonl``)."""

    team: Team
    digest: str
    preds: list[Prediction | None]
    log: PartialLog
    done: int = 0
    given_up: GiveUp | None = None
    submitted: bool = False


#: Teams named in the progress line (those with runs under way), at most.
PROGRESS_TEAMS = 3


def _progress_text(runs: Sequence[_TeamRun], n_images: int) -> str:
    """The teams with runs under way and how far each got: ``"alpha 20/200, beta 3/200"``."""
    active = [tr for tr in runs if not tr.submitted and 0 < tr.done < n_images]
    text = ", ".join(f"{tr.team.name} {tr.done}/{n_images}" for tr in active[:PROGRESS_TEAMS])
    more = len(active) - PROGRESS_TEAMS
    return text + (f", +{more} more" if more > 0 else "")


def _grade(data: Dataset, teams: Sequence[Team], root: Path, opts: GradeOptions,
           expect_common: dict[str, str], *, workers: int | None, client: Any,
           report_workers: int | None, progress: bool,
           emit: Callable[[str], None], digests: dict[str, str],
           sandbox: dict[str, Any], refused: dict[str, str]) -> GradeResult:
    (root / TEAMS_DIR).mkdir(parents=True, exist_ok=True)
    loop = _GradeLoop(data, teams, root, opts, expect_common, emit=emit, sandbox=sandbox,
                      refused=refused)
    loop.sort_teams(digests)
    loop.resume()
    return loop.run(workers=workers, client=client, report_workers=report_workers,
                    progress=progress)


class _GradeLoop:
    """One grade in steps: sort the teams (refused, already graded, to grade), take back what
    an interrupted grade kept, run every image left of every team, and finish each team (its
    scoring and reports in the finisher's processes) as its last image comes back."""

    def __init__(self, data: Dataset, teams: Sequence[Team], root: Path, opts: GradeOptions,
                 expect_common: dict[str, str], *, emit: Callable[[str], None],
                 sandbox: dict[str, Any], refused: dict[str, str]) -> None:
        self.data, self.teams, self.root, self.opts = data, teams, root, opts
        self.expect_common, self.emit, self.sandbox = expect_common, emit, sandbox
        self.refused = refused
        self.n_images = len(data.samples)
        self.ids = (data.samples.ids if isinstance(data.samples, DatasetSamples)  # no GT read
                    else [s.id for s in data.samples])
        self.states: dict[str, dict[str, Any]] = {}
        self.todo: list[tuple[Team, str]] = []
        self.skipped: list[str] = []
        self.runs: list[_TeamRun] = []
        self.graded: list[str] = []
        self.errors: dict[str, str] = dict(refused)
        self.bar: Any = None
        self.finisher: _Finisher | None = None
        self.finishing: dict[Future, _FinishJob] = {}

    def sort_teams(self, digests: dict[str, str]) -> None:
        """Refused teams said, teams graded by an earlier run skipped, the others to do."""
        for team in self.teams:
            if team.name in self.refused:
                self.emit(f"{team.shown}: error: {self.refused[team.name]}")
                continue
            digest = digests[team.name]
            team_dir = self.root / TEAMS_DIR / team.name
            state = _read_state(team_dir)
            expect = {**self.expect_common, "team": team.name, "submission_sha256": digest}
            if _state_valid(state, expect, team_dir, self.opts.formats):
                assert state is not None
                self.states[team.name] = state
                self.skipped.append(team.name)
                (team_dir / PARTIAL_FILE).unlink(missing_ok=True)  # graded: nothing to resume
                self.emit(f"{team.name}: skipped: already graded ({_passed(state)})")
            else:
                (team_dir / STATE_FILE).unlink(missing_ok=True)  # stale: never trusted again
                self.todo.append((team, digest))
        if self.todo:
            self.emit(f"grading {len(self.todo)} of {len(self.teams)} teams on "
                      f"{self.n_images} images")

    def resume(self) -> None:
        """Each team's results kept by an interrupted grade on the same dataset, submission,
        options and sandbox: those images do not run again."""
        n_images = self.n_images
        for team, digest in self.todo:
            path = self.root / TEAMS_DIR / team.name / PARTIAL_FILE
            header = {**self.expect_common, "team": team.name, "submission_sha256": digest}
            kept = read_partial(path, header, self.ids)
            preds: list[Prediction | None] = [None] * n_images
            for j, pred in (kept or {}).items():
                preds[j] = pred
            self.runs.append(_TeamRun(team=team, digest=digest, preds=preds,
                                      done=len(kept or {}),
                                      log=PartialLog(path, header, append=kept is not None)))
            if kept:
                self.emit(f"{team.name}: resuming: {len(kept)} of {n_images} images kept "
                          "from the last run")
        for tr in self.runs:  # the kept results may hold a run of timeouts already
            if (run := first_timeout_run(tr.preds, self.opts.give_up_after)) is not None:
                self.give_up(tr, run)

    def say(self, line: str) -> None:
        """A line of the grade's log (above the progress bar on a terminal)."""
        if hasattr(self.bar, "write"):  # a tqdm bar on a terminal: print above it
            self.bar.write(line, file=sys.stdout)
        else:
            self.emit(line)

    def give_up(self, tr: _TeamRun, run: tuple[int, int]) -> list[int]:
        """Run none of the team's images after ``run`` whose results are not back (they are
        skipped; :func:`settle` decides the verdicts when the team is done); their indices."""
        first, last = run
        ids, after = self.ids, self.opts.give_up_after
        later = [j for j in range(last + 1, self.n_images) if tr.preds[j] is None]
        tr.given_up = GiveUp(after=after, first=ids[first], last=ids[last],
                             timeouts=last - first + 1, skipped=len(later))
        skip = tr.given_up.prediction()
        for j in later:
            tr.preds[j] = skip
        tr.done += len(later)
        self.say(f"{tr.team.name}: giving up after {last - first + 1} consecutive timeouts "
                 f"({ids[first]} to {ids[last]}): {len(later)} later images not run "
                 f"(--give-up-after {after})")
        return later

    def _units(self) -> tuple[list[GradeUnit], list[tuple[int, int]], dict]:
        """The runs left: the units, each unit's (team, image index), and the reverse map."""
        units: list[GradeUnit] = []
        where: list[tuple[int, int]] = []  # unit position -> (team, image index)
        position: dict[tuple[int, int], int] = {}
        opts = self.opts
        image_paths = self.data.image_paths()
        for k, tr in enumerate(self.runs):
            command = team_command(opts.command, tr.team.path)
            for j, image in enumerate(image_paths):
                if tr.preds[j] is None:
                    position[(k, j)] = len(units)
                    where.append((k, j))
                    units.append(GradeUnit(team=tr.team.name, submission=str(tr.team.path),
                                           image=str(image), command=command,
                                           output=opts.output, settings=opts.settings))
        return units, where, position

    def collect(self, block: bool) -> None:
        """Take in the finished teams' states (all of them, waiting, with ``block``)."""
        finishing = self.finishing
        ready = list(finishing) if block else [f for f in finishing if f.done()]
        for fut in ready:
            job = finishing.pop(fut)
            name = job.team.name
            try:
                try:
                    self.states[name] = result_of(fut)
                except BrokenProcessPool:  # lost with a dead report process: once more here
                    self.states[name] = _finish_team(job, self.data)
            except Exception as exc:  # the grader's own failure on this team only
                self.errors[name] = f"{type(exc).__name__}: {exc}"
                self.say(f"{name}: error: {self.errors[name]}")
                continue
            self.graded.append(name)
            gave_up = self.states[name].get("given_up")
            note = f"; {GiveUp(**gave_up).text()}" if gave_up else ""
            self.say(f"{name}: graded ({_passed(self.states[name])}{note})")

    def finish(self, tr: _TeamRun) -> None:
        """Every image of ``tr`` is back: its scoring and reports go to the finisher."""
        tr.log.close()
        # the verdicts do not depend on how many images ran at once nor on the order their
        # results came back: every image after the first run of timeouts is skipped
        given_up = settle(tr.preds, self.opts.give_up_after, self.ids)
        job = _FinishJob(team=tr.team, digest=tr.digest,
                         preds=[p for p in tr.preds if p is not None],
                         dataset_root=str(self.data.root), root=str(self.root),
                         opts=self.opts, expect_common=self.expect_common,
                         sandbox=self.sandbox,
                         given_up=None if given_up is None else given_up.to_dict())
        tr.preds, tr.submitted = [], True  # the job holds them now
        assert self.finisher is not None
        self.finishing[self.finisher.submit(job, self.data)] = job

    def keep(self, where: tuple[int, int], pred: Prediction) -> _TeamRun | None:
        """Record the result of image ``where`` = (team, image index) (kept in the team's
        partial results); its team, or ``None`` when it is not used (the team was given up
        meanwhile)."""
        k, j = where
        tr = self.runs[k]
        if tr.submitted or tr.preds[j] is not None:  # dropped: the team was given up
            return None
        tr.preds[j] = pred
        tr.done += 1
        tr.log.add(j, self.ids[j], pred)
        self.bar.update(1)
        return tr

    def run(self, *, workers: int | None, client: Any, report_workers: int | None,
            progress: bool) -> GradeResult:
        """Run what is left, finish each team as it completes; the grade's result."""
        from arenabench.progress import progress as progress_bar

        units, where, position = self._units()
        self.bar = progress_bar(len(units), desc="grade", unit="run", enabled=progress)
        if report_workers is None:  # only the HTML report is worth other processes
            report_workers = usable_cores() if "html" in self.opts.formats else 1
        self.finisher = _Finisher(report_workers, n_teams=len(self.todo))
        execution = _execute(units, workers=workers, scheduler=client)
        finished = False
        try:
            self._loop(execution, where, position)
            finished = True
        except BaseException:  # interrupted: a partial leaderboard of the finished teams
            try:
                for i, pred in execution.ready():  # runs that ended before the stop: kept
                    self.keep(where[i], pred)
                self.collect(block=False)
                self._write_partial_leaderboard()
            except Exception:  # never hide the interrupt behind a report error
                pass
            raise
        finally:
            execution.close()  # stops and cancels what is still running or pending
            for tr in self.runs:
                tr.log.close()
            self.bar.close()
            self.finisher.close(wait=finished)
        return self._result()

    def _loop(self, execution: Any, where: list[tuple[int, int]],
              position: dict[tuple[int, int], int]) -> None:
        from arenabench.progress import drop

        after, n_images = self.opts.give_up_after, self.n_images
        for tr in self.runs:  # every image kept (or not run): nothing left to run
            if tr.done == n_images:
                self.finish(tr)
        for i, pred in execution:
            tr = self.keep(where[i], pred)
            if tr is None:
                continue
            k, j = where[i]
            run = timeout_run(tr.preds, j) if tr.given_up is None else None
            if after and run and run[1] - run[0] + 1 >= after:
                later = self.give_up(tr, run)
                execution.drop(position[(k, x)] for x in later)
                drop(self.bar, len(later))  # they will not run: out of the work and its ETA
            self.bar.set_postfix_str(_progress_text(self.runs, n_images), refresh=False)
            if tr.done == n_images:
                self.finish(tr)
            self.collect(block=False)
        self.collect(block=True)

    def _rows(self) -> list:
        return rank_rows(_row(t.name, self.states[t.name]) for t in self.teams
                         if t.name in self.states)

    def _write_partial_leaderboard(self) -> None:
        """After a stop: the leaderboard of the finished teams, and what each other did."""
        n_images, states = self.n_images, self.states
        unfinished = [{"team": tr.team.name, "images_done": tr.done, "images_total": n_images}
                      for tr in self.runs if tr.team.name not in states
                      and tr.team.name not in self.errors]
        done = len(self.skipped) * n_images + sum(
            n_images if tr.team.name in states else tr.done for tr in self.runs)
        write_leaderboard_files(
            self.root, self._rows(), data=self.data, opts=self.opts,
            manifest_sha256=self.expect_common["dataset_manifest_sha256"], images_done=done,
            images_total=len(self.teams) * n_images, sandbox=self.sandbox,
            unfinished=unfinished)
        for u in unfinished:
            if u["images_done"] == n_images:  # run, but not scored and reported yet
                self.say(f"{u['team']}: not finished: all {n_images} images run (kept), its "
                         "scoring, phase check and reports not done: the same command does "
                         "them")
            else:
                self.say(f"{u['team']}: not finished: {u['images_done']} of {n_images} "
                         "images done (kept: the same command resumes from there)")

    def _result(self) -> GradeResult:
        """Every team graded: the leaderboard files and the grade's result."""
        teams, states = self.teams, self.states
        rows = self._rows()
        done = sum(states[t.name]["summary"].get("n", 0) for t in teams if t.name in states)
        with deferred_stops():  # every team is graded: a stop now cuts no leaderboard file off
            files = write_leaderboard_files(
                self.root, rows, data=self.data, opts=self.opts,
                manifest_sha256=self.expect_common["dataset_manifest_sha256"],
                images_done=done, images_total=len(teams) * self.n_images,
                sandbox=self.sandbox)
        systemic = systemic_failure({t.name: states[t.name] for t in teams if t.name in states})
        return GradeResult(rows=rows, graded=self.graded, skipped=self.skipped,
                           errors=self.errors, files=files, systemic=systemic)


@dataclass(frozen=True)
class _FinishJob:
    """Everything needed to write one team's reports and state (picklable)."""

    team: Team
    digest: str
    preds: list[Prediction]
    dataset_root: str
    root: str
    opts: GradeOptions
    expect_common: dict[str, str]
    sandbox: dict[str, Any] = field(default_factory=dict)
    given_up: dict[str, Any] | None = None


def _finish_in_worker(job: _FinishJob) -> dict[str, Any]:
    # a SIGTERM (the grade stopped) unwinds the job: its phase check's runs are killed,
    # then the worker exits
    with worker_task():
        # the grade's images: the first n of the dataset, loaded once per worker process
        data = process_state(("grade-dataset", job.dataset_root, len(job.preds)),
                             lambda: load_dataset(job.dataset_root, limit=len(job.preds)))
        return _finish_team(job, data)


class _Finisher:
    """Writes teams' reports while the commands go on: in a pool of spawned processes (the
    HTML report's plots and thumbnails take seconds per team, more than a busy grader can
    spend in one thread), or inline for ``workers <= 1``."""

    def __init__(self, workers: int, *, n_teams: int) -> None:
        n = min(workers, n_teams)
        self._pool = None
        if n > 1:
            self._pool = local_executor(n, initializer=init_worker, initargs=(None, os.getpid()))

    def submit(self, job: _FinishJob, data: Dataset) -> Future:
        """Start writing ``job``'s reports (inline when there is no usable pool)."""
        if self._pool is not None:
            try:
                return self._pool.submit(_finish_in_worker, job)
            except BrokenProcessPool:  # a report process died: go on in this process
                self._pool = None
        fut: Future = Future()
        try:
            fut.set_result(_finish_team(job, data))
        except Exception as exc:
            fut.set_exception(exc)
        return fut

    def close(self, *, wait: bool) -> None:
        """``wait``: let the jobs under way finish; otherwise (a stop) cancel the queued jobs
        and end the pool's processes: SIGTERM unwinds a job (its phase check's runs are
        killed), SIGKILL after :data:`arenabench.interrupts.WORKER_GRACE_S`."""
        if self._pool is None:
            return
        if wait:
            self._pool.shutdown(wait=True)
            return
        end_executor(self._pool)


def _passed(state: dict[str, Any]) -> str:
    s = state["summary"]
    return f"{s.get('n_passed', 0)}/{s.get('n', 0)} passed"


def _finish_team(job: _FinishJob, data: Dataset) -> dict[str, Any]:
    """Score one team's predictions, write its reports, then its state file (last)."""
    team, opts = job.team, job.opts
    results = [
        score_sample(s, p, tolerance=opts.tolerance, area_reference=opts.area_reference)
        for s, p in zip(data.samples, job.preds, strict=True)
    ]
    if opts.phases and not all(r.passed for r in results):
        from arenabench.eval.phase_check import check_phases, dataset_scene_source

        pipe = _team_pipeline(team_command(opts.command, team.path), settings=opts.settings,
                              output=opts.output, team=team.name, base_dir=str(team.path))
        source = dataset_scene_source(data.root, None if data.meta is None else data.meta.doc)
        try:
            results = check_phases(results, [s.gt for s in data.samples[:len(results)]],
                                   pipe.run, phases=opts.phases, tolerance=opts.tolerance,
                                   area_reference=opts.area_reference, workers=2,
                                   source=source, stop=pipe.stop)
        finally:
            pipe.close()
    report = build_report(results, pipeline=team.name, dataset=str(data.root),
                          area_reference=opts.area_reference, tolerance=opts.tolerance,
                          manifest_sha256=job.expect_common["dataset_manifest_sha256"])
    team_dir = Path(job.root) / TEAMS_DIR / team.name
    write_reports(report, team_dir, formats=opts.formats, dataset=data)
    write_feedback(report, team_dir, team=team.name)  # what may be handed back to the team
    if "json" in opts.formats:  # what the preflight saw inside the sandbox, with the report
        path = team_dir / FORMATS["json"]
        doc = json.loads(path.read_text(encoding="utf-8"))
        doc["sandbox"] = job.sandbox
        doc["given_up"] = job.given_up  # images skipped after a run of timeouts (give_up)
        atomic_write_json(path, doc)
    state = {
        "schema": STATE_SCHEMA,
        "team": team.name,
        **job.expect_common,
        "submission_sha256": job.digest,
        "options": opts.to_dict(),
        "report": _report_link(team.name, opts.formats),
        "summary": report.summary.to_dict(),
        "first_error": first_error(job.preds, str(team.path)),
        "given_up": job.given_up,
    }
    atomic_write_json(team_dir / STATE_FILE, sealed(state))  # last: marks the team as graded
    (team_dir / PARTIAL_FILE).unlink(missing_ok=True)  # graded: nothing to resume
    return state


def write_leaderboard_files(root: Path, rows: list[LeaderboardRow], *, data: Dataset,
                            opts: GradeOptions, manifest_sha256: str,
                            images_done: int | None = None, images_total: int | None = None,
                            sandbox: dict[str, Any] | None = None,
                            unfinished: Sequence[dict[str, Any]] = ()) -> dict[str, Path]:
    """Write ``leaderboard.json``, ``.csv`` and ``.html`` into ``root`` (atomically);
    ``unfinished``: the teams an interrupted grade did not finish, with how far each got."""
    doc = leaderboard_dict(
        rows,
        dataset={"path": str(data.root), "manifest_sha256": manifest_sha256,
                 "n": len(data.samples)},
        options=opts.to_dict(), images_done=images_done, images_total=images_total,
        sandbox=sandbox, unfinished=unfinished,
    )
    return write_leaderboard(doc, root)


#: Statuses of a run that failed without an answer (what a broken setup gives).
_FAILED = ("crash", "timeout", "limit", "bad_output")
#: Share of teams (and least number) failing alike that makes a failure systemic.
SYSTEMIC_SHARE, SYSTEMIC_MIN_TEAMS = 0.8, 3


def first_error(preds: Sequence[Prediction], submission: str) -> str | None:
    """The first line of the first failed run's message (``None``: no run failed), with the
    submission's path written ``{submission}`` so that teams failing alike compare equal."""
    for p in preds:
        if p.status in _FAILED:
            line = ((p.message or "").strip().splitlines() or [""])[0]
            return f"{p.status}: {line.replace(submission, '{submission}')}"[:300]
    return None


def systemic_failure(states: dict[str, dict[str, Any]]) -> str | None:
    """One line when at least :data:`SYSTEMIC_SHARE` of the teams (and at least
    :data:`SYSTEMIC_MIN_TEAMS`) passed nothing and failed with the same first error line."""
    from collections import Counter

    errors = Counter(
        st.get("first_error") for st in states.values()
        if st.get("first_error") and st["summary"].get("n_passed", 0) == 0)
    if not errors:
        return None
    line, n = errors.most_common(1)[0]
    if n >= SYSTEMIC_MIN_TEAMS and n >= SYSTEMIC_SHARE * len(states):
        return (f"{n} of {len(states)} teams fail alike ({line}): the grading setup, not the "
                "teams, is the likely cause")
    return None


__all__ = [
    "DEFAULT_COMMAND",
    "GradeOptions",
    "GradeResult",
    "GradeUnit",
    "SubmissionsError",
    "grade",
    "run_unit",
    "team_command",
]
