"""``arenabench bench``: run :func:`arenabench.eval.bench.items.run_bench`, print a table and write
``bench.json``."""

from __future__ import annotations

import sys
import textwrap

from arenabench.cliopts import (
    CommandParser,
    add_count,
    add_out,
    add_workers,
    output_problem,
    usage_error,
)
from arenabench.eval.bench.items import TARGETS, BenchConfig, BenchResult, target_met
from arenabench.exitcodes import ExitCode

#: (key, label, unit) rows of the table, in the order of docs/benchmark.md.
ROWS: tuple[tuple[str, str, str], ...] = (
    ("generate_disk_ips", "1 generation to disk (image + GT)", "images/s"),
    ("generate_memory_ips", "2 generation in memory (render + GT)", "images/s"),
    ("naive_ips", "3 naive baseline (renderer per image, lit)", "images/s"),
    ("encode_floor_ips", "4 floor: PNG encode + write", "images/s"),
    ("pipeline_ips", "5 reference pipeline from files", "images/s"),
    ("pipeline_eval_ips", "5b the same via the eval runner (start-up in)", "images/s"),
    ("sweep_ips", "6 streaming sweep (render..score)", "scenes/s"),
    ("worker_peak_rss_mb", "7 peak RSS per worker", "MB"),
    ("worker_rss_growth_mb", "7 RSS growth over the renders", "MB"),
    ("sandbox_overhead_ms", "8 bubblewrap cost per external run", "ms"),
    ("script_inprocess_cpu_ms", "9 external Python script per image: in one process", "CPU ms"),
    ("script_cold_cpu_ms", "9 the same, a new process per image (--no-warm)", "CPU ms"),
    ("script_warm_cpu_ms", "9 the same, warm interpreter (default)", "CPU ms"),
    ("script_warm_vs_inprocess", "9 warm / in one process", "x"),
    ("markerless_boxes_ms", "10 reference pipeline, no markers: boxes", "CPU ms"),
    ("markerless_noise_ms", "10 the same: noise", "CPU ms"),
    ("markerless_blank_ms", "10 the same: blank", "CPU ms"),
    ("bigset_load_s_per_10k", "11 big set: load and check, per 10,000 entries", "CPU s"),
    ("bigset_eval_s_per_10k", "11 load, score, report, per 10,000 entries", "CPU s"),
    ("bigset_peak_rss_mb", "11 peak RSS of that run", "MB"),
    ("bigset_rss_mb_per_10k", "11 RSS 10,000 more entries add", "MB"),
    ("twin_example_s", "12 twin of the example, no texture: wall time", "s"),
    ("twin_example_peak_mb", "12 the same: peak RSS", "MB"),
    ("disk_vs_naive", "(1)/(3)", "x"),
    ("disk_vs_floor", "(1)/(4)", "x"),
    ("disk_vs_memory_cpu", "(1)/(2) CPU per image, warm", "x"),
)


#: figure key -> path of its CPU milliseconds per image in ``details``.
CPU_MS: dict[str, tuple[str, ...]] = {
    "generate_disk_ips": ("generate_disk", "cpu_ms_per_image"),
    "generate_memory_ips": ("generate_memory", "cpu_ms_per_image"),
    "naive_ips": ("naive", "cpu_ms_per_image_with_startup"),
    "encode_floor_ips": ("encode_floor", "cpu_ms_per_image"),
    "pipeline_ips": ("pipeline", "cpu_ms_per_image"),
    "pipeline_eval_ips": ("pipeline", "eval_runner", "cpu_ms_per_image"),
    "sweep_ips": ("sweep", "cpu_ms_per_scene"),
}


def _cpu_ms(details: dict, key: str) -> str:
    node: object = details
    for part in CPU_MS.get(key, ()):
        node = node.get(part) if isinstance(node, dict) else None
    return f"{node:.1f}" if isinstance(node, (int, float)) and key in CPU_MS else ""


def format_table(result: BenchResult, *, quick: bool = False) -> str:
    """The plain-text table: figure, unit, target and PASS/MISS (targets of a 2-core machine).

    With ``quick`` (tiny counts, meaningless figures) the targets are shown but not judged.
    """
    targets = {k: (op, v) for k, op, v, _ in TARGETS}
    header = ("measurement", "value", "unit", "CPU ms/img", "target", "")
    lines = [header]
    for key, label, unit in ROWS:
        value = result.figures.get(key)
        shown = "-" if value is None else f"{value:,.1f}" if value >= 10 else f"{value:.2f}"
        if key in targets:
            op, t = targets[key]
            met = target_met(value, op, t)
            met_text = "" if quick else "PASS" if met else "MISS"
        else:
            op, t, met_text = "", None, ""
        target = f"{op} {t:g}" if t is not None else ""
        lines.append((label, shown, unit, _cpu_ms(result.details, key), target, met_text))
    widths = [max(len(row[i]) for row in lines) for i in range(6)]
    out = []
    for n, row in enumerate(lines):
        cells = [row[0].ljust(widths[0]), row[1].rjust(widths[1]), row[2].ljust(widths[2]),
                 row[3].rjust(widths[3]), row[4].ljust(widths[4]), row[5]]
        out.append("  ".join(cells).rstrip())
        if n == 0:
            out.append("-" * len(out[0]))
    m = result.machine
    v = m.get("versions", {})
    out.append("")
    out.append(f"{m.get('cores')} cores, {result.details.get('workers')} workers; "
               f"{v.get('gl_renderer', '?')}; python {v.get('python')}, "
               f"opencv {v.get('opencv')}, numpy {v.get('numpy')}, "
               f"pyrender {v.get('pyrender')}; {result.seconds:.0f} s in all")
    out.append("Targets: the figures a full run should reach on a 2-core machine without a GPU "
               "(docs/benchmark.md). CPU ms/img: CPU time (all processes and threads) "
               "per image.")
    if quick:
        out.append("Quick run: tiny counts, so the figures say only that every item runs; "
                   "no PASS/MISS verdicts (run without --quick for those).")
    load = result.details.get("load_avg_start") or []
    cores = m.get("cores") or 1
    if load and load[0] > 0.5 * cores:
        out.append(f"Note: load average {load[0]:.1f} on {cores} cores when the run started: "
                   "other processes shared the CPUs, so the rates above are lower than on an "
                   "idle machine (CPU ms/img is less affected).")
    return "\n".join(textwrap.fill(line, 100) if len(line) > 100 else line for line in out)


def build_parser() -> CommandParser:
    """The ``arenabench bench`` argument parser."""
    p = CommandParser(
        prog="arenabench bench",
        description="Measure generation and scoring throughput on this machine (a full run "
        "takes about 1.5 minutes on 2 idle cores; --quick takes seconds): prints a table and "
        "writes OUT/bench.json.",
    )
    d = BenchConfig()
    add_out(p, default=".", help="folder of bench.json")
    add_count(p, default=d.count, help="scenes generated / scored")
    add_count(p, "--sweep-count", default=d.sweep_count, help="scenes of the streaming sweep")
    add_count(p, "--naive-count", default=d.naive_count, help="scenes of the naive baseline")
    add_workers(p, help="processes")
    add_count(p, "--rss-renders", default=d.rss_renders,
              help="consecutive renders of the memory check")
    p.add_argument("--quick", action="store_true",
                   help="tiny counts (seconds; checks that everything runs, figures meaningless)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench bench``; returns 0, or 2 on a usage error."""
    args = build_parser().parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    from arenabench.eval.bench.items import run_bench
    from arenabench.fileio import atomic_write_json

    if problem := output_problem(args.out):
        return usage_error("arenabench bench", problem)
    try:
        if args.quick:
            cfg = BenchConfig.quick(workers=args.workers)
        else:
            cfg = BenchConfig(count=args.count, sweep_count=args.sweep_count,
                              naive_count=args.naive_count, rss_renders=args.rss_renders,
                              workers=args.workers)
    except ValueError as exc:
        print(f"arenabench bench: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    from arenabench.generator.dataset.gl_check import OffscreenGLError, require_offscreen_gl

    try:
        require_offscreen_gl()  # every figure renders
    except OffscreenGLError as exc:
        print(f"arenabench bench: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE

    def progress(key: str, seconds: float) -> None:
        print(f"  {key}: {seconds:.1f} s", file=sys.stderr, flush=True)

    result = run_bench(cfg, on_item=progress)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "bench.json"
    data = result.to_json()
    if args.quick:  # figures from tiny counts: no verdicts
        data["quick"] = True
        for target in data["targets"]:
            target["met"] = None
    atomic_write_json(path, data)
    print(format_table(result, quick=args.quick))
    print(f"\nwrote {path}")
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
