"""Acceptance on a generated eyrc set: the reference pipeline in-process, through the
competition command ``python -m arenabench.detect --image {image}`` and through a callable give
the same per-image results; ``arenabench demo`` ends with the report and its path."""

import os
import sys
from pathlib import Path

import pytest
from paths import TESTS

pytest.importorskip("arenabench.generator.commands.generate", reason="generator not available yet")
pytest.importorskip("arenabench.pipeline", reason="pipeline not available yet")
pytest.importorskip("arenabench.detect", reason="arenabench.detect command not available yet")

from arenabench.eval.commands.demo import main as demo_main
from arenabench.eval.commands.eval import main as eval_main
from arenabench.eval.reports.json_report import read_json
from arenabench.generator.commands.generate import main as generate_main

PIPES = TESTS / "pipelines"


@pytest.fixture(scope="module")
def eyrc(tmp_path_factory):
    out = tmp_path_factory.mktemp("gen") / "eyrc"
    rc = generate_main(
        ["--preset", "eyrc", "--count", "10", "--seed", "11", "--out", str(out), "--no-progress"]
    )
    assert rc == 0
    return out


def _per_image(report):
    return [
        (
            r.id,
            r.passed,
            r.category,
            r.prediction.status,
            r.prediction.count,
            r.prediction.area,
            sorted(r.prediction.marker_ids or []),
        )
        for r in report.images
    ]


@pytest.mark.integration
def test_reference_same_in_process_by_command_and_by_callable(eyrc, tmp_path, monkeypatch):
    # "python" on PATH must be this interpreter (the venv's), as it is for a user in the venv
    monkeypatch.setenv("PATH", f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.syspath_prepend(str(PIPES))
    runs = {
        "builtin": ["--pipeline", "reference"],
        "command": ["--cmd", "python -m arenabench.detect --image {image}"],
        "callable": ["--pipeline", "reference_callable:detect"],
    }
    reports = {}
    for name, spec in runs.items():
        rc = eval_main(
            [str(eyrc), *spec, "--out", str(tmp_path / name), "--no-progress", "--workers", "2"]
        )
        assert rc == 0
        reports[name] = read_json(tmp_path / name / "report.json")
    expected = _per_image(reports["builtin"])
    assert len(expected) == 10
    assert _per_image(reports["command"]) == expected
    assert _per_image(reports["callable"]) == expected
    summary = reports["builtin"].summary
    assert summary.pass_rate >= 0.8, summary
    assert summary.marker_id_accuracy == 1.0
    # the eyrc twin varies the boxes only: its camera is fixed, so no breakdown by it
    assert "obstacles.count" in reports["builtin"].breakdown
    assert "camera.tilt_deg" not in reports["builtin"].breakdown


@pytest.mark.integration
def test_demo_ends_with_the_report_and_its_path(tmp_path, capsys):
    example = TESTS / "data" / "task1c_image.jpg"
    assert demo_main(["--out", str(tmp_path / "demo"), "--count", "4", "--workers", "2",
                      "--example", str(example)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    html = tmp_path / "demo" / "report-reference" / "report.html"
    assert out[-1] == f"open the HTML report: {html.resolve()}"
    # a short story: the example in three lines, the set, the score table, the report
    assert len(out) < 25
    assert out[0].startswith("1. the reference pipeline on ")
    assert out[1].strip().startswith("markers [80, 85, 90, 95], 2 obstacles, area ")
    assert out[2].strip() == f"competition output: {tmp_path / 'demo' / 'obstacles.txt'}"
    assert out[3].startswith("2. generated 4 eyrc images")
    assert out[4].startswith("3. reference: pass rate")
    assert not any(line.lstrip().startswith(("{", '"')) for line in out)  # no JSON dump
    assert html.is_file() and (html.parent / "junit.xml").is_file()
    assert any("pass rate" in line for line in out)
    # a second run reuses the dataset
    assert demo_main(["--out", str(tmp_path / "demo"), "--count", "4", "--workers", "2"]) == 0
    assert "reusing dataset" in capsys.readouterr().out
