"""What a new user meets first: output and exit behaviour, messages, help, progress, packaging.

Real subprocesses and real pipes where the behaviour is about them."""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import toy_arena
from clirun import CliResult, run_cli
from paths import ROOT

from arenabench.cli import COMMANDS
from arenabench.cli import main as cli_main
from arenabench.exitcodes import ExitCode

EXAMPLE = ROOT / "tests" / "data" / "task1c_image.jpg"
PIPES = ROOT / "tests" / "pipelines"


def _run(*args: str, cwd: Path | None = None, env: dict | None = None) -> CliResult:
    """``arenabench ARGS`` in this process (tests/clirun.py)."""
    return run_cli(*args, cwd=cwd, env=env)


def _run_process(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``arenabench ARGS`` in a fresh interpreter (its own ``sys.path`` and module cache)."""
    return subprocess.run([sys.executable, "-m", "arenabench", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def toy(tmp_path_factory) -> Path:
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toyux") / "toy", n=3, seed=5)


# ----------------------------------------------------------------------------- closed pipes

@pytest.mark.integration
@pytest.mark.parametrize("module", [["-m", "arenabench", "detect"], ["-m", "arenabench.detect"]])
def test_closed_pipe_exits_quietly(tmp_path, module):
    """The reader is gone before the command writes: no traceback, exit status 141."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run(
            [sys.executable, *module, "--image", str(EXAMPLE), "--json", "--indent", "2",
             "--contours"], cwd=tmp_path, stdout=write_end, stderr=subprocess.PIPE, text=True,
            timeout=120)
    finally:
        os.close(write_end)
    assert proc.returncode == ExitCode.BROKEN_PIPE
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr
    assert "Exception ignored" not in proc.stderr


@pytest.mark.integration
def test_head_one_in_a_shell_pipeline(tmp_path):
    cmd = (f"{sys.executable} -m arenabench detect --image {EXAMPLE} --json --indent 2 "
           "--contours | head -1")
    proc = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout == "{\n"
    assert "Traceback" not in proc.stderr and "Broken" not in proc.stderr


@pytest.mark.integration
def test_every_command_goes_through_the_quiet_wrapper(tmp_path):
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run([sys.executable, "-m", "arenabench", "presets", "--params"],
                              stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert proc.returncode == ExitCode.BROKEN_PIPE and proc.stderr == ""


# ----------------------------------------------------------------------------- detect output

def test_detect_says_where_obstacles_txt_went_and_keeps_stdout_empty(tmp_path):
    proc = _run("detect", "--image", str(EXAMPLE), "--output", "out/o.txt", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stdout == ""
    assert proc.stderr.strip().splitlines() == [
        "arenabench detect: wrote out/o.txt: marker ids [80, 85, 90, 95], 2 obstacles, "
        "area 72092.5 px^2"
    ]
    assert (tmp_path / "out" / "o.txt").read_text().startswith("Aruco ID: [80, 85, 90, 95]")


def test_detect_json_is_one_compact_line_contours_on_request(tmp_path):
    line = _run("detect", "--image", str(EXAMPLE), "--json", cwd=tmp_path).stdout
    assert line.count("\n") == 1
    data = json.loads(line)
    assert data["count"] == 2 and data["homography"] and "contour" not in data["obstacles"][0]
    full = _run("detect", "--image", str(EXAMPLE), "--json", "--contours", "--indent", "2",
                cwd=tmp_path).stdout
    assert full.count("\n") > 100
    assert len(json.loads(full)["obstacles"][0]["contour"]) >= 4


@pytest.mark.integration
def test_eval_reads_what_our_own_detector_writes(toy, tmp_path):
    """The README's command line: every image is answered (none is bad_output)."""
    proc = _run("eval", str(toy), "--cmd", "{python} -m arenabench.detect --image {image} --json",
                "--output", "json", "--out", str(tmp_path / "r"), "--formats", "json",
                "--no-progress")
    assert proc.returncode == 0, proc.stderr
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert [img["status"] for img in report["images"]] == ["ok"] * 3
    assert report["summary"]["pass_rate"] == 1.0


def test_a_json_line_pipeline_may_give_polygons_in_image_px():
    from arenabench.eval.scoring.answers import prediction_from_result

    square = [[10, 10], [60, 10], [60, 60], [10, 60]]
    pred = prediction_from_result({"count": 1, "area": 2500.0, "obstacles_image": [square]},
                                  latency_ms=1.0)
    assert pred.status == "ok" and pred.obstacles_space == "image"
    assert pred.obstacles == (((10.0, 10.0), (60.0, 10.0), (60.0, 60.0), (10.0, 60.0)),)
    bad = prediction_from_result({"count": 1, "area": 1.0, "obstacles_frame": [[[0, "x"]]],
                                  "homography": [[1, 0]]}, latency_ms=1.0)
    assert bad.status == "ok" and bad.obstacles == () and bad.homography is None


# ----------------------------------------------------------------------------- usage and help

def test_no_command_prints_usage_and_exits_2(capsys):
    assert cli_main([]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: arenabench") and "--version" in err


def _status(argv: list[str]) -> int | None:
    """A command's exit status, returned or raised (``--help`` may raise ``SystemExit(0)``)."""
    try:
        return cli_main(argv)
    except SystemExit as exc:
        return exc.code


def test_help_command_is_the_commands_help(capsys):
    direct = _status(["generate", "--help"])
    expected = capsys.readouterr().out
    via_help = _status(["help", "generate"])
    assert capsys.readouterr().out == expected and "--count" in expected
    assert direct in (0, None) and via_help in (0, None)
    assert cli_main(["help", "evl"]) == 2
    assert "did you mean 'eval'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "hint"),
    [
        (["generat"], "did you mean 'generate'?"),
        (["generate", "--count", "1", "--out", "{tmp}/x", "--set", "camera.tilt=3"],
         "did you mean 'camera.tilt_deg'"),
        (["generate", "--count", "1", "--out", "{tmp}/x", "--preset", "eyr"],
         "did you mean 'eyrc'"),
        (["eval", "{tmp}", "--pipeline", "referense"], "did you mean 'reference'?"),
        (["sweep", "--vary", "camera.tilt=0:10", "--pipeline", "reference", "--out", "{tmp}/s"],
         "did you mean 'camera.tilt_deg'"),
        (["presets", "--show", "eyrc-uprite"], "did you mean 'eyrc-upright'?"),
        (["detect", "--image", "x.png", "--profile", "refrence"], "did you mean 'reference'?"),
        (["detect", "--image", "x.png", "--corners", "outr"], "did you mean 'outer'?"),
    ],
)
def test_did_you_mean(argv, hint, tmp_path, capsys):
    rc = cli_main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err
    assert rc == 2 and hint in err, err
    assert "Traceback" not in err


def _help(name: str, capsys) -> str:
    try:
        rc = cli_main([name, "--help"])
    except SystemExit as exc:
        rc = exc.code
    assert rc in (0, None)
    return capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_help_is_wrapped_plain_and_complete(name, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    text = _help(name, capsys)
    assert text.startswith(f"usage: arenabench {name}")
    assert "``" not in text
    assert max(len(line) for line in text.splitlines()) <= 100
    lines = text.splitlines()
    option = re.compile(r"^  (-\S+)( \S+)?(, -\S+( \S+)?)*$")
    for here, after in zip(lines, [*lines[1:], ""], strict=True):
        if option.match(here):  # an option alone on its line: its help follows, indented
            assert after.startswith(" " * 10), f"{name}: no help for {here.strip()!r}"


def test_defaults_are_shown(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    text = _help("eval", capsys)
    assert re.search(r"--tolerance TOLERANCE\s+max \|area_rel_err\| to pass \(default: 0.05\)",
                     text)
    assert re.search(r"--timeout TIMEOUT\s+.*default", text)
    assert re.search(r"--area-reference \{visible,footprint,contour\}\s+GT area [\s\S]*?"
                     r"\(default:\s+visible\)", text)
    assert cli_main(["--help"]) == 0
    assert "-V, --version" in capsys.readouterr().out


def test_help_formatter_appends_defaults_once():
    import argparse

    from arenabench.clihelp import HelpFormatter

    p = argparse.ArgumentParser(prog="x", formatter_class=HelpFormatter,
                                description="a " * 80 + "\n\nexamples:\n  x --n 3   # keep")
    p.add_argument("--n", type=int, default=3, help="things")
    p.add_argument("--m", type=int, default=4, help="more (default 4)")
    p.add_argument("--flag", action="store_true", help="a switch")
    text = p.format_help()
    assert "things (default: 3)" in text and "more (default 4)" in text
    assert "a switch (default" not in text
    assert "  x --n 3   # keep" in text


# ----------------------------------------------------------------------------- messages

@pytest.mark.integration
def test_pipeline_module_in_the_current_folder(tmp_path, monkeypatch, toy):
    from arenabench.eval.pipelines import load_callable

    (tmp_path / "mymod_ux.py").write_text(
        "def fn(image):\n    return {'count': 0, 'area': 0.0}\n")
    monkeypatch.chdir(tmp_path)
    before = list(sys.path)
    assert load_callable("mymod_ux:fn")(None) == {"count": 0, "area": 0.0}
    assert sys.path == before
    proc = _run_process("eval", str(toy), "--pipeline", "mymod_ux:fn", "--no-progress",
                        cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "No module named" not in proc.stderr


def test_fit_error_names_the_file(tmp_path, capsys):
    from arenabench.generator.commands.fit import main as fit_main

    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((300, 300, 3), 255, np.uint8))
    assert fit_main([str(blank), "--out", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"arenabench fit: error: {blank}: marker id 80")
    assert not (tmp_path / "s.json").exists()


def test_data_folder_is_ignored():
    if shutil.which("git") and (ROOT / ".git").exists():
        proc = subprocess.run(["git", "check-ignore", "-q", "data/eyrc200/images/000000.png"],
                              cwd=ROOT, timeout=30)
        assert proc.returncode == 0
    else:
        assert "data/" in (ROOT / ".gitignore").read_text().splitlines()


def test_benchmark_docs_and_bench_help_agree_on_the_duration(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    text = " ".join(_help("bench", capsys).split())
    readme = (ROOT / "docs" / "benchmark.md").read_text()
    phrase = "about 1.5 minutes on 2 idle cores"
    assert phrase in text and phrase in readme
    assert "two minutes" not in text


# ----------------------------------------------------------------------------- progress

def test_plain_progress_prints_a_few_lines():
    from arenabench.progress import PlainProgress

    buf, now = io.StringIO(), [0.0]
    with PlainProgress(200, desc="generate", unit="img", file=buf, clock=lambda: now[0]) as bar:
        for _ in range(200):
            now[0] += 0.25
            bar.update(1)
    lines = buf.getvalue().splitlines()
    assert len(lines) == 10 and lines[-1] == "generate: 200/200 img (100 %), 50.0 s"
    assert lines[0] == "generate: 20/200 img (10 %), 5.0 s, eta 45 s"
    # a quick run: only the final line
    quick = io.StringIO()
    with PlainProgress(200, desc="eval", unit="img", file=quick, clock=lambda: now[0]) as bar:
        for _ in range(200):
            bar.update(1)
    assert quick.getvalue().splitlines() == ["eval: 200/200 img (100 %), 0.0 s"]
    # slow work: a line every 10 s even between 10 % steps
    buf2 = io.StringIO()
    bar = PlainProgress(1000, desc="eval", unit="img", file=buf2, clock=lambda: now[0])
    for _ in range(3):
        now[0] += 11.0
        bar.update(1)
    assert len(buf2.getvalue().splitlines()) == 3


def test_progress_picks_bar_lines_or_nothing():
    import pty

    from tqdm import tqdm

    from arenabench.progress import PlainProgress, progress

    buf = io.StringIO()
    with progress(5, desc="x", enabled=False, file=buf) as bar:
        bar.update(5)
    assert buf.getvalue() == ""
    assert isinstance(progress(5, desc="x", file=io.StringIO()), PlainProgress)
    leader, follower = pty.openpty()
    try:
        with open(follower, "w", closefd=False) as tty:
            bar = progress(5, desc="x", file=tty)
            assert isinstance(bar, tqdm)
            bar.close()
    finally:
        os.close(leader)
        os.close(follower)


def test_eval_progress_in_a_log_is_plain_lines(toy):
    proc = _run("eval", str(toy), "--pipeline", "reference")
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr
    assert "eval reference: 3/3 img (100 %)" in proc.stderr


@pytest.mark.integration
def test_generate_progress_in_a_log_is_plain_lines(tmp_path):
    proc = _run("generate", "--count", "2", "--out", str(tmp_path / "g"), "--workers", "1")
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("generate: 2/2 img (100 %)")
    assert "2 rendered" in proc.stdout


# ----------------------------------------------------------------------------- packaging

@pytest.mark.integration
def test_wheel_builds_without_warnings_and_holds_the_package_data(tmp_path):
    """A wheel of a copy of the project: no setuptools warning about undeclared packages, and
    every subpackage and the scene files inside."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for name in ("src", "generator", "eval"):
        shutil.copytree(ROOT / name, src / name,
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", str(tmp_path / "dist"),
         str(src)], capture_output=True, text=True, timeout=600)
    log = proc.stdout + proc.stderr
    if proc.returncode != 0 and re.search(r"No matching distribution|Could not find a version",
                                          log):
        pytest.skip("setuptools for the isolated build is not reachable here")
    assert proc.returncode == 0, log[-3000:]
    assert "absent from the `packages` configuration" not in log
    assert "Package would be ignored" not in log
    wheel = next((tmp_path / "dist").glob("arenabench-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for required in ("arenabench/generator/scenes/task1c_example.json",
                     "arenabench/generator/assets/presets/eyrc.toml",
                     "arenabench/pipeline/detection.py", "arenabench/eval/sweep/html.py",
                     "arenabench/eval/reports/html_report.py", "arenabench/progress.py"):
        assert required in names, required


def test_sweep_point_colours():
    from arenabench.eval.sweep.html import point_class

    assert point_class(3, 1.0, 0.44, 0.9) == "unsure"  # 100 % of 3: clears, interval does not
    assert point_class(200, 0.99, 0.96, 0.9) == "pass"
    assert point_class(200, 0.5, 0.43, 0.9) == "fail"
    assert point_class(0, 0.0, 0.0, 0.9) == "fail"


# ------------------------------------------------------ what a new user trips on, round 3

SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"


@pytest.mark.integration
def test_demo_ends_saying_how_to_run_arenabench_from_a_shell():
    venv_bin = Path(sys.executable).parent
    if not (venv_bin / "arenabench").is_file():
        pytest.skip("not run from a virtual environment with the arenabench script")
    code = "from arenabench.eval.commands.demo import _on_path_hint; print(_on_path_hint())"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "PATH": "/usr/bin:/bin"}, timeout=60)
    hint = proc.stdout.strip()
    assert proc.returncode == 0 and len(hint.splitlines()) == 1, proc.stderr
    shown = os.path.relpath(venv_bin / "arenabench", ROOT)
    if shown.startswith("../.."):
        shown = str(venv_bin / "arenabench")
    assert f"{shown} --help" in hint and f"source {Path(shown).parent / 'activate'}" in hint
    # arenabench on PATH already: no activation advice
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "PATH": f"{venv_bin}:/usr/bin:/bin"},
                          timeout=60)
    assert "source" not in proc.stdout and "arenabench --help" in proc.stdout


@pytest.mark.integration
def test_render_writes_a_one_image_dataset_that_eval_scores(tmp_path):
    out = tmp_path / "one"
    proc = _run("render", str(SCENE), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert f"arenabench eval {out}" in proc.stderr
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == [
        "gt/000000.json", "images/000000.png", "manifest.jsonl"]
    proc = _run("eval", str(out), "--pipeline", "reference", "--out", str(tmp_path / "rep"),
                "--no-progress", "--formats", "json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "rep" / "report.json").read_text())["summary"]
    assert (summary["n"], summary["n_passed"]) == (1, 1)


@pytest.mark.integration
def test_pytest_plugin_without_the_cache_provider_uses_a_temporary_folder(tmp_path,
                                                                          tmp_path_factory):
    (tmp_path / "test_team.py").write_text(
        "from pathlib import Path\n\n"
        "def test_dataset(arenabench_dataset):\n"
        "    assert (arenabench_dataset / 'manifest.jsonl').is_file()\n"
        "    assert Path(__file__).parent not in arenabench_dataset.parents\n"
    )
    # its own --basetemp: sessions of other pytest runs on this machine prune the shared one
    basetemp = tmp_path_factory.mktemp("inner") / "base"
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_team.py",
         "--arenabench-count", "1", "--rootdir", str(tmp_path), "--basetemp", str(basetemp)],
        capture_output=True, text=True, cwd=tmp_path, timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "__pycache__") == [
        "test_team.py"]  # no cache folder left in the project
    assert list(basetemp.glob("arenabench*/*/manifest.jsonl"))  # the session's temporary one


@pytest.mark.integration
def test_html_frame_outlines_follow_a_pipeline_warping_to_the_outer_corners():
    """eyrc-upright: the reference pipeline with outer corners warps to another frame than the
    GT's (inner corners); the GT outlines drawn on its warp must sit on its boxes."""
    from shapely.geometry import Polygon

    from arenabench.eval.reports.html_report import gt_frame_polygons
    from arenabench.frame import FrameSpec
    from arenabench.generator.dataset.make import make_sample
    from arenabench.pipeline import DetectConfig, detect

    sample = make_sample("eyrc-upright", seed=0, index=0)
    gt = sample.record.to_dict()
    det = detect(sample.bgr, DetectConfig(frame=FrameSpec(corners="outer")))
    assert det.status == "ok" and det.count == gt["count"] > 0
    found = [Polygon(o.contour).buffer(0) for o in det.obstacles]

    def best_iou(poly) -> float:
        p = Polygon(poly).buffer(0)
        return max(p.intersection(d).area / p.union(d).area for d in found)

    mapped = gt_frame_polygons(gt, np.asarray(det.homography))
    assert min(best_iou(p) for p in mapped) > 0.9
    as_is = [o["visible_frame_px"] for o in gt["obstacles"]]  # the GT's own (inner) frame
    assert max(best_iou(p) for p in as_is) < 0.8
    # with the GT's own homography the polygons are left as they are
    assert gt_frame_polygons(gt, np.asarray(gt["homography"])) == as_is


@pytest.mark.integration
def test_sweep_whose_points_all_pass_says_the_breakdown_cannot_be_determined(tmp_path):
    proc = _run("sweep", "--vary", "camera.tilt_deg=0,2", "--pipeline", "reference",
                "--per-point", "1", "--workers", "1", "--no-progress", "--no-plots",
                "--out", str(tmp_path / "s"))
    assert proc.returncode == 0, proc.stderr
    line = next(ln for ln in proc.stdout.splitlines() if "breakdown reference" in ln)
    assert "camera.tilt_deg=cannot be determined with 1 scene(s) at the first value" in line
    assert "at least 35 passing scenes per value" in line
    assert "fails at the first value" not in line


def test_formats_doc_says_detect_json_is_one_line_for_output_json():
    text = (ROOT / "docs" / "formats.md").read_text()
    section = text.split("### `arenabench detect --json`", 1)[1].split("\n## ", 1)[0]
    assert "indented JSON" not in section and "one compact JSON line" in section
    assert "--output json" in section


def test_plain_progress_says_the_time_left_and_what_is_under_way():
    import io

    from arenabench.progress import PlainProgress, duration_text

    now = [0.0]
    buf = io.StringIO()
    with PlainProgress(100, desc="grade", unit="run", file=buf,
                       clock=lambda: now[0]) as bar:
        now[0] = 60.0
        bar.set_postfix_str("alpha 20/50, beta 5/50")
        bar.update(25)  # 25 runs in 60 s: 75 left take 180 s
    first, last = buf.getvalue().splitlines()
    assert first == ("grade: 25/100 run (25 %), 60.0 s, eta 3 min 00 s; alpha 20/50, "
                     "beta 5/50")
    assert last == "grade: 25/100 run (25 %), 60.0 s"  # the end: no estimate, no status
    assert [duration_text(s) for s in (12.4, 550, 7500)] == ["12 s", "9 min 10 s",
                                                              "2 h 05 min"]


def test_grade_progress_names_the_teams_under_way():
    from pathlib import Path

    from arenabench.eval.grade.grading import _progress_text, _TeamRun
    from arenabench.eval.grade.partial import PartialLog
    from arenabench.eval.grade.submissions import Team

    runs = [_TeamRun(team=Team(name=n, path=Path("/x") / n), digest="0",
                     preds=[], log=PartialLog(Path("/nonexistent"), {}), done=d)
            for n, d in (("done", 8), ("alpha", 3), ("beta", 1), ("gamma", 2), ("delta", 5),
                         ("idle", 0))]
    assert _progress_text(runs, 8) == "alpha 3/8, beta 1/8, gamma 2/8, +1 more"
