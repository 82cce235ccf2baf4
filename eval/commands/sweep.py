"""``arenabench sweep``: vary preset parameters, render and score every point in memory, find
each parameter's breakdown point.

Exit status: 0 done; 2 usage error (bad --vary, unknown parameter, bad options, no cluster);
130 / 143 stopped by SIGINT / SIGTERM (what finished is written, ``"complete": false``).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from arenabench.cliopts import (
    CommandParser,
    add_area_reference,
    add_cmd,
    add_no_progress,
    add_out,
    add_output_mode,
    add_preset,
    add_run_options,
    add_scheduler,
    add_seed,
    add_set,
    add_tolerance,
    add_workers,
    lock_out,
    output_problem,
    usage_error,
    write_failure,
)
from arenabench.eval.phase_check import add_phase_check_argument, resolve_phases
from arenabench.eval.pipelines import BUILTIN_PIPELINES
from arenabench.eval.runs import (
    OUTPUT_MODES,
    resolve_competition_python,
    run_settings_from_args,
)
from arenabench.exitcodes import ExitCode
from arenabench.interrupts import Interrupted, stop_on_signals

EPILOG = """\
examples:
  arenabench sweep --preset eyrc --vary camera.tilt_deg=0:40:5 --per-point 50 \\
      --pipeline reference --out out/tilt
  arenabench sweep --vary camera.tilt_deg=0:40:10 --vary lighting.intensity=0.4,0.2,0 \\
      --pipeline seed --pipeline reference --cmd "python3 map.py --image {image}" --out out/grid
  arenabench sweep --vary camera.tilt_deg=0:40 --vary camera.altitude_m=8:14 --random 200 \\
      --per-point 5 --pipeline reference --out out/random
  arenabench sweep ... --scheduler tcp://10.0.0.5:8786      # run on a Dask cluster

--vary KEY=SPEC overrides preset parameter KEY (any name of 'arenabench presets --params'):
  a:b:step  a, a+step, ... up to b (step may be negative: jpeg.quality=95:15:-20)
  a:b       5 evenly spaced values in a grid; the continuous range with --random
  v1,v2,..  these values, in this order (words for text parameters; ';' separates colours)
The first value is the easy end: a parameter's breakdown point is the furthest value, scanning
from it, whose pass-rate lower 95 % Wilson bound is >= --threshold (marginal over the other
parameters unless --breakdown-mode axis). Scene i is the same base scene at every point
(common random numbers) unless --independent-scenes.

Several --vary make a grid (first varies slowest); --random N draws N points instead.
Pipelines (--pipeline and --cmd, repeatable) run on the same images. In --cmd, {python} is the
Python running arenabench and {competition_python} the competition's environment (numpy and
OpenCV at the competition's versions, made once into the cache; see 'arenabench check
--help'). Nothing is written to disk per image unless --keep-images or --keep-failures (--cmd
pipelines read a temporary file).

outputs in --out: sweep.json (schema arenabench.sweep/1), sweep.csv, results.jsonl,
plots/*.png, sweep.html.
"""


class _PipelineAction(argparse.Action):
    """Collects --pipeline and --cmd in the order given."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = list(getattr(namespace, self.dest) or [])
        items.append(("cmd" if option_string == "--cmd" else "pipeline", values))
        setattr(namespace, self.dest, items)


def build_parser() -> CommandParser:
    """The argument parser of ``arenabench sweep``."""
    from arenabench.generator.parameters.presets import DEFAULT_PRESET, preset_names, resolve_preset

    p = CommandParser(
        prog="arenabench sweep",
        description="Robustness sweep: vary preset parameters over a grid (or at random), "
                    "render and score every point in memory, report breakdown points.",
        epilog=EPILOG,
    )
    add_preset(p, resolve=resolve_preset, default=DEFAULT_PRESET, names=preset_names())
    p.add_argument("--vary", action="append", default=[], metavar="KEY=SPEC",
                   help="parameter to vary (repeatable; see below)")
    add_set(p, help="fixed override at every point, as for 'arenabench generate'")
    p.add_argument("--random", type=int, default=None, metavar="N",
                   help="draw N random points from the ranges instead of the grid")
    p.add_argument("--per-point", type=int, default=50, help="scenes per point (default 50)")
    add_seed(p, help="sweep seed")
    p.add_argument("--independent-scenes", action="store_true",
                   help="different scenes at every point (default: the same base scenes)")
    p.add_argument("--pipeline", dest="pipes", action=_PipelineAction, metavar="NAME",
                   help=f"built-in ({', '.join(BUILTIN_PIPELINES)}) or 'pkg.module:function' "
                        "(repeatable; modules are looked for in the current folder first)")
    add_cmd(p, dest="pipes", action=_PipelineAction,
            help="external command, e.g. 'python3 map.py --image {image}' (repeatable)")
    add_output_mode(p, OUTPUT_MODES)
    add_tolerance(p)
    add_area_reference(p)
    p.add_argument("--threshold", type=float, default=0.9,
                   help="breakdown threshold on the pass rate's lower 95 %% bound (default 0.9)")
    p.add_argument("--breakdown-mode", choices=("marginal", "axis"), default="marginal",
                   help="pool the other parameters (marginal, default) or hold them at their "
                        "first value (axis; grid only)")
    keep = p.add_mutually_exclusive_group()
    keep.add_argument("--keep-images", action="store_true",
                      help="write every rendered image and its GT to OUT/images, OUT/gt")
    keep.add_argument("--keep-failures", action="store_true",
                      help="write only images some pipeline failed on")
    add_out(p, required=True)
    add_workers(p, help="local processes (1 = in this process)")
    add_scheduler(p, help="run on an existing Dask distributed cluster")
    p.add_argument("--no-plots", action="store_true", help="skip plots and sweep.html")
    add_no_progress(p)
    add_phase_check_argument(p)
    add_run_options(p)
    return p


def _error(message: str) -> int:
    return usage_error("arenabench sweep", message)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``arenabench sweep``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    from arenabench.eval.sweep.outputs import FILES

    if problem := output_problem(args.out, own=FILES.values(), what="'arenabench sweep' output"):
        return _error(problem)
    if not args.vary:
        return _error("give at least one --vary KEY=SPEC")
    if not args.pipes:
        return _error("give --pipeline NAME|pkg.module:function and/or --cmd TEMPLATE")
    try:
        spec = _spec(args)
    except ValueError as exc:
        return _error(str(exc))
    from arenabench.eval.commands.poor_fit import say_poor_fits

    say_poor_fits("arenabench sweep", [args.preset])
    if args.scheduler is None:  # renders here: OpenGL must work before anything is written
        from arenabench.generator.dataset.gl_check import OffscreenGLError, require_offscreen_gl

        try:
            require_offscreen_gl()
        except OffscreenGLError as exc:
            return _error(str(exc))
    return _run(args, spec)


def _spec(args: argparse.Namespace):
    """The sweep the options describe, every pipeline tried first (one line for what fails:
    an import error, a missing executable or script)."""
    from arenabench.eval.sweep.grid import parse_varies
    from arenabench.eval.sweep.records import PipelineSpec, SweepSpec
    from arenabench.generator.parameters.param_values import parse_overrides

    axes = parse_varies(args.vary)
    overrides = parse_overrides(args.overrides)
    clash = sorted(set(overrides) & {a.key for a in axes})
    if clash:
        raise ValueError(f"--set {clash[0]}: also given with --vary")
    settings = run_settings_from_args(args)
    pipelines = tuple(PipelineSpec(kind, value, settings=settings, output=args.output)
                      for kind, value in args.pipes)
    for p in pipelines:
        _try_pipeline(p, timeout_s=settings.limits.timeout_s)
    return SweepSpec(
        preset=args.preset, axes=axes, pipelines=pipelines, per_point=args.per_point,
        seed=args.seed, random=args.random, overrides=overrides,
        tolerance=args.tolerance, area_reference=args.area_reference,
        threshold=args.threshold, breakdown_mode=args.breakdown_mode,
        keep="all" if args.keep_images else "failures" if args.keep_failures else "none",
        independent_scenes=args.independent_scenes,
        phases=resolve_phases(args.phase_check, [args.preset]),
    )


def _try_pipeline(p, *, timeout_s: float) -> None:
    """Raise ``ValueError`` with one line when pipeline ``p`` cannot run at all."""
    from arenabench.eval.runs import check_command, missing_script_problem, trial_pipeline

    if p.kind == "cmd" and (problem := missing_script_problem(p.value, base_dir=p.base_dir)):
        raise ValueError(f"--cmd {p.value!r}: {problem}")
    if p.kind == "cmd":  # missing executables now, as one line
        check_command(p.value, settings=p.settings, output=p.output, base_dir=p.base_dir)
    elif ":" in p.value:  # import errors now, as one line
        p.build().close()
    if p.kind == "pipeline" and ":" in p.value:
        trial_pipeline(p.value, timeout_s=timeout_s)


def _run(args: argparse.Namespace, spec) -> int:
    """Make the competition's interpreter where a command names it, take the lock, run the
    sweep and write its files; the exit status."""
    from contextlib import ExitStack

    from arenabench.eval.scoring.results import HarnessError
    from arenabench.eval.sweep.execution import run_sweep
    from arenabench.eval.sweep.outputs import KeptImageWriter, write_sweep
    from arenabench.fileio import FolderLockedError
    from arenabench.generator.model.sampler import SamplingError

    writer = KeptImageWriter(args.out)
    with stop_on_signals() as stop, ExitStack() as held:
        try:
            templates, _ = resolve_competition_python(
                [p.value if p.kind == "cmd" else "" for p in spec.pipelines],
                progress=not args.no_progress, prog="arenabench sweep")
            spec = replace(spec, pipelines=tuple(
                replace(p, value=t) if p.kind == "cmd" else p
                for p, t in zip(spec.pipelines, templates, strict=True)))
            held.enter_context(lock_out(args.out))  # generate's lock: one run per --out
            result = run_sweep(spec, workers=args.workers, scheduler=args.scheduler,
                               progress=not args.no_progress, on_output=writer)
        except (ValueError, SamplingError, FolderLockedError) as exc:
            return _error(str(exc))
        except OSError as exc:  # e.g. the scheduler cannot be reached
            return _error(f"{type(exc).__name__}: {exc}")
        except HarnessError as exc:  # the harness's own failure: nothing of it is scored
            print(f"arenabench sweep: error: the harness could not run an image: {exc}; "
                  "nothing written", file=sys.stderr)
            return ExitCode.HARNESS
        except Interrupted as exc:  # before the first task or after the last one
            print(f"arenabench sweep: {exc}; nothing written", file=sys.stderr)
            return exc.exit_code
        try:
            with stop.deferred():  # a signal now waits until the outputs are written
                written = write_sweep(result, args.out, plots=not args.no_plots)
        except Interrupted:
            pass
        except OSError as exc:  # ENOSPC: one line, no traceback
            print(f"arenabench sweep: error: {write_failure(exc, args.out)}", file=sys.stderr)
            return stop.exit_code or 1
    return _said(args, spec, result, written, writer, stop)


def _said(args: argparse.Namespace, spec, result, written, writer, stop) -> int:
    """The sweep's closing lines and exit status."""
    run = result.run
    if not result.complete:
        print(f"arenabench sweep: interrupted by {run['interrupted']}: {run['samples_done']} "
              f"of {run['samples']} samples done ({run['points_done']} of "
              f"{len(result.points)} points complete); partial results written to "
              f"{written['json'].parent}/ (\"complete\": false)", file=sys.stderr)
        return stop.exit_code or 130
    print(f"sweep: {len(result.points)} points x {spec.per_point} scenes x "
          f"{len(spec.pipelines)} pipeline(s) in {run['seconds']:.1f} s "
          f"({run['samples_per_s']} samples/s, {run['skipped']} skipped)")
    from arenabench.eval.sweep.breakdown import breakdown_texts

    for name, texts in breakdown_texts(result).items():
        print(f"  breakdown {name}: " + ", ".join(f"{k}={v}" for k, v in texts.items()))
    print(f"  wrote {written['json'].parent}/ (sweep.json, sweep.csv, results.jsonl"
          f"{', plots/, sweep.html' if not args.no_plots else ''}"
          f"{f', {writer.written} images' if writer.written else ''})")
    return stop.exit_code or 0  # a signal during the final writes: they were completed


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
