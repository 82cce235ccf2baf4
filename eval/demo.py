"""``arenabench demo``: generate a small eyrc set (reused when present), score the reference
pipeline on it, write the reports and say where ``report.html`` is."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``arenabench demo``."""
    p = argparse.ArgumentParser(
        prog="arenabench demo",
        description="Generate a small eyrc dataset, evaluate the reference pipeline on it and "
        "write report.json/.csv/.md/.html and junit.xml.",
    )
    p.add_argument("--out", type=Path, default=Path("demo-out"), help="output folder")
    p.add_argument("--count", type=int, default=24, help="images (default 24)")
    p.add_argument("--seed", type=int, default=0, help="generator seed (default 0)")
    p.add_argument("--pipeline", default="reference", help="pipeline to score (default reference)")
    p.add_argument("--workers", type=int, default=None, help="parallel workers (default: cores)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the demo; returns 0, or 2 on a usage error or when generation fails."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.count < 1:
        print(f"arenabench demo: error: --count must be >= 1, got {args.count}", file=sys.stderr)
        return 2
    from arenabench.fileio import OutputPathError, check_output_dir

    try:
        check_output_dir(args.out)
    except OutputPathError as exc:
        print(f"arenabench demo: error: --out {args.out}: {exc}", file=sys.stderr)
        return 2
    dataset_dir = args.out / f"dataset-eyrc-n{args.count}-s{args.seed}"
    if (dataset_dir / "manifest.jsonl").is_file():
        print(f"reusing dataset {dataset_dir}")
    else:
        from arenabench.generator.cli import main as generate_main

        print(f"generating {args.count} eyrc images into {dataset_dir} ...")
        rc = generate_main(
            [
                "--preset",
                "eyrc",
                "--count",
                str(args.count),
                "--seed",
                str(args.seed),
                "--out",
                str(dataset_dir),
                "--no-progress",
            ]
        )
        if rc != 0:
            print(f"arenabench demo: error: generation failed (exit status {rc})", file=sys.stderr)
            return 2
    from .dataset import load_dataset
    from .reports import write_reports
    from .reports.summary_rows import headline, summary_rows
    from .runner import evaluate

    dataset = load_dataset(dataset_dir)
    report = evaluate(args.pipeline, dataset, workers=args.workers, progress=True)
    report_dir = args.out / f"report-{report.pipeline.replace(':', '_').replace('/', '_')}"
    written = write_reports(report, report_dir, dataset=dataset)
    print()
    width = max(len(k) for k, _ in summary_rows(report.summary))
    for key, value in summary_rows(report.summary):
        if not key.startswith("failures:") or value != "0":
            print(f"  {key:<{width}}  {value}")
    print()
    print(headline(report))
    print(f"report files in {report_dir}/ (report.json, results.csv, report.md, junit.xml)")
    print(f"open the HTML report: {written['html'].resolve()}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
