"""``arenabench check map.py``: know before you submit.

Generates (or reuses, from the user cache) a set of hidden-test twin scenes, runs the script on
each as the competition did (``python3 map.py --image PATH``, ``obstacles.txt`` in the working
directory; sandboxed where bubblewrap works: the ``eval --cmd`` machinery), phase-checks the
failures, and prints a short verdict with the report's path (docs/phase-check.md).

Exit status: 0 the pass rate reaches ``--fail-under``; 1 it does not; 2 bad input (before any
work); 130/143 stopped by SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import os
import sys
from pathlib import Path

from arenabench.cliopts import (
    CommandParser,
    add_count,
    add_no_progress,
    add_out,
    add_run_options,
    add_workers,
    output_problem,
    usage_error,
)

from .phase_check import add_phase_check_argument

PROG = "arenabench check"
#: Twin scenes a check runs on by default.
DEFAULT_COUNT = 200
DEFAULT_PRESET = "eyrc"
#: Pass rate a script must reach (``--fail-under``).
DEFAULT_FAIL_UNDER = 0.95
#: Environment variable naming the cache folder (default: ``$XDG_CACHE_HOME/arenabench``, else
#: ``~/.cache/arenabench``).
CACHE_ENV = "ARENABENCH_CACHE_DIR"
#: Largest ``--count``.
MAX_COUNT = 10000

EPILOG = """\
examples:
  arenabench check map.py                       # 200 eyrc twin scenes, threshold 95 %
  arenabench check map.py --count 50 --fail-under 0.9
  arenabench check src/map.py --preset eyrc-jitter --seed 3 --out check-report/

The twin set is generated once per (preset, seed, count, generator version) into the cache
(ARENABENCH_CACHE_DIR, else $XDG_CACHE_HOME/arenabench, else ~/.cache/arenabench: sets/) and
reused. The script runs as '{python} SCRIPT --image IMAGE' (the Python running arenabench,
which has OpenCV; --python for another) with its own folder visible read-only and, as its
working directory, a private copy of that folder (what the competition's run in the script's
folder amounts to, without letting one run see another's obstacles.txt); exit status 3 means
markers not found.

exit status: 0 pass rate >= --fail-under, 1 below it, 2 bad input, 130/143 interrupted.
"""


def build_parser() -> CommandParser:
    """The argument parser of ``arenabench check``."""
    p = CommandParser(
        prog=PROG,
        description="Know before you submit: run a competition script on hidden-test twin "
        "scenes, tell robust failures from luck, and name the strongest cause.",
        epilog=EPILOG,
    )
    p.add_argument("script", help="the competition script (map.py)")
    add_count(p, maximum=MAX_COUNT, default=DEFAULT_COUNT,
              help=f"twin scenes (default: {DEFAULT_COUNT})")
    p.add_argument("--seed", type=int, default=0, help="scene seed (default: %(default)s)")
    p.add_argument("--preset", default=DEFAULT_PRESET,
                   help="scene preset (default: %(default)s, the hidden-test twin)")
    p.add_argument("--fail-under", type=float, default=DEFAULT_FAIL_UNDER, metavar="RATE",
                   help="pass rate needed for exit status 0 (default: %(default)s)")
    p.add_argument("--python", default="{python}",
                   help="interpreter that runs the script (default: the one running "
                   "arenabench)")
    add_out(p, help="folder for the report files (default: the cache's reports/ folder)")
    add_workers(p, help="scripts run at once")
    add_no_progress(p)
    add_phase_check_argument(p)
    add_run_options(p)
    return p


def cache_dir() -> Path:
    """The user cache folder of arenabench (see :data:`CACHE_ENV`)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "arenabench"


def twin_set_dir(*, preset: str, seed: int, count: int) -> Path:
    """Cache folder of the twin set ``<preset>-<seed>-<count>-<generator version>``."""
    from arenabench.generator.make import GENERATOR_VERSION

    return cache_dir() / "sets" / f"{preset}-{seed}-{count}-v{GENERATOR_VERSION}"


def _report_dir(script: Path) -> Path:
    digest = hashlib.sha256(str(script).encode()).hexdigest()[:10]
    return cache_dir() / "reports" / f"{script.stem}-{digest}"


def _error(message: str) -> int:
    return usage_error(PROG, message)


def _validate(args: argparse.Namespace) -> str | None:
    """The first bad input, as one line; ``None`` when all is well."""
    from arenabench.generator.presets import get_preset

    script = Path(args.script)
    if not script.exists():
        return f"{args.script}: no such file"
    if not script.is_file():
        return f"{args.script}: not a file"
    if not os.access(script, os.R_OK):
        return f"{args.script}: not readable"
    if args.seed < 0:
        return f"--seed must be >= 0, got {args.seed}"
    if not (math.isfinite(args.fail_under) and 0.0 <= args.fail_under <= 1.0):
        return f"--fail-under must be a pass rate in [0, 1], got {args.fail_under}"
    try:
        get_preset(args.preset)
    except ValueError as exc:
        return f"--preset: {exc}"
    return None


def verdict_lines(report, *, fail_under: float, phases: int) -> list[str]:
    """The verdict: pass rate, robust and phase-dependent failures, the strongest cause
    (:func:`arenabench.eval.breakdown.strongest_cause_text`)."""
    from .breakdown import strongest_cause_text
    from .phase_check import PHASE_DEPENDENT_MEANING, rate_text, unchecked_text

    s = report.summary
    ok = s.pass_rate >= fail_under
    lines = [f"{'PASS' if ok else 'FAIL'}: pass rate {rate_text(s.pass_rate)} "
             f"({s.n_passed}/{s.n}; needed {rate_text(fail_under)})"]
    n_fail = s.n - s.n_passed
    if n_fail:
        fails = ", ".join(f"{c} {v}" for c, v in s.failures.items() if v)
        lines.append(f"  failures: {n_fail} ({fails})")
        pc = s.phase_check
        if pc is not None:
            lines.append(f"  robust failures: {pc['robust']} ({rate_text(s.robust_failure_rate)})"
                         ": fail at every sub-pixel position: the method is wrong there")
            lines.append(f"  phase-dependent failures: {pc['phase_dependent']} "
                         f"({rate_text(s.phase_dependent_failure_rate)}): "
                         f"{PHASE_DEPENDENT_MEANING.split(': ', 1)[1]}")
        unchecked = pc["unchecked"] if pc is not None else n_fail
        if phases and unchecked:
            lines.append(f"  not phase-checked ({unchecked_text()}): {unchecked}")
        if report.causes:
            text = strongest_cause_text(report.causes)
            lines.append(f"  {text[0].lower()}{text[1:]}")
        first = next(r for r in report.images if not r.passed)
        detail = first.prediction.message or (
            f"gt {first.truth.count} obstacles / {first.truth.area:.0f} px, answered "
            f"{first.prediction.count} / {first.prediction.area}")
        lines.append(f"  first failure: {first.id}: {first.category}: {detail[:200]}")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``arenabench check``; returns the exit status."""
    from arenabench.interrupts import Interrupted, stop_on_signals

    with stop_on_signals():
        try:
            return _main(argv)
        except Interrupted as exc:
            print(f"{PROG}: interrupted ({exc}); nothing more written", file=sys.stderr)
            return exc.exit_code


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    problem = _validate(args)
    if problem:
        return _error(problem)
    import shlex

    from .external import CommandPipeline
    from .run_limits import run_settings_from_args

    script = Path(args.script).resolve()
    out = args.out if args.out is not None else _report_dir(script)
    if problem := output_problem(out):
        return _error(problem)
    template = f"{shlex.quote(args.python)} {shlex.quote(str(script))} --image {{image}}"
    from dataclasses import replace

    try:
        # the working directory holds a copy of the script's folder, as when the competition
        # ran the script there: relative reads work, obstacles.txt lands in the copy
        base = run_settings_from_args(args)
        settings = replace(base, workdir_from=str(script.parent),  # and no __pycache__ there
                           env={"PYTHONDONTWRITEBYTECODE": "1", **base.env})
        pipeline = CommandPipeline(template, settings=settings,
                                   name=script.name, base_dir=str(script.parent))
    except ValueError as exc:
        return _error(str(exc))

    from arenabench.generator.dataset_writer import GenerateError, generate_dataset

    from .dataset_reader import DatasetError, load_dataset
    from .evaluation import EvaluationInterrupted, evaluate
    from .phase_check import resolve_phases
    from .reports import write_reports

    twin = twin_set_dir(preset=args.preset, seed=args.seed, count=args.count)
    progress = not args.no_progress
    try:
        made = generate_dataset(twin, preset=args.preset, count=args.count, seed=args.seed,
                                workers=min(args.workers or _cores(), 8), progress=progress)
    except (GenerateError, ValueError) as exc:
        return _error(f"twin set {twin}: {exc}")
    if made.interrupted is not None:
        print(f"{PROG}: {made.summary()}", file=sys.stderr)
        return 128 + made.interrupted
    from arenabench.cliopts import lock_out
    from arenabench.fileio import FolderLockedError
    from arenabench.interrupts import Interrupted, deferred_stops

    from .evaluation import empty_report

    # the set is made: a stop from now on writes the partial (perhaps empty) reports
    dataset = None
    phases = resolve_phases(args.phase_check, [args.preset])
    try:
        with lock_out(out):  # one run at a time writes into the report folder
            try:
                try:
                    dataset = load_dataset(twin)
                except (DatasetError, ValueError) as exc:
                    return _error(f"twin set {twin}: {exc}")
                what = "reused" if made.rendered == 0 else f"generated {made.rendered} scenes of"
                print(f"{PROG}: {what} twin set {twin} ({args.count} scenes of {args.preset}, "
                      f"seed {args.seed})")
                report = evaluate(pipeline, dataset, workers=args.workers, progress=progress,
                                  phases=phases)
            except (EvaluationInterrupted, Interrupted) as exc:  # partial reports, INCOMPLETE
                partial = exc.report if isinstance(exc, EvaluationInterrupted) else empty_report(
                    pipeline=pipeline.name, dataset=str(twin),
                    n_total=None if dataset is None else len(dataset.samples))
                with deferred_stops():  # a second stop does not cut the writing short
                    write_reports(partial, out, dataset=dataset)
                print(f"{PROG}: interrupted after {partial.images_done} images; running "
                      f"scripts killed; partial report in {out}", file=sys.stderr)
                return exc.exit_code
            try:
                with deferred_stops():  # every image ran: a stop cuts no report off
                    written = write_reports(report, out, dataset=dataset)
            except Interrupted:  # raised once they are written: the exit status says so
                pass
    except FolderLockedError as exc:
        return _error(str(exc))
    for line in verdict_lines(report, fail_under=args.fail_under, phases=phases):
        print(line)
    print(f"  report: {written.get('html', next(iter(written.values()))).resolve()}")
    return 0 if report.summary.pass_rate >= args.fail_under else 1


def _cores() -> int:
    from arenabench.workers import usable_cores

    return usable_cores()


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
