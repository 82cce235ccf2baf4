"""``arenabench eval``: score a pipeline on a dataset, write reports, gate CI with exit codes.

Exit status: 0 all thresholds met; 1 a ``--fail-under`` threshold missed (one-line reason on
stderr); 2 usage error (bad options, bad dataset, unreadable report, missing executable);
130/143 stopped by SIGINT/SIGTERM (running commands killed, the finished images' reports
written with ``"complete": false``).
"""

from __future__ import annotations

import sys
from contextlib import ExitStack
from pathlib import Path

from arenabench.cliopts import (
    EXIT_FAILED,
    CommandParser,
    add_area_reference,
    add_count,
    add_no_progress,
    add_out,
    add_run_options,
    add_tolerance,
    add_workers,
    lock_out,
    output_problem,
    write_failure,
)

from .metric_registry import fail_under_help
from .phase_check import add_phase_check_argument
from .pipelines import BUILTIN_PIPELINES
from .predictions import OUTPUT_MODES
from .run_limits import run_settings_from_args

EPILOG = """\
examples:
  arenabench eval DATASET --pipeline reference --out out/
  arenabench eval DATASET --pipeline mypkg.module:function
  arenabench eval DATASET --cmd "python3 map.py --image {image}" --timeout 30
  arenabench eval DATASET --pipeline seed --fail-under pass_rate=0.95,area_rel_err.p95=0.05
  arenabench eval --compare OLD/report.json NEW/report.json

--cmd: split into arguments without a shell; {image} is the path of a private copy of the
image (named image.png etc., --image-name) and {python} the Python running arenabench. Each
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
    src.add_argument(
        "--cmd", help="external command template, e.g. 'python3 map.py --image {image}'"
    )
    src.add_argument(
        "--compare", nargs=2, metavar=("OLD", "NEW"), help="compare two report.json files"
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
    p.add_argument(
        "--output",
        choices=OUTPUT_MODES,
        default="obstacles",
        help="how --cmd answers: obstacles.txt in its cwd (default) or a JSON line",
    )
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
    p.add_argument(
        "--formats",
        default="json,csv,md,html,junit",
        help="report files to write (default: json,csv,md,html,junit)",
    )
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


def _warn_if_incomplete(root: Path) -> None:
    """One warning line when ``dataset.json`` says an interrupted ``generate`` left the dataset
    unfinished: the scores then cover only the scenes its manifest lists."""
    import json

    try:
        meta = json.loads((root / "dataset.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    if isinstance(meta, dict) and meta.get("complete") is False:
        count = (meta.get("args") or {}).get("count", "?")
        print(f"arenabench eval: warning: {root}/dataset.json: the dataset is incomplete "
              f"({meta.get('finished', '?')} of {count} scenes; an interrupted generate): only "
              "those are scored; run the same generate command again to finish it",
              file=sys.stderr)


def _usage_error(parser: CommandParser, message: str) -> int:
    return parser.fail(message)


def _run_compare(old: str, new: str, gate: list[str]) -> int:
    from .compare import compare, format_comparison, parse_regression_limits, regressions
    from .reports.json_report import read_json

    try:
        limits = parse_regression_limits(gate)
        a, b = read_json(old), read_json(new)
    except ValueError as exc:
        print(f"arenabench eval: error: {exc}", file=sys.stderr)
        return 2
    cmp = compare(a, b)
    print(format_comparison(cmp, old_name=old, new_name=new), end="")
    reasons = regressions(cmp, limits)
    if reasons:
        print(f"arenabench eval: FAILED: regression: {'; '.join(reasons)}", file=sys.stderr)
        return 1
    return 0


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
    if args.out is not None and (problem := output_problem(args.out)):
        return _usage_error(parser, problem)

    from arenabench.fileio import FolderLockedError
    from arenabench.interrupts import Interrupted, deferred_stops

    early: Interrupted | None = None  # a stop while the modules load: raised once they have
    try:
        with deferred_stops():
            from .dataset_reader import DatasetError, load_dataset
            from .evaluation import EvaluationInterrupted, empty_report, evaluate
            from .external import CommandPipeline
            from .phase_check import resolve_phases
            from .pipelines import make_pipeline
            from .reports import FORMATS, write_reports
            from .reports.summary_rows import headline
            from .thresholds import check_thresholds, parse_thresholds
    except Interrupted as exc:
        early = exc

    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in FORMATS]
    if not formats:
        return _usage_error(parser, f"--formats {args.formats!r}: no format named (known: "
                                    f"{', '.join(FORMATS)})")
    if bad:
        return _usage_error(parser, f"--formats: unknown {bad} (known: {', '.join(FORMATS)})")
    # the work starts here: a stop from now on writes the partial (perhaps empty) reports
    dataset = None
    locked = False
    interrupted: EvaluationInterrupted | None = None
    try:
        if early is not None:
            raise early
        try:
            thresholds = parse_thresholds(args.fail_under)
            pipeline = (
                CommandPipeline(args.cmd, settings=run_settings_from_args(args),
                                output=args.output, name=args.name or "")
                if args.cmd
                else make_pipeline(args.pipeline)
            )
            dataset = load_dataset(args.dataset, limit=args.limit, verify=not args.no_verify,
                                   skip_damaged=args.skip_damaged)
        except (DatasetError, ValueError) as exc:
            return _usage_error(parser, str(exc))
        try:  # the same lock as generate's: one run at a time writes into --out
            held.enter_context(lock_out(args.out))
            locked = True
        except FolderLockedError as exc:
            return _usage_error(parser, str(exc))
        _warn_if_incomplete(Path(args.dataset))
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
            phases=resolve_phases(args.phase_check,
                                  dataset.presets()),
            isolate=True,
            timeout_s=args.timeout,
        )
    except ValueError as exc:
        return _usage_error(parser, str(exc))
    except EvaluationInterrupted as exc:
        interrupted = exc
    except Interrupted as exc:  # before evaluate() had a report: an empty one
        interrupted = EvaluationInterrupted(empty_report(
            pipeline=args.name or args.cmd or args.pipeline,
            dataset=str(dataset.root if dataset is not None else args.dataset),
            area_reference=args.area_reference, tolerance=args.tolerance,
            n_total=None if dataset is None else len(dataset.samples)), exc.signum)
    if interrupted is not None:
        report = interrupted.report
        total = f" of {report.n_total}" if report.n_total is not None else ""
        print(
            f"arenabench eval: interrupted by signal {interrupted.signum} after "
            f"{report.images_done}{total} images; running commands killed",
            file=sys.stderr,
        )
        if args.out is not None:  # even with no image finished: never nothing
            try:
                with deferred_stops():  # a second stop does not cut the writing short
                    if not locked:
                        held.enter_context(lock_out(args.out))
                    write_reports(report, args.out, formats=formats, dataset=dataset)
            except FolderLockedError as exc:
                parser.fail(str(exc))
                return interrupted.exit_code
            except OSError as exc:
                parser.fail(write_failure(exc, args.out))
                return interrupted.exit_code
            print(f"  partial reports (\"complete\": false) in {args.out}", file=sys.stderr)
        return interrupted.exit_code
    written: dict = {}
    try:
        # every image ran: a stop now cuts no report off; it is raised once they are written
        # and the exit status says it came (arenabench.cli.run)
        with deferred_stops():
            print(headline(report))
            if args.out is not None:
                written = write_reports(report, args.out, formats=formats, dataset=dataset)
    except Interrupted:
        pass
    except OSError as exc:  # ENOSPC: one line, no traceback
        parser.fail(write_failure(exc, args.out))
        return EXIT_FAILED
    for fmt, path in written.items():
        print(f"  {fmt:<5} {path}")
    reasons = check_thresholds(report.summary, thresholds)
    if reasons:
        print(f"arenabench eval: FAILED: {'; '.join(reasons)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
