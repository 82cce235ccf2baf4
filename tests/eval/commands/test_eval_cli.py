"""``arenabench eval`` end to end on a drawn dataset: report files, exit codes, thresholds,
usage errors, ``--compare``, the breakdown and the pytest plugin."""

import csv
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
import toy_arena
from paths import TESTS

from arenabench.cli import main as arenabench_main
from arenabench.eval.evaluation import evaluate
from arenabench.eval.reports import write_reports

PIPES = TESTS / "pipelines"


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toycli") / "toy", n=8, seed=5)


@pytest.fixture(scope="module")
def run_dir(toy, tmp_path_factory):
    out = tmp_path_factory.mktemp("out")
    rc = arenabench_main(
        [
            "eval",
            str(toy),
            "--pipeline",
            "toy_arena:detect",
            "--out",
            str(out),
            "--no-progress",
            "--workers",
            "2",
        ]
    )
    assert rc == 0
    return out


def test_report_json_has_the_documented_keys(run_dir, toy):
    rep = json.loads((run_dir / "report.json").read_text())
    assert rep["schema"] == "arenabench.report/1"
    assert {"pipeline", "dataset", "area_reference", "tolerance", "summary", "images"} <= set(rep)
    assert (rep["area_reference"], rep["tolerance"]) == ("visible", 0.05)
    s = rep["summary"]
    assert {
        "n",
        "pass_rate",
        "pass_rate_ci95",
        "count_exact_rate",
        "count_mae",
        "area_rel_err",
        "marker_id_accuracy",
        "failures",
        "latency_ms",
    } <= set(s)
    assert set(s["area_rel_err"]) >= {"median", "p95", "max"}
    assert set(s["latency_ms"]) >= {"median", "p95"}
    assert set(s["failures"]) == {
        "markers_not_found",
        "wrong_count",
        "area_off",
        "crash",
        "timeout",
        "limit",
        "bad_output",
    }
    assert s["n"] == 8 and s["pass_rate"] == 1.0
    img = rep["images"][0]
    assert {"id", "pass", "category", "gt", "pred", "area_rel_err", "latency_ms"} <= set(img)
    assert set(img["gt"]) >= {"count", "area"} and set(img["pred"]) >= {
        "count",
        "area",
        "marker_ids",
    }
    gt0 = json.loads((toy / "gt" / "000000.json").read_text())
    assert img["gt"]["area"] == gt0["area"]["visible_px"]
    # the toy GT's markers have no corners: no gt.min_marker_gap_px
    assert set(rep["breakdown"]) == {"light.gain", "obstacles.count", "gt.min_box_visible_px"}
    assert [row["bin"] for row in rep["breakdown"]["obstacles.count"]] == ["0", "1", "2", "3"]


def test_csv_junit_markdown_html_written(run_dir):
    rows = list(csv.DictReader((run_dir / "results.csv").open()))
    assert len(rows) == 8 and rows[0]["pass"] == "1" and "param:light.gain" in rows[0]
    root = ET.parse(run_dir / "junit.xml").getroot()
    assert len(root.findall(".//testcase")) == 8 and not root.findall(".//failure")
    md = (run_dir / "report.md").read_text()
    assert "| pass rate | 100.0 % (8/8) |" in md and "### obstacles.count" in md
    html = (run_dir / "report.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and "data:image/png;base64," in html


@pytest.mark.integration
def test_fail_under_thresholds_and_directions(toy, tmp_path, capsys):
    base = ["eval", str(toy), "--pipeline", "toy_arena:detect", "--no-progress"]
    assert arenabench_main([*base, "--fail-under", "pass_rate=0.95,count_exact_rate=1"]) == 0
    capsys.readouterr()
    assert arenabench_main([*base, "--fail-under", "area_rel_err.p95=0.001"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("arenabench eval: FAILED: area_rel_err.p95 ") and "(maximum)" in err
    assert len(err.splitlines()) == 1
    # a perfect area tolerance makes images fail as area_off; junit shows them natively
    out = tmp_path / "strict"
    rc = arenabench_main(
        [*base, "--tolerance", "0.001", "--out", str(out), "--fail-under", "pass_rate=0.5"]
    )
    assert rc == 1
    fails = ET.parse(out / "junit.xml").getroot().findall(".//failure")
    assert fails and all(f.get("type") == "area_off" for f in fails)


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["eval", "{missing}", "--pipeline", "reference"], "dataset folder does not exist"),
        (
            ["eval", "{toy}", "--pipeline", "toy_arena:detect", "--fail-under", "speed=3"],
            "unknown metric 'speed'",
        ),
        (
            ["eval", "{toy}", "--pipeline", "toy_arena:detect", "--fail-under", "pass_rate=high"],
            "not a number",
        ),
        (["eval", "{toy}"], "give --pipeline"),
        (["eval", "{toy}", "--pipeline", "best"], "pipeline must be one of"),
        (["eval", "{toy}", "--pipeline", "toy_arena:detect", "--formats", "pdf"], "pdf"),
        (["eval", "{toy}", "--pipeline", "reference", "--cmd", "x"], "not allowed with"),
        (["eval", "--compare", "{missing}", "{missing}"], "not a readable arenabench report"),
    ],
)
def test_usage_errors_exit_2(argv, fragment, toy, tmp_path, capsys):
    argv = [a.format(toy=toy, missing=tmp_path / "nope") for a in argv]
    assert arenabench_main(argv) == 2
    assert fragment in capsys.readouterr().err


@pytest.mark.parametrize(("gate", "needle"), [
    (("--fail-under", "pass_rate=95"), "--fail-under pass_rate=95: must be a fraction in [0, 1]; "
                                       "95 % is 0.95"),
    (("--fail-under", "pass_rate=-1"), "must be a fraction in [0, 1]"),
    (("--fail-under", "area_rel_err.p95=-1"), "area_rel_err.p95=-1: must be a finite number >= 0"),
    (("--fail-under", "pass_rate=0.9", "--fail-under", "pass_rate=0.5"), "pass_rate given twice"),
])
def test_an_impossible_gate_is_refused_before_any_image(gate, needle, toy, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["eval", str(toy), "--pipeline", "toy_arena:detect", "--out", str(out),
            "--no-progress", *gate]
    assert arenabench_main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("arenabench eval: error: --fail-under")
    assert needle in err and captured.out == "", err
    assert not out.exists()


def test_malformed_ground_truth_names_file_and_field(toy, tmp_path, capsys):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    gt_file = bad / "gt" / "000002.json"
    gt = json.loads(gt_file.read_text())
    del gt["area"]["visible_px"]
    gt_file.write_text(json.dumps(gt))
    argv = ["eval", str(bad), "--pipeline", "toy_arena:detect"]
    assert arenabench_main(argv) == 2  # the edited file no longer matches the manifest
    err = capsys.readouterr().err
    assert str(gt_file) in err and "gt_sha256" in err and len(err.splitlines()) == 1
    assert arenabench_main([*argv, "--no-verify"]) == 2
    err = capsys.readouterr().err
    assert f"{gt_file}: area: 'visible_px' is a required property" in err
    assert len(err.splitlines()) == 1


def test_compare_shows_metrics_and_verdict_changes(toy, tmp_path, capsys):
    def worse(image):
        r = toy_arena.detect(image)
        return {**r, "count": r["count"] + 1} if r["count"] == 2 else r

    old = evaluate("toy_arena:detect", toy)
    new = evaluate(worse, toy)
    write_reports(old, tmp_path / "old", formats=("json",))
    write_reports(new, tmp_path / "new", formats=("json",))
    rc = arenabench_main(
        [
            "eval",
            "--compare",
            str(tmp_path / "old" / "report.json"),
            str(tmp_path / "new" / "report.json"),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    flipped = [r.id for r in new.images if not r.passed]
    assert flipped and f"pass -> fail: {len(flipped)}" in out
    for ident in flipped:
        assert f"  {ident}: now wrong_count" in out
    assert "fail -> pass: 0" in out
    assert "pass_rate" in out and "(worse)" in out


@pytest.mark.integration
def test_pytest_plugin_fixture_and_score(toy, tmp_path):
    test_file = tmp_path / "test_team.py"
    test_file.write_text(
        "from arenabench.eval import score\n"
        "import toy_arena\n\n"
        "def test_pipeline(arenabench_dataset):\n"
        "    assert score(toy_arena.detect, arenabench_dataset).pass_rate >= 0.95\n"
    )
    env = {**os.environ, "PYTHONPATH": str(PIPES)}
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            str(test_file),
            f"--arenabench-dataset={toy}",
            "--rootdir",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout


def test_plugin_module_imports_cheaply():
    code = (
        "import sys, arenabench.eval.pytest_plugin; "
        "heavy = {'cv2', 'pyrender', 'numpy', 'matplotlib', 'OpenGL'} & set(sys.modules); "
        "print(sorted(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.integration
def test_an_interrupted_dataset_is_scored_with_a_warning(toy, tmp_path, capsys):
    import shutil

    partial = tmp_path / "partial"
    shutil.copytree(toy, partial)
    meta_path = partial / "dataset.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {"args": {"count": 20}}
    meta.update(complete=False, finished=8)
    meta.setdefault("args", {})["count"] = 20
    meta_path.write_text(json.dumps(meta))
    rc = arenabench_main(["eval", str(partial), "--pipeline", "toy_arena:detect",
                          "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 0
    warning = [line for line in err.splitlines() if "warning" in line]
    assert len(warning) == 1 and "incomplete (8 of 20 scenes" in warning[0], err
