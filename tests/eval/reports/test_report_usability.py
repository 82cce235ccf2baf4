"""What a new user reads in the reports: a timed-out image's latency, the gates ``eval``
applied, the order of the HTML report's sections, ``--compare`` across datasets, and the pytest
plugin's cache key."""

import csv
import json
import shutil
import sys

import pytest
import toy_arena
from paths import TESTS

from arenabench.eval.commands.eval import main as eval_main
from arenabench.eval.evaluation import evaluate
from arenabench.eval.reports import write_reports
from arenabench.eval.runs import CommandPipeline
from arenabench.eval.runs.limits import RunLimits, RunSettings

PIPES = TESTS / "pipelines"
PY = sys.executable


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toyuse") / "toy", n=6, seed=4)


@pytest.mark.integration
def test_a_timed_out_image_has_no_latency_in_any_report(toy, tmp_path):
    report = evaluate(
        CommandPipeline(f"{PY} {PIPES / 'hang.py'} --image {{image}}",
                        settings=RunSettings(limits=RunLimits(timeout_s=1.0))),
        toy, workers=1, limit=1)
    (r,) = report.images
    assert r.category == "timeout"
    write_reports(report, tmp_path, formats=("json", "csv", "html"))
    entry = json.loads((tmp_path / "report.json").read_text())["images"][0]
    assert entry["status"] == "timeout" and entry["latency_ms"] is None
    assert json.loads((tmp_path / "report.json").read_text())["summary"]["latency_ms"] == {
        "median": None, "p95": None}
    (row,) = csv.DictReader((tmp_path / "results.csv").open())
    assert row["latency_ms"] == ""
    page = (tmp_path / "report.html").read_text()
    assert "<tr><td>latency ms</td><td colspan=2>-</td></tr>" in page  # the failure card
    row = page[page.index(f"<tr><td>{r.id}</td>"):]  # the table of images
    assert row[:row.index("</tr>")].endswith("<td>-</td>")  # its last cell: the latency


def test_latency_statistics_keep_the_images_that_have_one(toy):
    def slow_then_fine(image):
        return toy_arena.detect(image)

    report = evaluate(slow_then_fine, toy, workers=1, limit=3)
    lat = report.summary.latency_ms
    assert lat["median"] is not None and lat["median"] > 0
    assert all(r.to_dict()["latency_ms"] > 0 for r in report.images)


@pytest.mark.integration
def test_eval_prints_every_gate_and_its_outcome(toy, tmp_path, capsys):
    rc = eval_main([str(toy), "--pipeline", "toy_arena:detect", "--no-progress", "--workers",
                    "1", "--fail-under", "pass_rate=0.5,area_rel_err.p95=0.5"])
    assert rc == 0
    out = capsys.readouterr().out
    gates = [line for line in out.splitlines() if line.startswith("gate ")]
    assert len(gates) == 2, out
    assert gates[0].startswith("gate pass_rate >= 0.5: ") and gates[0].endswith(": pass")
    assert gates[1].startswith("gate area_rel_err.p95 <= 0.5: ") and gates[1].endswith(": pass")


def test_eval_prints_a_missed_gate_as_failed(toy, capsys):
    rc = eval_main([str(toy), "--cmd", f"{PY} {PIPES / 'crash.py'} --image {{image}}",
                    "--no-progress", "--workers", "1", "--limit", "1",
                    "--fail-under", "pass_rate=0.9,count_exact_rate=0"])
    assert rc == 1
    cap = capsys.readouterr()
    gates = [line for line in cap.out.splitlines() if line.startswith("gate ")]
    assert gates == ["gate pass_rate >= 0.9: 0: FAILED", "gate count_exact_rate >= 0: 0: pass"]
    assert "FAILED: pass_rate 0 < 0.9" in cap.err


def test_html_lists_the_likely_causes_before_the_failure_cards(tmp_path):
    from arenabench.eval.evaluation import build_report
    from arenabench.eval.scoring.results import ImageResult, ImageScore, Prediction, Truth

    def result(i, passed, size):
        return ImageResult(
            id=f"{i:06d}", image="", truth=Truth(count=1, area=1.0),
            prediction=Prediction(status="ok", count=1 if passed else 0, area=1.0,
                                  latency_ms=1.0),
            score=ImageScore(passed=passed, category=None if passed else "wrong_count",
                             count_err=0 if passed else -1, area_rel_err=0.0,
                             area_err_kind="relative", marker_ids_ok=None),
            params={"size": size})

    results = [result(i, i >= 4, float(i)) for i in range(10)]
    report = build_report(results, pipeline="p", dataset=str(tmp_path / "nowhere"))
    assert report.causes
    write_reports(report, tmp_path, formats=("html", "md"))
    for name in ("report.html", "report.md"):
        text = (tmp_path / name).read_text()
        causes = text.index("Likely causes")
        cards = text.index("Failing images" if name == "report.md" else "<h2>Failures</h2>")
        assert causes < cards, name


@pytest.fixture(scope="module")
def other_toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toyother") / "toy", n=6, seed=11)


@pytest.fixture(scope="module")
def two_runs(toy, other_toy, tmp_path_factory):
    outs = {}
    for name, data in (("a", toy), ("a2", toy), ("b", other_toy)):
        out = tmp_path_factory.mktemp(f"cmp-{name}")
        assert eval_main([str(data), "--pipeline", "toy_arena:detect", "--no-progress",
                          "--workers", "1", "--formats", "json,md", "--out", str(out)]) == 0
        outs[name] = out
    return outs


def test_report_json_records_the_manifest_hash(two_runs, toy):
    from arenabench.fileio import sha256_file

    doc = json.loads((two_runs["a"] / "report.json").read_text())
    assert doc["schema"] == "arenabench.report/1"
    assert doc["manifest_sha256"] == sha256_file(toy / "manifest.jsonl")


def test_compare_refuses_reports_of_different_datasets(two_runs, capsys):
    a, b = two_runs["a"] / "report.json", two_runs["b"] / "report.json"
    capsys.readouterr()
    rc = eval_main(["--compare", str(a), str(b)])
    cap = capsys.readouterr()
    assert rc == 2
    assert cap.out == ""
    (line,) = cap.err.strip().splitlines()
    assert "different datasets" in line and str(a) in line and str(b) in line


def test_compare_takes_the_out_folders(two_runs, capsys):
    capsys.readouterr()
    rc = eval_main(["--compare", str(two_runs["a"]), str(two_runs["a2"])])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert "pass -> fail: 0" in cap.out
    rc = eval_main(["--compare", str(two_runs["a"]), str(two_runs["b"])])
    assert rc == 2 and "different datasets" in capsys.readouterr().err


def test_compare_of_a_folder_without_a_report_is_one_line(two_runs, tmp_path, capsys):
    rc = eval_main(["--compare", str(tmp_path), str(two_runs["a"])])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "report.json" in err


def test_compare_warns_when_a_report_has_no_manifest_hash(two_runs, tmp_path, capsys):
    old = tmp_path / "old.json"
    doc = json.loads((two_runs["a"] / "report.json").read_text())
    del doc["manifest_sha256"]
    old.write_text(json.dumps(doc))
    capsys.readouterr()
    rc = eval_main(["--compare", str(old), str(two_runs["a2"])])
    cap = capsys.readouterr()
    assert rc == 0
    assert "warning" in cap.err and "manifest_sha256" in cap.err


def test_pytest_plugin_keys_its_set_by_the_generator_version():
    from arenabench.eval.pytest_plugin import dataset_key
    from arenabench.generator.dataset.make import GENERATOR_VERSION

    assert dataset_key("eyrc", 12, 0) == f"eyrc-n12-s0-v{GENERATOR_VERSION}"


@pytest.mark.integration
def test_pytest_plugin_caches_under_the_generator_version(tmp_path, tmp_path_factory):
    import subprocess

    from arenabench.generator.dataset.make import GENERATOR_VERSION

    (tmp_path / "test_team.py").write_text(
        "def test_dataset(arenabench_dataset):\n"
        "    print('DATASET', arenabench_dataset.name)\n")
    proc = subprocess.run(
        [PY, "-m", "pytest", "-q", "-s", "test_team.py", "--arenabench-count", "1",
         "--rootdir", str(tmp_path)],
        capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"DATASET eyrc-n1-s0-v{GENERATOR_VERSION}\n" in proc.stdout
    shutil.rmtree(tmp_path / ".pytest_cache")
