"""``arenabench bench`` item 11, big sets: loading a synthetic set
(:func:`arenabench.eval.datasets.bigset.write_big_set`: tiny images, real GT files) and scoring it
with a do-nothing pipeline, per 10,000 manifest entries.

Each measurement runs in a fresh process (:func:`measure_in_child`), which loads the set
(:func:`arenabench.eval.datasets.reader.load_dataset`, every file checked), evaluates
:func:`~arenabench.eval.datasets.bigset.fixed_answer` on it (2 threads) and writes ``report.json``,
``results.csv`` and ``junit.xml``, and reports the wall and CPU seconds of each step and its
peak RSS (the figures are CPU seconds: the machine may be shared).
Two sizes, ``entries`` and half of it, give the memory a set adds per 10,000 entries.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

#: The child's program: argv = dataset folder, report folder; prints one JSON line.
_CHILD = """
import resource, sys, time
from arenabench.eval.datasets.bigset import fixed_answer
from arenabench.fileio import dumps_json_line
from arenabench.eval.datasets.reader import load_dataset
from arenabench.eval.reports import write_reports
from arenabench.eval.evaluation import evaluate
load_dataset(sys.argv[1], limit=1)  # imports and caches warm, as in a long run
t0, c0 = time.perf_counter(), time.process_time()
data = load_dataset(sys.argv[1])
t1, c1 = time.perf_counter(), time.process_time()
report = evaluate(fixed_answer, data, workers=2)
t2, c2 = time.perf_counter(), time.process_time()
write_reports(report, sys.argv[2], formats=("json", "csv", "junit"))
t3, c3 = time.perf_counter(), time.process_time()
# VmHWM: this program's own peak (ru_maxrss keeps the parent's size at the fork)
try:
    with open("/proc/self/status") as fh:
        peak_mb = next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:")) / 1024
except (OSError, StopIteration):
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(dumps_json_line({"entries": len(data), "load_s": t1 - t0, "eval_s": t2 - t1,
                  "reports_s": t3 - t2, "load_cpu_s": c1 - c0, "eval_cpu_s": c2 - c1,
                  "reports_cpu_s": c3 - c2, "n_passed": report.summary.n_passed,
                  "peak_rss_mb": peak_mb}), end="")
"""


def measure_in_child(dataset: Path, reports: Path) -> dict[str, Any]:
    """Load, evaluate and report ``dataset`` in a fresh process; its timings and peak RSS."""
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(dataset), str(reports)],
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"bench: the big-set run failed: {proc.stderr.strip()[-500:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def big_set_figures(entries: int, scratch: Path) -> tuple[dict[str, float], dict[str, Any]]:
    """Item 11's figures for a set of ``entries`` (and one of half as many).

    Returns
    -------
    figures : dict
        ``bigset_load_s_per_10k`` (CPU seconds to load and check 10,000 entries: on a
        shared machine the CPU time, not the wall time, is the figure; one thread, so on an
        idle one they are about the same), ``bigset_eval_s_per_10k`` (CPU seconds to load,
        score and write the three report files),
        ``bigset_peak_rss_mb`` (peak RSS of the run of ``entries``) and
        ``bigset_rss_mb_per_10k`` (what 10,000 more entries add to the peak RSS; 0 when the
        larger set did not need more).
    details : dict
        Both runs' measurements.
    """
    from arenabench.eval.datasets.bigset import write_big_set

    runs = []
    for n in (max(1, entries // 2), entries):
        t0 = time.perf_counter()
        big = write_big_set(scratch / f"bigset-{n}", n)
        built = time.perf_counter() - t0
        run = measure_in_child(big.root, scratch / f"bigset-{n}-reports")
        if run["n_passed"] != big.passes:
            raise RuntimeError(f"bench: the big set scored {run['n_passed']} passes, "
                               f"expected {big.passes}")
        runs.append({**run, "build_s": built})
    half, full = runs
    per10k = 10_000 / entries
    figures = {
        "bigset_load_s_per_10k": full["load_cpu_s"] * per10k,
        "bigset_eval_s_per_10k": (full["load_cpu_s"] + full["eval_cpu_s"]
                                  + full["reports_cpu_s"]) * per10k,
        "bigset_peak_rss_mb": full["peak_rss_mb"],
        "bigset_rss_mb_per_10k": max(0.0, (full["peak_rss_mb"] - half["peak_rss_mb"])
                                     * 10_000 / (full["entries"] - half["entries"] or 1)),
    }
    return figures, {"entries": entries, "runs": runs}
