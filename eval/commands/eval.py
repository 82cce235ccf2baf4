"""``arenabench eval``: score a pipeline on a dataset, write reports, gate CI with exit codes.

Exit status: 0 all thresholds met; 1 a ``--fail-under`` threshold missed (one-line reason on
stderr); 2 usage error (bad options, bad dataset, unreadable report, missing executable);
130/143 stopped by SIGINT/SIGTERM (running commands killed, the finished images' reports
written with ``"complete": false``).
"""

from __future__ import annotations

import sys
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from arenabench.cliopts import (
    CommandParser,
    add_area_reference,
    add_cmd,
    add_count,
    add_formats,
    add_no_progress,
    add_out,
    add_output_mode,
    add_run_options,
    add_tolerance,
    add_workers,
    lock_out,
    output_problem,
    write_failure,
)
from arenabench.eval.phase_check import add_phase_check_argument
from arenabench.eval.pipelines import BUILTIN_PIPELINES
from arenabench.eval.runs import OUTPUT_MODES, run_settings_from_args
from arenabench.eval.scoring.metric_registry import fail_under_help
from arenabench.exitcodes import ExitCode

if TYPE_CHECKING:
    from arenabench.eval.datasets.reader import Dataset

EPILOG = """\
examples:
  arenabench eval DATASET --pipeline reference --out out/
  arenabench eval DATASET --pipeline mypkg.module:function
  arenabench eval DATASET --cmd "python3 map.py --image {image}" --timeout 30
  arenabench eval DATASET --cmd "{competition_python} map.py --image {image}"
  arenabench eval DATASET --pipeline seed --fail-under pass_rate=0.95,area_rel_err.p95=0.05
  arenabench eval --compare OLD/ NEW/     # two --out folders (or their report.json files)

--cmd: split into arguments without a shell; {image} is the path of a private copy of the
image (named image.png etc., --image-name), {python} the Python running arenabench and
{competition_python} the competition's environment (numpy and OpenCV at the competition's
versions, made once into the cache from the package index; arenabench's own Python, with one
line saying so, where it cannot be made); {{ and }} are literal braces, any other placeholder is
refused, and so is a script (an argument ending in .py, or the one after a Python interpreter)
that does not exist. Each
image runs in its own private directory holding only that copy; the command writes
obstacles.txt there (or prints a JSON line with --output json). Exit status 3 means "markers
not found". Under bubblewrap (--sandbox auto|bwrap) the command sees only the system, Python
and its own folder (read-only), no network and no dataset; without it the private directory,
limits and cleanup still apply. A run that hits --memory-limit, --max-procs or
--max-file-size is category 'limit'; every process a run starts is killed when it ends.

""" + fail_under_help() + """

exit status: 0 ok, 1 a threshold missed, 2 usage error, 130/143 interrupted (SIGINT/SIGTERM).
"""


def build_parser() -> CommandParser:
    """The argument parser of ``arenabench eval``."""
    from arenabench.eval.reports import FORMATS

    p = CommandParser(
        prog="arenabench eval",
        description="Score an obstacle-detection pipeline on a dataset written by the generator.",
        epilog=EPILOG,
    )
    p.add_argument("dataset", nargs="?", help="dataset folder (holds manifest.jsonl and gt/)")
    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--pipeline",
        help=f"built-in ({', '.join(BUILTIN_PIPELINES)}) or a callable 'pkg.module:function' "
        "(the module is looked for in the current folder first, then on sys.path)",
    )
    add_cmd(src)
    src.add_argument(
        "--compare", nargs=2, metavar=("OLD", "NEW"),
        help="compare two reports of the same dataset: report.json files or the --out "
        "folders holding them (reports of different datasets are refused)"
    )
    p.add_argument(
        "--fail-on-regression", action="append", default=[], metavar="METRIC=DELTA",
        help="with --compare: exit 1 when METRIC got worse by more than DELTA, e.g. "
        "pass_rate=0.02,area_rel_err.p95=0.01 (comma-separated or repeated)",
    )
    p.add_argument(
        "--name", default=None,
        help="the --cmd pipeline's name in reports (default: its template)",
    )
    add_output_mode(p, OUTPUT_MODES)
    add_workers(p, help="parallel workers")
    p.add_argument(
        "--executor",
        choices=("thread", "process"),
        default="thread",
        help="pool for the built-in pipelines (default thread); a 'pkg.module:function' "
        "runs in child processes either way (an exit, a crash or --timeout fails its image)",
    )
    add_tolerance(p)
    add_area_reference(p)
    add_out(p, help="folder for the report files")
    add_formats(p, tuple(FORMATS))
    p.add_argument(
        "--fail-under",
        action="append",
        default=[],
        metavar="METRIC=VALUE",
        help="threshold(s); see below",
    )
    add_count(p, "--limit", help="evaluate only the first N images")
    add_no_progress(p)
    add_phase_check_argument(p)
    add_run_options(p)
    p.add_argument(
        "--no-verify",
        action="store_true",
        help="do not check images and GT against the sha256 values of manifest.jsonl",
    )
    p.add_argument(
        "--skip-damaged", action="store_true",
        help="leave out image files that cannot be whole images (empty, text, cut short) and "
        "score the others (default: such a dataset is refused, 'dataset damaged')",
    )
    return p


def _warn_if_incomplete(dataset: Dataset) -> None:
    """One warning line when ``dataset.json`` says an interrupted ``generate`` left the dataset
    unfinished: the scores then cover only the scenes its manifest lists."""
    from arenabench.eval.datasets.reader import read_dataset_meta

    info = dataset.meta if dataset.meta is not None else read_dataset_meta(dataset.root)
    meta = info.doc
    if isinstance(meta, dict) and meta.get("complete") is False:
        args = meta.get("args")
        count = args.get("count", "?") if isinstance(args, dict) else "?"
        print(f"arenabench eval: warning: {info.path}: the dataset is incomplete "
              f"({meta.get('finished', '?')} of {count} scenes; an interrupted generate): only "
              "those are scored; run the same generate command again to finish it",
              file=sys.stderr)


def _usage_error(parser: CommandParser, message: str) -> int:
    return parser.fail(message)


def _compare_input(arg: str) -> Path:
    """The report a ``--compare`` argument names: a ``report.json`` file, or an ``--out``
    folder holding one."""
    from arenabench.eval.reports import FORMATS

    path = Path(arg)
    if path.is_dir():
        inside = path / FORMATS["json"]
        if not inside.exists():
            raise ValueError(f"{arg}: a folder without {FORMATS['json']} (give a report.json "
                             "file or the --out folder of an eval that wrote one)")
        return inside
    return path


def _run_compare(old: str, new: str, gate: list[str]) -> int:
    from arenabench.eval.reports.json_report import read_json
    from arenabench.eval.scoring.compare import (
        compare,
        dataset_problem,
        format_comparison,
        parse_regression_limits,
        regression_gate_lines,
        regressions,
    )

    try:
        limits = parse_regression_limits(gate)
        a, b = read_json(_compare_input(old)), read_json(_compare_input(new))
        problem, warning = dataset_problem(a, b, old_name=old, new_name=new)
        if problem:
            raise ValueError(problem)
    except ValueError as exc:
        print(f"arenabench eval: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    if warning:
        print(f"arenabench eval: warning: {warning}", file=sys.stderr)
    cmp = compare(a, b)
    print(format_comparison(cmp, old_name=old, new_name=new), end="")
    for line in regression_gate_lines(cmp, limits):
        print(line)
    reasons = regressions(cmp, limits)
    if reasons:
        print(f"arenabench eval: FAILED: regression: {'; '.join(reasons)}", file=sys.stderr)
        return ExitCode.FAILED
    return ExitCode.OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``arenabench eval``; returns the exit status."""
    from contextlib import ExitStack

    from arenabench.interrupts import Interrupted, stop_on_signals

    with stop_on_signals(), ExitStack() as held:  # held: the --out lock, until the end
        try:
            return _main(argv, held)
        except Interrupted as exc:
            print(f"arenabench eval: interrupted ({exc}); nothing more written",
                  file=sys.stderr)
            return exc.exit_code


def _main(argv: list[str] | None, held: ExitStack) -> int:
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    if args.compare:
        return _run_compare(*args.compare, args.fail_on_regression)
    if args.fail_on_regression:
        return _usage_error(parser, "--fail-on-regression goes with --compare OLD NEW")
    if not args.dataset:
        return _usage_error(parser, "a DATASET folder is required (or --compare OLD NEW)")
    if args.name is not None and not args.cmd:
        return _usage_error(parser, "--name names a --cmd pipeline (give --cmd TEMPLATE)")
    if args.name is not None and not args.name.strip():
        return _usage_error(parser, "--name must not be empty")
    if not args.pipeline and not args.cmd:
        return _usage_error(parser, "give --pipeline NAME|pkg.module:function or --cmd TEMPLATE")
    from arenabench.eval.reports import FORMATS, write_reports

    if args.out is not None and (problem := output_problem(
            args.out, own=FORMATS.values(), what="'arenabench eval' report",
            inputs=[("DATASET", args.dataset)])):
        return _usage_error(parser, problem)

    import os

    from arenabench.fileio import FolderLockedError
    from arenabench.interrupts import Interrupted, deferred_stops

    early: Interrupted | None = None  # a stop while the modules load: raised once they have
    try:
        with deferred_stops():
            from arenabench.eval.datasets.reader import DatasetError, load_dataset
            from arenabench.eval.evaluation import (
                EvaluationFailed,
                EvaluationInterrupted,
                empty_report,
                evaluate,
            )
            from arenabench.eval.phase_check import resolve_phases, set_presets
            from arenabench.eval.pipelines import make_pipeline
            from arenabench.eval.reports.summary_rows import first_failure_line, headline
            from arenabench.eval.runs import (
                OWN_PYTHON_PLACEHOLDER,
                CommandPipeline,
                missing_script_problem,
                resolve_competition_python,
                substitute_competition_python,
                uses_competition_python,
            )
            from arenabench.eval.scoring.thresholds import check_thresholds, parse_thresholds
    except Interrupted as exc:
        early = exc

    formats = args.formats
    # the work starts here: a stop from now on writes the partial (perhaps empty) reports
    dataset = None
    locked = False
    interpreter = None
    interrupted: EvaluationInterrupted | None = None
    failed: EvaluationFailed | None = None
    try:
        if early is not None:
            raise early
        try:
            thresholds = parse_thresholds(args.fail_under)
            if args.cmd and (problem := missing_script_problem(args.cmd,
                                                               base_dir=os.getcwd())):
                raise ValueError(f"--cmd {args.cmd!r}: {problem}")
            if args.cmd and uses_competition_python(args.cmd):  # the rest of the command first
                CommandPipeline(substitute_competition_python(args.cmd, OWN_PYTHON_PLACEHOLDER),
                                settings=run_settings_from_args(args), output=args.output)
            else:
                pipeline = (
                    CommandPipeline(args.cmd, settings=run_settings_from_args(args),
                                    output=args.output, name=args.name or "")
                    if args.cmd
                    else make_pipeline(args.pipeline)
                )
            dataset = load_dataset(args.dataset, limit=args.limit, verify=not args.no_verify,
                                   skip_damaged=args.skip_damaged)
            if args.cmd and uses_competition_python(args.cmd):  # made once, then reused
                (command,), interpreter = resolve_competition_python(
                    [args.cmd], progress=not args.no_progress, prog="arenabench eval")
                pipeline = CommandPipeline(command, settings=run_settings_from_args(args),
                                           output=args.output, name=args.name or args.cmd)
        except (DatasetError, ValueError) as exc:
            return _usage_error(parser, str(exc))
        try:  # the same lock as generate's: one run at a time writes into --out
            held.enter_context(lock_out(args.out))
            locked = True
        except FolderLockedError as exc:
            return _usage_error(parser, str(exc))
        _warn_if_incomplete(dataset)
        if dataset.skipped:
            first, why = dataset.skipped[0]
            print(f"arenabench eval: warning: {len(dataset.skipped)} damaged image(s) left out "
                  f"(--skip-damaged; {first}: {why})", file=sys.stderr)
        report = evaluate(
            args.pipeline if args.pipeline else pipeline,
            dataset,
            workers=args.workers,
            tolerance=args.tolerance,
            area_reference=args.area_reference,
            executor=args.executor,
            progress=not args.no_progress,
            phases=resolve_phases(args.phase_check, set_presets(dataset)),
            isolate=True,
            timeout_s=args.timeout,
        )
    except ValueError as exc:
        return _usage_error(parser, str(exc))
    except EvaluationInterrupted as exc:
        interrupted = exc
    except EvaluationFailed as exc:
        failed = exc
    except Interrupted as exc:  # before evaluate() had a report: an empty one
        interrupted = EvaluationInterrupted(empty_report(
            pipeline=args.name or args.cmd or args.pipeline,
            dataset=str(dataset.root if dataset is not None else args.dataset),
            area_reference=args.area_reference, tolerance=args.tolerance,
            n_total=None if dataset is None else len(dataset.samples)), exc.signum)
    stopped = interrupted or failed
    if stopped is not None:
        report = stopped.report
        if interpreter is not None:
            report = replace(report, interpreter=interpreter.to_dict())
        total = f" of {report.n_total}" if report.n_total is not None else ""
        if interrupted is not None:
            print(f"arenabench eval: interrupted by signal {interrupted.signum} after "
                  f"{report.images_done}{total} images; running commands killed",
                  file=sys.stderr)
            code = interrupted.exit_code
        else:
            print(f"arenabench eval: error: {failed}; running commands killed, nothing of it "
                  f"scored ({report.images_done}{total} images finished before)",
                  file=sys.stderr)
            code = ExitCode.HARNESS
        if args.out is not None:  # even with no image finished: never nothing
            try:
                with deferred_stops():  # a second stop does not cut the writing short
                    if not locked:
                        held.enter_context(lock_out(args.out))
                    write_reports(report, args.out, formats=formats, dataset=dataset)
            except FolderLockedError as exc:
                parser.fail(str(exc))
                return code
            except OSError as exc:
                parser.fail(write_failure(exc, args.out))
                return code
            print(f"  partial reports (\"complete\": false) in {args.out}", file=sys.stderr)
        return code
    if interpreter is not None:  # what ran the command, with the reports
        report = replace(report, interpreter=interpreter.to_dict())
    written: dict = {}
    try:
        # every image ran: a stop now cuts no report off; it is raised once they are written
        # and the exit status says it came (arenabench.cli.run)
        with deferred_stops():
            print(headline(report))
            if (first := first_failure_line(report)) is not None:
                print(f"  {first}")
            if args.out is not None:
                written = write_reports(report, args.out, formats=formats, dataset=dataset)
    except Interrupted:
        pass
    except OSError as exc:  # ENOSPC: one line, no traceback
        parser.fail(write_failure(exc, args.out))
        return ExitCode.FAILED
    for fmt, path in written.items():
        print(f"  {fmt:<5} {path}")
    for threshold in thresholds:  # every gate applied, passing or not: the CI log shows them
        print(threshold.gate_line(report.summary))
    reasons = check_thresholds(report.summary, thresholds)
    if reasons:
        print(f"arenabench eval: FAILED: {'; '.join(reasons)}", file=sys.stderr)
        return ExitCode.FAILED
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
