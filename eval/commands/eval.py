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
    if problem := _option_problem(args):
        return _usage_error(parser, problem)
    from arenabench.interrupts import Interrupted, deferred_stops

    early: Interrupted | None = None  # a stop while the modules load: raised once they have
    try:
        with deferred_stops():
            _load_modules()
    except Interrupted as exc:
        early = exc
    return _EvalRun(args, parser, held).main(early)


def _option_problem(args) -> str | None:
    """What is wrong with the options of a run (not ``--compare``), or None."""
    from arenabench.eval.reports import FORMATS

    if args.fail_on_regression:
        return "--fail-on-regression goes with --compare OLD NEW"
    if not args.dataset:
        return "a DATASET folder is required (or --compare OLD NEW)"
    if args.name is not None and not args.cmd:
        return "--name names a --cmd pipeline (give --cmd TEMPLATE)"
    if args.name is not None and not args.name.strip():
        return "--name must not be empty"
    if not args.pipeline and not args.cmd:
        return "give --pipeline NAME|pkg.module:function or --cmd TEMPLATE"
    if args.out is not None:
        return output_problem(args.out, own=FORMATS.values(), what="'arenabench eval' report",
                              inputs=[("DATASET", args.dataset)])
    return None


def _load_modules() -> None:
    """Import what a run needs (under deferred stops: a stop never cuts an import short)."""
    import arenabench.eval.datasets.reader
    import arenabench.eval.evaluation
    import arenabench.eval.phase_check
    import arenabench.eval.pipelines
    import arenabench.eval.reports
    import arenabench.eval.reports.summary_rows
    import arenabench.eval.scoring.thresholds  # noqa: F401


class _EvalRun:
    """One ``arenabench eval`` run in steps: build the pipeline and load the dataset, take the
    ``--out`` lock, evaluate, then report (the whole run, or what finished before a stop)."""

    def __init__(self, args, parser: CommandParser, held: ExitStack) -> None:
        self.args, self.parser, self.held = args, parser, held
        self.dataset: Dataset | None = None
        self.locked = False
        self.interpreter = None
        self.thresholds: list = []

    def main(self, early) -> int:
        """The run; ``early``: a stop that came while the modules loaded (raised first)."""
        from arenabench.eval.evaluation import EvaluationFailed, EvaluationInterrupted
        from arenabench.interrupts import Interrupted

        args = self.args
        # the work starts here: a stop from now on writes the partial (perhaps empty) reports
        try:
            if early is not None:
                raise early
            pipeline = self._prepare()
            if isinstance(pipeline, int):
                return pipeline
            report = self._evaluate(pipeline)
        except ValueError as exc:
            return _usage_error(self.parser, str(exc))
        except (EvaluationInterrupted, EvaluationFailed) as exc:
            return self._stopped(exc)
        except Interrupted as exc:  # before evaluate() had a report: an empty one
            from arenabench.eval.evaluation import empty_report

            dataset = self.dataset
            return self._stopped(EvaluationInterrupted(empty_report(
                pipeline=args.name or args.cmd or args.pipeline,
                dataset=str(dataset.root if dataset is not None else args.dataset),
                area_reference=args.area_reference, tolerance=args.tolerance,
                n_total=None if dataset is None else len(dataset.samples)), exc.signum))
        return self._finished(report)

    def _prepare(self):
        """The pipeline (or the built-in's name) with the dataset loaded and ``--out`` locked;
        an exit status when the options or the dataset are refused."""
        from arenabench.eval.datasets.reader import DatasetError
        from arenabench.fileio import FolderLockedError

        try:
            pipeline = self._pipeline_and_dataset()
        except (DatasetError, ValueError) as exc:
            return _usage_error(self.parser, str(exc))
        try:  # the same lock as generate's: one run at a time writes into --out
            self.held.enter_context(lock_out(self.args.out))
            self.locked = True
        except FolderLockedError as exc:
            return _usage_error(self.parser, str(exc))
        return pipeline

    def _pipeline_and_dataset(self):
        """Check the pipeline's options, load the dataset, then make the pipeline (the
        competition's interpreter is made only once the rest of the command holds)."""
        import os

        from arenabench.eval.datasets.reader import load_dataset
        from arenabench.eval.runs import (
            CommandPipeline,
            check_command,
            missing_script_problem,
            resolve_competition_python,
            uses_competition_python,
        )
        from arenabench.eval.scoring.thresholds import parse_thresholds

        args = self.args
        self.thresholds = parse_thresholds(args.fail_under)
        if not args.cmd:
            from arenabench.eval.pipelines import make_pipeline

            make_pipeline(args.pipeline)  # an unknown name: refused before the dataset is read
            pipeline = args.pipeline  # evaluate() makes it (a callable: isolated)
        elif problem := missing_script_problem(args.cmd, base_dir=os.getcwd()):
            raise ValueError(f"--cmd {args.cmd!r}: {problem}")
        settings = run_settings_from_args(args) if args.cmd else None
        competition = bool(args.cmd) and uses_competition_python(args.cmd)
        if competition:  # the rest of the command first: its interpreter is made after
            check_command(args.cmd, settings=settings, output=args.output)
        elif args.cmd:
            pipeline = CommandPipeline(args.cmd, settings=settings, output=args.output,
                                       name=args.name or "")
        self.dataset = load_dataset(args.dataset, limit=args.limit, verify=not args.no_verify,
                                    skip_damaged=args.skip_damaged)
        if competition:  # made once, then reused
            (command,), self.interpreter = resolve_competition_python(
                [args.cmd], progress=not args.no_progress, prog="arenabench eval")
            pipeline = CommandPipeline(command, settings=settings, output=args.output,
                                       name=args.name or args.cmd)
        return pipeline

    def _evaluate(self, pipeline):
        from arenabench.eval.commands.poor_fit import say_poor_fits
        from arenabench.eval.evaluation import evaluate
        from arenabench.eval.phase_check import resolve_phases, set_presets

        args, dataset = self.args, self.dataset
        say_poor_fits("arenabench eval", set_presets(dataset))
        _warn_if_incomplete(dataset)
        if dataset.skipped:
            first, why = dataset.skipped[0]
            print(f"arenabench eval: warning: {len(dataset.skipped)} damaged image(s) left out "
                  f"(--skip-damaged; {first}: {why})", file=sys.stderr)
        return evaluate(
            pipeline, dataset, workers=args.workers, tolerance=args.tolerance,
            area_reference=args.area_reference, executor=args.executor,
            progress=not args.no_progress,
            phases=resolve_phases(args.phase_check, set_presets(dataset)),
            isolate=True, timeout_s=args.timeout,
        )

    def _with_interpreter(self, report):
        """``report`` with what ran the command (the competition's interpreter), if made."""
        if self.interpreter is None:
            return report
        return replace(report, interpreter=self.interpreter.to_dict())

    def _stopped(self, stopped) -> int:
        """A run stopped by a signal or a harness failure: say what finished, write the partial
        reports, return the exit status."""
        from arenabench.eval.evaluation import EvaluationInterrupted
        from arenabench.eval.reports import write_reports
        from arenabench.fileio import FolderLockedError
        from arenabench.interrupts import deferred_stops

        args = self.args
        report = self._with_interpreter(stopped.report)
        total = f" of {report.n_total}" if report.n_total is not None else ""
        if isinstance(stopped, EvaluationInterrupted):
            print(f"arenabench eval: interrupted by signal {stopped.signum} after "
                  f"{report.images_done}{total} images; running commands killed",
                  file=sys.stderr)
            code = stopped.exit_code
        else:
            print(f"arenabench eval: error: {stopped}; running commands killed, nothing of it "
                  f"scored ({report.images_done}{total} images finished before)",
                  file=sys.stderr)
            code = ExitCode.HARNESS
        if args.out is None:
            return code
        try:  # even with no image finished: never nothing
            with deferred_stops():  # a second stop does not cut the writing short
                if not self.locked:
                    self.held.enter_context(lock_out(args.out))
                write_reports(report, args.out, formats=args.formats, dataset=self.dataset)
        except FolderLockedError as exc:
            self.parser.fail(str(exc))
            return code
        except OSError as exc:
            self.parser.fail(write_failure(exc, args.out))
            return code
        print(f"  partial reports (\"complete\": false) in {args.out}", file=sys.stderr)
        return code

    def _finished(self, report) -> int:
        """Every image ran: the headline, the reports, the gates and the exit status."""
        from arenabench.eval.reports import write_reports
        from arenabench.eval.reports.summary_rows import first_failure_line, headline
        from arenabench.eval.scoring.thresholds import check_thresholds
        from arenabench.interrupts import Interrupted, deferred_stops

        args = self.args
        report = self._with_interpreter(report)
        written: dict = {}
        try:
            # a stop now cuts no report off; it is raised once they are written and the exit
            # status says it came (arenabench.cli.run)
            with deferred_stops():
                print(headline(report))
                if (first := first_failure_line(report)) is not None:
                    print(f"  {first}")
                if args.out is not None:
                    written = write_reports(report, args.out, formats=args.formats,
                                            dataset=self.dataset)
        except Interrupted:
            pass
        except OSError as exc:  # ENOSPC: one line, no traceback
            self.parser.fail(write_failure(exc, args.out))
            return ExitCode.FAILED
        for fmt, path in written.items():
            print(f"  {fmt:<5} {path}")
        for threshold in self.thresholds:  # every gate applied, passing or not: the CI log
            print(threshold.gate_line(report.summary))
        reasons = check_thresholds(report.summary, self.thresholds)
        if reasons:
            print(f"arenabench eval: FAILED: {'; '.join(reasons)}", file=sys.stderr)
            return ExitCode.FAILED
        return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
