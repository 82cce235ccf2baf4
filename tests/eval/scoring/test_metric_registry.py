"""The metric registry (eval/metric_registry.py): every metric is complete, every consumer
(--fail-under, --compare, --fail-on-regression, summary rows, leaderboard, docs) derives from
it, and the summary rows read as before the registry existed."""

from __future__ import annotations

import csv
import io
import re
from dataclasses import replace

import pytest
from paths import ROOT

from arenabench.eval.grade.leaderboard import LEADERBOARD_METRICS, LeaderboardRow
from arenabench.eval.reports.summary_rows import phase_rows, summary_rows
from arenabench.eval.scoring.compare import (
    COMPARED_METRICS,
    compare,
    parse_regression_limits,
    regressions,
)
from arenabench.eval.scoring.metric_registry import (
    DIRECTIONS,
    GATED,
    KINDS,
    METRIC,
    METRICS,
    Metric,
    column_metrics,
    lookup,
    metrics_table_markdown,
)
from arenabench.eval.scoring.results import CATEGORIES, STATUSES, Report, Summary
from arenabench.eval.scoring.thresholds import check_thresholds, parse_thresholds
from arenabench.eval.sweep.grid import parse_varies
from arenabench.eval.sweep.outputs import sweep_csv
from arenabench.eval.sweep.records import PipelineSpec, PointSummary, SweepResult, SweepSpec

DOCS = ROOT / "docs"

#: A summary as written by a real run (the toy arena pipeline on 6 toy images, tolerance 0.005).
SUMMARY = {
    "area_rel_err": {"max": 0.022007528207434207, "median": 0.017322269618188703,
                     "p95": 0.021565658654375795},
    "area_rel_err_signed": {"max": -0.013512589600040701, "mean": -0.01754116426096308,
                            "median": -0.017322269618188703, "min": -0.022007528207434207,
                            "p5": -0.021565658654375795, "p95": -0.01382312236743449},
    "count_exact_rate": 1.0, "count_mae": 0.0,
    "failures": {"area_off": 4, "bad_output": 0, "crash": 0, "limit": 0,
                 "markers_not_found": 0, "timeout": 0, "wrong_count": 0},
    "latency_ms": {"median": 122.92527700037681, "p95": 257.0319412500339},
    "marker_id_accuracy": 1.0, "n": 6, "n_passed": 2, "pass_rate": 0.3333333333333333,
    "pass_rate_ci95": [0.09677141110578041, 0.700006684861608],
    "phase_check": {"robust": 3, "phase_dependent": 1, "phases": 4},
    "phase_dependent_failure_rate": 1 / 6, "robust_failure_rate": 0.5,
}


def _summary(**changes: object) -> Summary:
    return Summary.from_dict({**SUMMARY, **changes})


def _report(summary: Summary) -> Report:
    return Report(pipeline="p", dataset="d", area_reference="visible", tolerance=0.05,
                  summary=summary, images=())


def test_every_metric_is_complete_and_names_a_summary_value():
    assert len({m.name for m in METRICS}) == len(METRICS)
    d = _summary().to_dict()
    for m in METRICS:
        assert m.label and m.row and m.direction in DIRECTIONS and m.kind in KINDS, m
        assert isinstance(lookup(d, m.name), (int, float)), m.name
    # every summary value that is a number is registered (n and n_passed are sizes, not metrics)
    def leaves(node: object, path: str) -> list[str]:
        if isinstance(node, dict):
            return [p for k, v in node.items() for p in leaves(v, f"{path}.{k}" if path else k)]
        if isinstance(node, list):
            return [p for i, v in enumerate(node) for p in leaves(v, f"{path}.{i}")]
        return [path] if isinstance(node, (int, float)) else []
    skipped = {"n", "n_passed", "area_rel_err_signed.mean"} | {
        p for p in leaves(d, "") if p.startswith("phase_check.")}
    assert set(leaves(d, "")) - skipped == {m.name for m in METRICS}


def test_categories_derive_from_statuses():
    failing = [s for s in STATUSES if s != "ok"]
    assert [c for c in CATEGORIES if c in STATUSES] == failing
    assert set(CATEGORIES) - set(STATUSES) == {"wrong_count", "area_off"}
    assert {m.name for m in METRICS if m.group == "failures"} == {
        f"failures.{c}" for c in CATEGORIES}


@pytest.mark.parametrize(("spec", "needle"), [
    ("pass_rate=95", "--fail-under pass_rate=95: must be a fraction in [0, 1]; 95 % is 0.95"),
    ("pass_rate=2", "--fail-under pass_rate=2: must be a fraction in [0, 1]; 2 % is 0.02"),
    ("pass_rate=-1", "--fail-under pass_rate=-1: must be a fraction in [0, 1]"),
    ("count_exact_rate=1.5", "must be a fraction in [0, 1]"),
    ("area_rel_err.p95=-1", "--fail-under area_rel_err.p95=-1: must be a finite number >= 0"),
    ("failures.crash=-1", "--fail-under failures.crash=-1: must be a finite number >= 0"),
    ("latency_ms.p95=inf", "latency_ms.p95=inf: not a number"),
    ("pass_rate=0.9,pass_rate=0.95", "pass_rate given twice ('pass_rate=0.9' and "
                                     "'pass_rate=0.95')"),
    ("pass_rate=٠.٩", "not a number"),
    ("pass_rate=0_9", "not a number"),
])
def test_fail_under_refuses_a_limit_no_metric_can_reach(spec, needle):
    with pytest.raises(ValueError) as err:
        parse_thresholds([spec])
    assert needle in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_every_metric_declares_the_range_of_its_limits():
    from arenabench.eval.scoring.metric_registry import KIND_RANGES

    assert set(KIND_RANGES) == set(KINDS)
    for m in GATED:  # a limit at either end of the range is accepted
        lo, hi = m.limits
        assert parse_thresholds([f"{m.name}={lo}"])[0].value == lo
        if hi != float("inf"):
            assert parse_thresholds([f"{m.name}={hi}"])[0].value == hi
    assert parse_thresholds(["pass_rate=0.95", "area_rel_err.p95=0.05"])[1].value == 0.05
    with pytest.raises(ValueError, match=r"area_rel_err\.p95 given twice"):
        parse_thresholds(["area_rel_err.p95=0.05", "area_rel_err.p95=0.1"])


def test_fail_on_regression_deltas_keep_the_same_ranges():
    from arenabench.eval.scoring.compare import parse_regression_limits

    assert parse_regression_limits(["pass_rate=0.02,area_rel_err.p95=3"]) == {
        "pass_rate": 0.02, "area_rel_err.p95": 3.0}
    for spec, needle in (("pass_rate=2", "must be a fraction in [0, 1]; 2 % is 0.02"),
                         ("count_mae=-1", "must be a finite number >= 0"),
                         ("pass_rate=0.1,pass_rate=0.2", "pass_rate given twice")):
        with pytest.raises(ValueError, match=re.escape(needle)):
            parse_regression_limits([spec])


def test_fail_under_takes_names_and_directions_from_the_registry():
    gated = [m.name for m in GATED]
    parsed = parse_thresholds([",".join(f"{n}=0.5" for n in gated)])
    assert [t.metric for t in parsed] == gated
    assert all(t.minimum == (METRIC[t.metric].direction == "higher") for t in parsed)
    with pytest.raises(ValueError, match="did you mean 'pass_rate'"):
        parse_thresholds(["pass_rat=0.5"])
    s = _summary()
    assert check_thresholds(s, parse_thresholds(["pass_rate_ci95.0=0.1"])) == [
        "pass_rate_ci95.0 0.09677 < 0.1"]
    assert check_thresholds(s, parse_thresholds(["failures.area_off=3"])) == [
        "failures.area_off 4 > 3 (maximum)"]
    # a signed error is judged on its magnitude
    assert check_thresholds(s, parse_thresholds(["area_rel_err_signed.min=0.02"])) == [
        "|area_rel_err_signed.min| 0.02201 > 0.02 (maximum)"]
    assert check_thresholds(s, parse_thresholds(["area_rel_err_signed.max=0.02"])) == []


def test_compare_and_regressions_follow_the_registry_directions():
    assert COMPARED_METRICS == GATED
    old = _report(_summary())
    new = _report(_summary(pass_rate=0.5, count_mae=0.5, robust_failure_rate=0.25,
                           area_rel_err_signed={**SUMMARY["area_rel_err_signed"],
                                                "median": 0.01}))
    cmp = compare(old, new)
    assert [name for name, *_ in cmp.metrics] == [m.name for m in GATED]
    limits = parse_regression_limits([",".join(f"{m.name}=0" for m in GATED)])
    reasons = regressions(cmp, limits)
    # pass rate (higher) and robust failures (lower) got better, count MAE (lower) worse; the
    # signed median went from -0.0173 to +0.01: nearer zero, so better
    assert [r.split()[0] for r in reasons] == ["count_mae"]
    with pytest.raises(ValueError, match=re.escape("unknown metric 'pass_rate_ci95.1'")):
        parse_regression_limits(["pass_rate_ci95.1=0"])


def test_summary_rows_read_as_before_the_registry():
    s = _summary(phase_check=None, robust_failure_rate=None, phase_dependent_failure_rate=None)
    assert summary_rows(s) == [
        ("images", "6"), ("pass rate", "33.3 % (2/6)"),
        ("pass rate 95 % CI (Wilson)", "9.7 % - 70.0 %"), ("count exact rate", "100.0 %"),
        ("count MAE", "0"), ("|area rel err| median / p95 / max", "0.01732 / 0.02157 / 0.02201"),
        ("signed area rel err median / p5 / p95", "-0.01732 / -0.02157 / -0.01382"),
        ("signed area rel err min / max", "-0.02201 / -0.01351"),
        ("marker id accuracy", "100.0 %"), ("latency ms median / p95", "123 / 257"),
        *((f"failures: {c}", "4" if c == "area_off" else "0") for c in CATEGORIES),
    ]
    rows = phase_rows(_summary())
    assert rows[:2] == [("robust failures (fail at every phase)", "50.0 % (3/6)"),
                        ("phase-dependent failures", "16.7 % (1/6; 4 phases per failure)")]
    # every registered metric's row is shown
    shown = {label for label, _ in summary_rows(_summary())}
    assert {m.row for m in METRICS} <= shown


def test_leaderboard_metric_keys_come_from_the_registry():
    row = LeaderboardRow(team="t", summary=_summary(), report="r", submission_sha256="0" * 64)
    d = row.to_dict()
    for m in LEADERBOARD_METRICS:
        assert d[m.key] == pytest.approx(lookup(SUMMARY, m.name)), m.name
    none = replace(row, summary=_summary(count_mae=None, robust_failure_rate=None))
    assert none.to_dict()["count_mae"] is None and none.to_dict()["robust_failure_rate"] is None


def test_docs_list_every_registered_metric():
    text = (DOCS / "formats.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- metrics-table:begin -->\n(.*?)<!-- metrics-table:end -->", text, re.S)
    assert m, "docs/formats.md lacks the generated metrics table"
    assert m.group(1) == metrics_table_markdown(), "regenerate the table in docs/formats.md"
    for metric in METRICS:
        assert f"`{metric.name}`" in m.group(1)


def test_eval_help_lists_every_gated_metric(capsys):
    from arenabench.cli import main

    assert main(["eval", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for m in GATED:
        head, _, tail = m.name.rpartition(".")
        if m.group == "failures":
            assert "failures.<category>" in text
        else:
            assert (m.name in text) or (f"{head}." in text and tail in text), m.name


#: The columns ``sweep.csv`` had before they came from the registry (a varied tilt).
SWEEP_CSV_HEADER = (
    "point,camera.tilt_deg,pipeline,n,n_passed,skipped,pass_rate,pass_rate_ci95_lo,"
    "pass_rate_ci95_hi,count_exact_rate,count_mae,area_rel_err_median,area_rel_err_p95,"
    "area_rel_err_max,marker_id_accuracy,"
    + ",".join(f"failures_{c}" for c in CATEGORIES)
    + ",latency_ms_median,latency_ms_p95"
)


def _sweep_result() -> SweepResult:
    spec = SweepSpec(preset="eyrc", axes=parse_varies(["camera.tilt_deg=0:40:20"]),
                     pipelines=(PipelineSpec("pipeline", "seed"),), per_point=6)
    summaries = tuple(PointSummary(index=i, params={"camera.tilt_deg": t}, pipeline="seed",
                                   summary=_summary(), skipped=i)
                      for i, t in enumerate((0, 20, 40)))
    return SweepResult(spec=spec, points=tuple(s.params for s in summaries),
                       summaries=summaries, images=(), breakdown={})


def test_sweep_csv_columns_come_from_the_registry():
    rows = list(csv.reader(io.StringIO(sweep_csv(_sweep_result()))))
    header = rows[0]
    assert header == ["point", "camera.tilt_deg", "pipeline", "n", "n_passed", "skipped",
                      *(m.key for m in column_metrics())]
    assert ",".join(header) == SWEEP_CSV_HEADER
    d = _summary().to_dict()
    for row in rows[1:]:
        cells = dict(zip(header, row, strict=True))
        assert cells["pass_rate_ci95_lo"] == str(d["pass_rate_ci95"][0])
        assert cells["failures_area_off"] == "4" and cells["latency_ms_p95"] == str(
            d["latency_ms"]["p95"])
    assert [r[5] for r in rows[1:]] == ["0", "1", "2"]


def test_a_newly_registered_metric_becomes_a_sweep_csv_column():
    new = Metric("count_mae_weighted", "weighted count MAE", "lower", "count", "weighted")
    hidden = Metric("count_bias", "count bias", "nearer_zero", "count", "bias", column=False)
    metrics = (*METRICS, new, hidden)
    header = sweep_csv(_sweep_result(), metrics=metrics).splitlines()[0].split(",")
    assert "count_mae_weighted" in header and "count_bias" not in header
    # a quality metric comes before the failure counts, the timings stay last
    assert header.index("count_mae_weighted") < header.index("failures_crash")
    assert header[-2:] == ["latency_ms_median", "latency_ms_p95"]
