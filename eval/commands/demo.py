"""``arenabench demo``: the project in one short story.

1. (``--example IMAGE``) the pipeline on one real image, in three lines, and the
   ``obstacles.txt`` it writes;
2. a small eyrc set generated (reused when present);
3. the reference pipeline scored on it: the summary table;
4. where ``report.html`` is.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from arenabench.cliopts import (
    CommandParser,
    add_count,
    add_no_progress,
    add_out,
    add_seed,
    add_workers,
    output_problem,
    usage_error,
)
from arenabench.exitcodes import ExitCode
from arenabench.generator.parameters.presets import DEFAULT_PRESET


def build_parser() -> CommandParser:
    """The argument parser of ``arenabench demo``."""
    p = CommandParser(
        prog="arenabench demo",
        description="Generate a small eyrc dataset, evaluate the reference pipeline on it and "
        "write report.json/.csv/.md/.html and junit.xml. With --example, first run the "
        "pipeline on one real image and write OUT/obstacles.txt.",
    )
    add_out(p, default="demo-out")
    add_count(p, default=24, help="images")
    add_seed(p, help="generator seed")
    p.add_argument("--pipeline", default="reference", help="pipeline to score (default reference)")
    add_workers(p)
    p.add_argument("--example", type=Path, default=None, metavar="IMAGE",
                   help="first detect on this image and write OUT/obstacles.txt")
    add_no_progress(p)
    return p


def _example(image_path: Path, out: Path) -> int:
    from arenabench.competition import format_obstacles_txt
    from arenabench.fileio import atomic_write_text
    from arenabench.imageio import ImageLoadError, load_image
    from arenabench.pipeline import detect

    try:
        image = load_image(image_path)
    except ImageLoadError as exc:
        print(f"arenabench demo: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    result = detect(image)
    target = out / "obstacles.txt"
    atomic_write_text(target, format_obstacles_txt(result.marker_ids, result.count,
                                                   result.total_area))
    print(f"1. the reference pipeline on {image_path}:")
    print(f"   markers {list(result.marker_ids)}, {result.count} obstacles, "
          f"area {result.total_area:.1f} px^2 ({result.status})")
    print(f"   competition output: {target}")
    return ExitCode.OK


def main(argv: list[str] | None = None) -> int:
    """Run the demo; returns 0, or 2 on a usage error or when generation fails."""
    args = build_parser().parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    if args.count < 1:
        print(f"arenabench demo: error: --count must be >= 1, got {args.count}", file=sys.stderr)
        return ExitCode.USAGE
    from arenabench.eval.pipelines import make_pipeline

    if problem := output_problem(args.out):
        return usage_error("arenabench demo", problem)
    try:
        make_pipeline(args.pipeline)  # an unknown name or import now, not after rendering
    except ValueError as exc:
        print(f"arenabench demo: error: --pipeline: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    from arenabench.cliopts import lock_out
    from arenabench.fileio import FolderLockedError

    try:
        with lock_out(args.out):  # generate's lock: one run at a time writes into --out
            return _run(args)
    except FolderLockedError as exc:
        print(f"arenabench demo: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE


def _run(args: argparse.Namespace) -> int:
    """The demo's steps, with the --out lock held."""
    step = 1
    if args.example is not None:
        rc = _example(args.example, args.out)
        if rc:
            return rc
        step = 2
    dataset_dir = args.out / f"dataset-{DEFAULT_PRESET}-n{args.count}-s{args.seed}"
    if (dataset_dir / "manifest.jsonl").is_file():
        print(f"{step}. reusing dataset {dataset_dir} ({args.count} {DEFAULT_PRESET} images)")
    else:
        from arenabench.generator.dataset.dataset_writer import GenerateError, generate_dataset
        from arenabench.generator.dataset.gl_check import OffscreenGLError
        from arenabench.generator.model.sampler import SamplingError

        try:
            result = generate_dataset(
                dataset_dir, preset=DEFAULT_PRESET, count=args.count, seed=args.seed,
                workers=args.workers or _cores(),
                progress=not args.no_progress,
            )
        except (GenerateError, SamplingError, ValueError, OffscreenGLError) as exc:
            print(f"arenabench demo: error: generation failed: {exc}", file=sys.stderr)
            return ExitCode.USAGE
        print(f"{step}. generated {result.rendered} eyrc images (seed {args.seed}) into "
              f"{dataset_dir} in {result.seconds:.0f} s")
    step += 1
    from arenabench.eval.datasets.reader import load_dataset
    from arenabench.eval.evaluation import evaluate
    from arenabench.eval.reports import write_reports
    from arenabench.eval.reports.summary_rows import headline, summary_rows

    dataset = load_dataset(dataset_dir)
    report = evaluate(args.pipeline, dataset, workers=args.workers,
                      progress=not args.no_progress)
    report_dir = args.out / f"report-{report.pipeline.replace(':', '_').replace('/', '_')}"
    written = write_reports(report, report_dir, dataset=dataset)
    print(f"{step}. {headline(report)}")
    rows = [(k, v) for k, v in summary_rows(report.summary)
            if not k.startswith("failures:") or v != "0"]
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"   {key:<{width}}  {value}")
    print(f"   report files in {report_dir}/ (report.json, results.csv, report.md, junit.xml)")
    print(_on_path_hint())
    print(f"open the HTML report: {written['html'].resolve()}")  # the story ends here
    return ExitCode.OK


def _on_path_hint() -> str:
    """How to run ``arenabench`` from a shell: the command as this run found it (the
    project's ``.venv/bin/arenabench`` after ``make demo``), and how to put it on PATH."""
    import os
    import shutil

    here = Path(sys.executable).parent
    exe = here / "arenabench"
    if shutil.which("arenabench") == str(exe) or not exe.is_file():
        return "next: arenabench --help (every command; arenabench help COMMAND)"
    shown = os.path.relpath(exe) if not os.path.relpath(exe).startswith("../..") else str(exe)
    activate = Path(shown).parent / "activate"
    return (f"next: {shown} --help (every command), or put arenabench on PATH with: "
            f"source {activate}")


def _cores() -> int:
    from arenabench.workers import usable_cores

    return usable_cores()


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
