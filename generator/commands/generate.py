"""``arenabench generate``: render a dataset of scenes with exact ground truth."""

from __future__ import annotations

import os
import sys

from arenabench.cliopts import (
    CommandParser,
    add_count,
    add_no_progress,
    add_out,
    add_preset,
    add_scheduler,
    add_seed,
    add_set,
    add_workers,
    output_problem,
    usage_error,
)
from arenabench.exitcodes import ExitCode
from arenabench.generator.parameters.presets import DEFAULT_PRESET, preset_names, resolve_preset


def build_parser() -> CommandParser:
    """The ``arenabench generate`` argument parser."""
    p = CommandParser(
        prog="arenabench generate",
        description="Render COUNT scenes of a preset into OUT (images/, gt/, manifest.jsonl, "
                    "dataset.json, coco.json). Re-running with the same arguments resumes or "
                    "does nothing; a larger --count with the same seed, preset and --set "
                    "extends the set (the same files as generating the larger count at once); "
                    "other changes are refused.",
    )
    add_preset(p, resolve=resolve_preset, default=DEFAULT_PRESET, names=preset_names(),
               help="scene preset (a set's dataset.json: the preset it was made from)")
    add_count(p, required=True, help="number of scenes")
    add_seed(p, random=True, help="run seed (for a hidden grading set use 'random': a small "
             "seed lets a submission re-render the set and read its answers)")
    add_out(p, required=True, help="output directory")
    add_set(p, help="override a preset parameter, e.g. camera.tilt_deg=10:30 or "
                    "obstacles.count=3")
    add_workers(p, help="rendering processes; the output does not depend on it")
    add_scheduler(p, help="render on this Dask cluster instead (files are written here, the "
                  "same bytes as a local run; see docs/scale-out.md)")
    add_no_progress(p)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench generate``; returns 0 on success, 2 on a usage or argument error,
    130 / 143 when stopped by SIGINT / SIGTERM (what finished is kept; re-running resumes)."""
    args = build_parser().parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, its line printed)
        return args
    from arenabench.generator.dataset.dataset_writer import GenerateError, generate_dataset
    from arenabench.generator.dataset.gl_check import OffscreenGLError
    from arenabench.generator.model.sampler import SamplingError
    from arenabench.generator.parameters.param_values import parse_overrides
    from arenabench.interrupts import Interrupted, exit_code, stop_on_signals
    from arenabench.seeds import random_seed

    if problem := output_problem(args.out):
        return usage_error("arenabench generate", problem)
    seed = random_seed() if args.seed == "random" else args.seed
    if args.seed == "random":
        print(f"arenabench generate: seed {seed} (random; recorded in "
              f"{os.path.join(args.out, 'dataset.json')}, which no submission may see)",
              flush=True)
    with stop_on_signals():
        try:
            overrides = parse_overrides(args.overrides)
            result = generate_dataset(
                args.out, preset=args.preset, count=args.count, seed=seed,
                overrides=overrides, workers=args.workers or 1,  # None: --scheduler
                scheduler=args.scheduler,
                progress=not args.no_progress,
            )
        except (GenerateError, SamplingError, ValueError, OffscreenGLError) as exc:
            print(f"arenabench generate: error: {exc}", file=sys.stderr)
            return ExitCode.USAGE
        except Interrupted as exc:  # before or after the rendering loop
            print(f"arenabench generate: {exc}; run the same command again to resume",
                  file=sys.stderr)
            return exc.exit_code
        except OSError as exc:  # e.g. the scheduler cannot be reached
            print(f"arenabench generate: error: {type(exc).__name__}: {exc}", file=sys.stderr)
            return ExitCode.USAGE
    if result.interrupted is not None:
        print(f"arenabench generate: {result.summary()}", file=sys.stderr)
        return exit_code(result.interrupted)
    print(result.summary())
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
