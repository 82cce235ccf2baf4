"""Pipeline adapters with real pipelines: in-process callables and real subprocesses, including
deliberately broken ones (tests/pipelines/). The harness must finish and categorise each."""

import os
import re
import sys

import cv2
import numpy as np
import pytest
import toy_arena
from paths import TESTS

from arenabench.eval.commands.eval import main as eval_main
from arenabench.eval.evaluation import evaluate
from arenabench.eval.pipelines import CallablePipeline
from arenabench.eval.runs import CommandPipeline
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.eval.scoring.results import Prediction

PIPES = TESTS / "pipelines"

PY = sys.executable


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toy") / "toy set", n=8, seed=3)


def _per_image(report):
    return [
        (
            r.id,
            r.passed,
            r.category,
            r.prediction.count,
            r.prediction.area,
            r.prediction.marker_ids,
            r.score.area_rel_err,
        )
        for r in report.images
    ]


@pytest.mark.integration
def test_callable_command_and_json_line_give_identical_results(toy):
    by_spec = evaluate("toy_arena:detect", toy, workers=2)
    by_function = evaluate(toy_arena.detect, toy, workers=2)
    script = PIPES / "toy_arena.py"
    by_cmd = evaluate(CommandPipeline(f"{PY} '{script}' --image {{image}}"), toy, workers=2)
    by_json = evaluate(
        CommandPipeline(f"{PY} '{script}' --image {{image}}", output="json"), toy, workers=2
    )
    total_area = evaluate(
        CommandPipeline(f"{PY} '{PIPES / 'total_area.py'}' --image {{image}}"), toy, workers=2
    )
    expected = _per_image(by_spec)
    assert by_spec.summary.pass_rate == 1.0 and len(expected) == 8
    for other in (by_function, by_cmd, by_json, total_area):
        assert _per_image(other) == expected
    # the dataset folder has a space in its name: {image} substitution is per argument
    assert " " in str(toy)
    assert all(r.prediction.latency_ms > 0 for r in by_cmd.images)


@pytest.mark.integration
def test_process_pool_matches_thread_pool(toy):
    threads = evaluate("toy_arena:detect", toy, workers=2, executor="thread")
    procs = evaluate("toy_arena:detect", toy, workers=2, executor="process")
    assert _per_image(procs) == _per_image(threads)


@pytest.mark.integration
def test_crashing_command_is_a_crash_with_its_stderr(toy, tmp_path, capsys):
    rc = eval_main(
        [
            str(toy),
            "--cmd",
            f"{PY} {PIPES / 'crash.py'} {{image}}",
            "--out",
            str(tmp_path),
            "--fail-under",
            "pass_rate=0.9",
            "--no-progress",
            "--limit",
            "3",
        ]
    )
    assert rc == 1
    err = capsys.readouterr().err
    assert "pass_rate 0 < 0.9" in err and len(err.strip().splitlines()) == 1
    from arenabench.eval.reports.json_report import read_json

    report = read_json(tmp_path / "report.json")
    assert [r.category for r in report.images] == ["crash"] * 3
    first = report.images[0].prediction
    assert first.message.startswith("exit status 1")
    assert "deliberate crash in the test pipeline" in first.stderr


@pytest.mark.integration
def test_hanging_command_times_out_and_its_children_are_killed(toy, tmp_path):
    from hostile_util import processes_with

    marker = f"hang-marker-{os.getpid()}"
    report = evaluate(
        CommandPipeline(
            f"{PY} {PIPES / 'hang.py'} --marker {marker}",
            settings=RunSettings(limits=RunLimits(timeout_s=1.5)),
        ),
        toy,
        workers=3,
        limit=3,
    )
    assert [r.category for r in report.images] == ["timeout"] * 3
    for r in report.images:
        assert "timed out after 1.5 s" in r.prediction.message
        assert re.search(r"child-pid (\d+)", r.prediction.stdout)
    assert processes_with(marker) == [], "a child of the hanging pipeline survived"
    assert report.summary.failures["timeout"] == 3


def test_garbage_output_is_bad_output_quoting_the_text(toy):
    report = evaluate(CommandPipeline(f"{PY} {PIPES / 'garbage.py'}"), toy, workers=2, limit=2)
    for r in report.images:
        assert r.category == "bad_output"
        assert "the obstacles are: many" in r.prediction.message
        assert "garbage" in r.prediction.stdout


def test_missing_obstacles_file_and_missing_executable(toy):
    silent = evaluate(CommandPipeline(f"{PY} -c pass"), toy, limit=1)
    assert silent.images[0].category == "bad_output"
    assert "obstacles.txt was not written" in silent.images[0].prediction.message
    with pytest.raises(ValueError, match="executable '/nonexistent/pipeline' does not exist"):
        CommandPipeline("/nonexistent/pipeline --image {image}")
    with pytest.raises(ValueError, match="executable 'no-such-tool-xyz' not found on PATH"):
        CommandPipeline("no-such-tool-xyz --image {image}")


@pytest.mark.integration
def test_eight_parallel_commands_never_share_a_working_directory(toy, tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    report = evaluate(
        CommandPipeline(f"{PY} {PIPES / 'isolation.py'} --image {{image}}"), toy, workers=8
    )
    assert report.summary.pass_rate == 1.0, [r.prediction.stderr for r in report.images]
    cwds = {re.search(r"cwd \S+ (\S+)", r.prediction.stdout).group(1) for r in report.images}
    assert len(cwds) == 8
    assert list(tmp_path.iterdir()) == [], "the runs' private directories must be removed"


def test_markers_not_found_from_exit_status_3(tmp_path):
    blank = tmp_path / "blank image.png"
    cv2.imwrite(str(blank), np.full((300, 300, 3), 180, np.uint8))
    pred = CommandPipeline(f"{PY} {PIPES / 'toy_arena.py'} --image {{image}}").run(blank)
    assert (pred.status, pred.count, pred.area) == ("markers_not_found", 0, 0.0)
    in_proc = CallablePipeline(toy_arena.detect).run(blank)
    assert in_proc.status == "markers_not_found"


def test_in_process_failures_never_escape(toy):
    def boom(image):
        raise ZeroDivisionError("in-process boom")

    crashed = evaluate(boom, toy, limit=2)
    assert [r.category for r in crashed.images] == ["crash", "crash"]
    assert "ZeroDivisionError: in-process boom" in crashed.images[0].prediction.message
    assert "Traceback" in crashed.images[0].prediction.stderr
    junk = evaluate(lambda image: "three boxes", toy, limit=1)
    assert junk.images[0].category == "bad_output"

    class Answer:
        status, count, total_area, marker_ids = "ok", 1, 10.0, [80]

    obj = evaluate(lambda image: Answer(), toy, limit=2)
    assert obj.images[1].prediction == Prediction(
        status="ok",
        count=1,
        area=10.0,
        marker_ids=(80,),
        latency_ms=obj.images[1].prediction.latency_ms,
    )


@pytest.mark.parametrize(("result", "shown"), [
    ((2, 72000.0), "tuple (2, 72000.0)"),
    ([2, 72000.0], "list [2, 72000.0]"),
    ("Obstacles: 2", "str 'Obstacles: 2'"),
    (2, "int 2"),
    (None, "NoneType None"),
    (np.array([2.0, 7.0]), "ndarray"),
])
def test_a_result_that_is_not_a_mapping_says_so(result, shown):
    from arenabench.eval.scoring.answers import prediction_from_result

    pred = prediction_from_result(result, latency_ms=1.0)
    assert pred.status == "bad_output"
    assert pred.message.startswith("the result is not a mapping (a dict, or an object with "
                                   f"count and area attributes): {shown}"), pred.message


def test_adapter_arguments_are_validated():
    with pytest.raises(ValueError, match="timeout_s"):
        RunLimits(timeout_s=0)
    with pytest.raises(ValueError, match="output"):
        CommandPipeline(f"{PY} {{image}}", output="xml")
    with pytest.raises(ValueError, match="template"):
        CommandPipeline("x 'unclosed")
    with pytest.raises(TypeError):
        CommandPipeline(f"{PY} {{image}}", RunSettings())  # settings is keyword-only
    with pytest.raises(ValueError, match=r"pkg\.module:function"):
        CallablePipeline("no_colon")
    with pytest.raises(ValueError, match="cannot import"):
        CallablePipeline("no_such_module_xyz:f")


@pytest.mark.parametrize(
    "script, category, status",
    [
        ("crash.py", "crash", 1),
        pytest.param("hang.py", "timeout", 1, marks=pytest.mark.integration),
        pytest.param("garbage.py", "bad_output", 1, marks=pytest.mark.integration),
        pytest.param("total_area.py", None, 0, marks=pytest.mark.integration),
    ],
)
def test_broken_pipelines_through_the_cli(script, category, status, toy, tmp_path, capsys):
    from arenabench.eval.reports.json_report import read_json

    rc = eval_main(
        [
            str(toy),
            "--cmd",
            f"{PY} {PIPES / script} --image {{image}}",
            "--timeout",
            "1.5",
            "--limit",
            "2",
            "--workers",
            "2",
            "--no-progress",
            "--fail-under",
            "pass_rate=1",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == status
    report = read_json(tmp_path / "report.json")
    assert [r.category for r in report.images] == [category, category]
    err = capsys.readouterr().err
    assert ("FAILED: pass_rate 0 < 1" in err) == (status == 1)
