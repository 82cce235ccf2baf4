"""``arenabench grade``: run every team's submission on a (hidden) dataset, write each team's
report and a ranked leaderboard; re-running skips teams already graded.

Exit status: 0 done; 1 the grader could not finish some team (the others are ranked);
2 usage error (bad dataset, submissions folder, output folder or option; no cluster) or a
failed preflight (no sandbox without --sandbox none, a guessable seed, a grading command that
cannot run the reference submission), before any team runs; 3 most teams failed alike (the
setup, not the teams: one line names the shared error; the leaderboard is written);
130 / 143 interrupted by SIGINT / SIGTERM (running commands are killed; teams already
finished stay graded: run the same command again to resume).
"""

from __future__ import annotations

import sys
from pathlib import Path

from arenabench.cliopts import (
    GIVE_UP_AFTER_RULE,
    WORKERS_RULE,
    CommandParser,
    add_area_reference,
    add_cmd,
    add_formats,
    add_no_progress,
    add_out,
    add_output_mode,
    add_run_options,
    add_scheduler,
    add_tolerance,
    add_workers,
    lock_out,
    output_problem,
    usage_error,
)
from arenabench.cmdtemplate import GRADE_PLACEHOLDERS, GRADE_REFUSED
from arenabench.eval.phase_check import add_phase_check_argument
from arenabench.eval.runs import OUTPUT_MODES
from arenabench.exitcodes import ExitCode

PROG = "arenabench grade"

EPILOG = """\
examples:
  arenabench grade hidden/ submissions/ --out results/
  arenabench grade hidden/ submissions/ --out results/ --timeout 30 --workers 8
  arenabench grade hidden/ submissions/ --out results/ --cmd "$HOME/teams-venv/bin/python \\
      {submission}/map.py --image {image}"
  arenabench grade hidden/ submissions/ --out results/ --cmd "python3 {submission}/run.py {image}"
  arenabench grade hidden/ submissions/ --out results/ --scheduler tcp://10.0.0.5:8786

SUBMISSIONS holds one folder per team; the folder's name is the team. Each team's command
(default: python3 {submission}/map.py --image {image}) runs once per image as for
'arenabench eval --cmd': {submission} is the team folder's absolute path, {image} the image,
{competition_python} the competition's environment (numpy and OpenCV at the competition's
versions, made once into the cache: see 'arenabench check --help'); {{ and }} are literal
braces; relative paths are resolved from the team folder. {python} (arenabench's own Python)
is refused: name the teams' interpreter. Submissions are only read.

outputs in --out: teams/TEAM/ (report.json, results.csv, report.md, report.html, junit.xml,
grade-state.json), leaderboard.json (schema arenabench.leaderboard/1), leaderboard.csv,
leaderboard.html. Ranked by pass rate, then count exact rate, then median |area error|;
teams equal on all three share a rank (listed by name); latency is never ranked on.

Before any team runs (exit 2, one line, when one fails): bubblewrap must work (or pass
--sandbox none explicitly); a set generated with a seed below 2**64 is refused (generate
hidden sets with --seed random, or pass --allow-guessable-seed); the preflight runs a probe
and the built-in reference submission (or --reference DIR) through the grading command in the
sandbox and reports the Python, numpy and OpenCV versions seen there (in leaderboard.json and
each team's report.json), and warns when arenabench itself is importable there.

Resuming: a team graded before on the same dataset (manifest sha256), with the same submission
files and the same options is skipped ("skipped: already graded"); so is everything after an
interruption that had finished. A team an interruption stopped half-way keeps the results of
its finished images (teams/TEAM/partial-results.jsonl): only the others run again.

A team whose runs time out N times in a row (in image order; --give-up-after N) is given up:
its later images are not run, and every image after the first such run counts as a timeout
("skipped: N consecutive timeouts before it"), whether it ran or not; its report.json says how
many (given_up).

exit status: 0 done; 1 some team could not be graded; 2 usage error or a failed check before
any team ran; 3 most teams failed alike (the setup, not the teams); 4 the harness could not run
an image (nothing of it scored; run again to resume); 130/143 interrupted (the
leaderboard of the finished teams is written, marked INCOMPLETE, naming the unfinished teams
and how far each got). The organiser's recipe from
a fresh machine: docs/grading.md.
"""


def build_parser() -> CommandParser:
    """The argument parser of ``arenabench grade``."""
    from arenabench.eval.grade.teams import DEFAULT_COMMAND
    from arenabench.eval.reports import FORMATS

    p = CommandParser(
        prog=PROG,
        description="Grade many teams' submissions on one dataset and rank them.",
        epilog=EPILOG,
    )
    p.add_argument("dataset", help="dataset folder (holds manifest.jsonl and gt/)")
    p.add_argument("submissions", help="folder with one sub-folder per team")
    add_out(p, required=True)
    add_cmd(p, default=DEFAULT_COMMAND, help="command template per team and image")
    add_output_mode(p, OUTPUT_MODES)
    add_tolerance(p)
    add_area_reference(p)
    add_formats(p, tuple(FORMATS), help="report files per team")
    add_scheduler(p, help="run on an existing Dask cluster (dataset and submissions at the "
                  "same paths on every worker; see docs/scale-out.md)")
    add_workers(p, help="commands run at once here")
    p.add_argument("--report-workers", type=WORKERS_RULE.argtype("--report-workers"),
                   default=None, metavar="N",
                   help="processes here writing the teams' reports (default: cores)")
    add_no_progress(p)
    p.add_argument("--allow-guessable-seed", action="store_true",
                   help="grade a set generated with a seed below 2**64 (a submission can "
                        "re-render it and read its answers)")
    p.add_argument("--reference", default=None, metavar="DIR",
                   help="a known-good submission for the preflight (default: the built-in "
                        "reference detector as a competition script)")
    from arenabench.limits import DEFAULT_GIVE_UP_AFTER

    p.add_argument("--give-up-after", type=GIVE_UP_AFTER_RULE.argtype("--give-up-after"),
                   default=DEFAULT_GIVE_UP_AFTER, metavar="N",
                   help="after N timeouts in a row (in image order) run none of that team's "
                   "later images: they are recorded as timeouts, 'skipped' (0: never; "
                   "default: %(default)s)")
    add_phase_check_argument(p)
    add_run_options(p, placeholders=GRADE_PLACEHOLDERS, refused=GRADE_REFUSED)
    return p


#: GradeOptions parameter -> the option that sets it (for error messages).
_OPTION_NAMES = {"command": "--cmd", "formats": "--formats", "tolerance": "--tolerance",
                 "give_up_after": "--give-up-after"}


def _error(message: str) -> int:
    return usage_error(PROG, message)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``arenabench grade``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    if args.reference is not None and not Path(args.reference).is_dir():
        return _error(f"--reference {args.reference}: not a folder (a known-good submission)")

    from arenabench.eval.datasets.reader import DatasetError
    from arenabench.eval.grade.submissions import SubmissionsError

    if problem := output_problem(args.out):
        return _error(problem)
    try:
        dataset, options = _inputs(args)
    except (DatasetError, SubmissionsError, ValueError) as exc:
        msg = str(exc)
        for param, option in _OPTION_NAMES.items():  # GradeOptions names its parameters
            if msg.startswith(f"{param} "):
                msg = f"{option}{msg[len(param):]}"
        return _error(msg)
    from arenabench.eval.commands.poor_fit import say_poor_fits
    from arenabench.eval.phase_check import set_presets

    say_poor_fits(PROG, set_presets(dataset))
    result = _run(args, dataset, options)
    if isinstance(result, int):
        return result
    return _said(result)


def _inputs(args):
    """The dataset and the grade's options, every input checked before any run."""
    from arenabench.eval.datasets.reader import load_dataset
    from arenabench.eval.grade.grading import GradeOptions, check_out_dir
    from arenabench.eval.grade.submissions import find_teams
    from arenabench.eval.phase_check import resolve_phases, set_presets
    from arenabench.eval.runs import run_settings_from_args

    dataset = load_dataset(args.dataset)
    phases = resolve_phases(args.phase_check, set_presets(dataset))
    options = GradeOptions(command=args.cmd, output=args.output, tolerance=args.tolerance,
                           area_reference=args.area_reference,
                           settings=run_settings_from_args(args), formats=args.formats,
                           phases=phases, give_up_after=args.give_up_after)
    find_teams(args.submissions)
    check_out_dir(args.out, Path(args.submissions), dataset.root)
    return dataset, options


def _run(args, dataset, options):
    """Make the competition's interpreter where the command names it, take the lock and
    grade; the grade's result, or an exit status."""
    from contextlib import ExitStack
    from dataclasses import replace

    from arenabench.eval.datasets.reader import DatasetError
    from arenabench.eval.grade.grading import grade
    from arenabench.eval.grade.submissions import SubmissionsError
    from arenabench.eval.runs import resolve_competition_python
    from arenabench.eval.scoring.results import HarnessError
    from arenabench.fileio import FolderLockedError
    from arenabench.interrupts import Interrupted, stop_on_signals

    with stop_on_signals(), ExitStack() as held:
        try:
            (command,), _ = resolve_competition_python([options.command], prog=PROG,
                                                progress=not args.no_progress)
            options = replace(options, command=command)
            held.enter_context(lock_out(args.out))  # generate's lock: one run per --out
            result = grade(dataset, args.submissions, args.out, options=options,
                           workers=args.workers, scheduler=args.scheduler,
                           report_workers=args.report_workers, progress=not args.no_progress,
                           log=print, allow_guessable_seed=args.allow_guessable_seed,
                           reference=args.reference)
        except (DatasetError, SubmissionsError, ValueError) as exc:
            return _error(str(exc))
        except OSError as exc:  # e.g. the scheduler cannot be reached
            return _error(f"{type(exc).__name__}: {exc}")
        except FolderLockedError as exc:
            return _error(str(exc))
        except HarnessError as exc:  # the grader's own failure: nothing of it was scored
            print(f"{PROG}: error: the harness could not run an image: {exc}; nothing of it "
                  "was scored, finished teams stay graded (and the finished images of the "
                  "others): run the same command again to resume", file=sys.stderr)
            return ExitCode.HARNESS
        except Interrupted as exc:
            print(f"{PROG}: {exc}: finished teams stay graded, and the finished images of "
                  "the others; run the same command again to resume", file=sys.stderr)
            return exc.exit_code
    return result


def _said(result) -> int:
    """The grade's closing lines and exit status."""
    failed = f", {len(result.errors)} failed" if result.errors else ""
    print(f"{len(result.graded)} graded, {len(result.skipped)} skipped{failed}; "
          f"leaderboard of {len(result.rows)} teams:")
    for name, path in result.files.items():
        print(f"  {name:<16} {path}")
    if result.errors:
        for team, why in result.errors.items():  # a name that is not printable, escaped
            shown = team if team.isprintable() else repr(team)
            print(f"{PROG}: could not grade {shown}: {why}", file=sys.stderr)
        return ExitCode.FAILED
    if result.systemic:
        print(f"{PROG}: error: {result.systemic}", file=sys.stderr)
        return ExitCode.SYSTEMIC
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
