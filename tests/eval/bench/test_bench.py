"""``arenabench bench --quick`` through the real command (a subprocess): every figure is there.

Timings are not asserted (speed belongs to the benchmark itself); the test keeps the
benchmark from rotting: every measurement runs, on real renders, real files and the real
pipeline, and bench.json holds every key docs/benchmark.md names.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from arenabench.eval.bench.items import FIGURE_KEYS, BenchConfig
from arenabench.eval.commands.bench import main

DOCUMENTED_KEYS = (
    "generate_disk_ips", "generate_memory_ips", "naive_ips", "encode_floor_ips",
    "pipeline_ips", "sweep_ips", "worker_peak_rss_mb", "worker_rss_growth_mb",
)  # fmt: skip


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory) -> tuple[subprocess.CompletedProcess, dict]:
    out = tmp_path_factory.mktemp("bench")
    proc = subprocess.run(
        [sys.executable, "-m", "arenabench", "bench", "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc, json.loads((out / "bench.json").read_text())


@pytest.mark.integration
def test_bench_json_holds_every_figure(quick_run):
    _, data = quick_run
    for key in (*DOCUMENTED_KEYS, *FIGURE_KEYS):
        assert key in data, key
        assert isinstance(data[key], float) and math.isfinite(data[key]), key
        if key in ("worker_rss_growth_mb", "sandbox_overhead_ms"):
            assert data[key] >= 0.0
        else:
            assert data[key] > 0.0, key
    assert data["cores"] >= 1
    for name in ("python", "numpy", "opencv", "pyrender", "gl_renderer"):
        assert data["versions"][name], name
    assert data["disk_vs_naive"] == pytest.approx(data["generate_disk_ips"] / data["naive_ips"])
    assert data["disk_vs_floor"] == pytest.approx(
        data["generate_disk_ips"] / data["encode_floor_ips"])
    assert data["details"]["rss"]["renders"] == BenchConfig.quick().rss_renders
    assert {t["key"] for t in data["targets"]} >= {"generate_disk_ips", "pipeline_ips",
                                                    "sweep_ips", "worker_peak_rss_mb"}
    # the pipeline ran on the generated files and mostly passed (real outcome, not timing)
    assert data["details"]["pipeline"]["pass_rate"] >= 0.5
    rates = data["details"]["sweep"]["pass_rate"]
    assert len(rates) == 4 and sum(rates.values()) / len(rates) >= 0.5


@pytest.mark.integration
def test_bench_prints_every_row(quick_run):
    proc, _ = quick_run
    for label in ("generation to disk", "generation in memory", "naive baseline", "floor",
                  "reference pipeline", "streaming sweep", "peak RSS", "RSS growth",
                  "(1)/(3)", "(1)/(4)", "llvmpipe" if "llvmpipe" in proc.stdout else "cores"):
        assert label in proc.stdout, label
    # quick mode: targets shown, no verdicts, described in the words of docs/benchmark.md
    assert not any(line.rstrip().endswith(("PASS", "MISS")) for line in proc.stdout.splitlines())
    assert "no PASS/MISS verdicts" in proc.stdout and "issue" not in proc.stdout
    assert "docs/benchmark.md" in proc.stdout


@pytest.mark.integration
def test_quick_bench_json_has_no_verdicts(quick_run):
    _, data = quick_run
    assert data["quick"] is True
    assert data["targets"] and all(t["met"] is None for t in data["targets"])


def test_full_table_judges_targets():
    from arenabench.eval.bench.items import TARGETS, BenchResult
    from arenabench.eval.commands.bench import format_table

    figures = {k: (v * 2 if op == ">=" else v / 2) for k, op, v, _ in TARGETS}
    text = format_table(BenchResult(figures=figures, details={}, machine={"cores": 2}))
    assert text.count("PASS") == len(TARGETS) and "MISS" not in text


@pytest.mark.parametrize("argv, fragment", [
    (["--count", "0"], "argument --count: must be an integer in [1, 1000000]"),
    (["--workers", "0"], "argument --workers: must be an integer in [1, 256]"),
    (["--rss-renders", "-3"], "argument --rss-renders: must be an integer in [1, 1000000]"),
])
def test_usage_errors_exit_2(argv, fragment, capsys, tmp_path):
    assert main([*argv, "--out", str(tmp_path)]) == 2
    assert fragment in capsys.readouterr().err
    assert not (tmp_path / "bench.json").exists()


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="naive_count"):
        BenchConfig(naive_count=0)
    with pytest.raises(ValueError, match="workers"):
        BenchConfig(workers=True)


def test_the_twin_item_without_its_image_has_no_figures_and_says_why(tmp_path):
    from arenabench.eval.bench.twin_cost import twin_cost

    figures, details = twin_cost(tmp_path, image=tmp_path / "absent.jpg")
    assert figures == {} and "absent.jpg not found" in details["skipped"]
