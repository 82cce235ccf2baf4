"""``arenabench check SCRIPT`` end to end: a cached twin set, the script run as the competition
ran it (a real subprocess, sandboxed where bubblewrap works), the phase check, the verdict."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from clirun import CliResult, run_cli
from paths import TESTS

from arenabench.generator.dataset.make import GENERATOR_VERSION

PIPELINES = TESTS / "pipelines"
# Scenes 1, 6 and 7 of seed 0 (generator versions 7 and 8) are ones the Canny style loses at their
# phases, and wins at others (docs/rendering.md): under the competition's numpy and OpenCV (check's
# default interpreter), 1 at all 8 shifted phases, 6 at 4 and 7 at 5.
COUNT = 8


def _check(*args: str, cache: Path) -> CliResult:
    return run_cli("check", *args, "--no-progress", env={"ARENABENCH_CACHE_DIR": str(cache)})


@pytest.fixture(scope="module")
def cache(competition_cache):
    """The session's cache: it holds the competition's environment, which check uses."""
    return competition_cache


@pytest.mark.integration
def test_a_good_script_passes_and_the_set_is_reused(cache, tmp_path):
    out = tmp_path / "report"
    proc = _check(str(PIPELINES / "style_blur127.py"), "--count", str(COUNT), "--out", str(out),
                  cache=cache)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"PASS: pass rate 100.0 % ({COUNT}/{COUNT}" in proc.stdout
    assert f"generated {COUNT} scenes" in proc.stdout
    twin = cache / "sets" / f"eyrc-0-{COUNT}-v{GENERATOR_VERSION}"
    assert (twin / "dataset.json").is_file()
    report = json.loads((out / "report.json").read_text())
    assert report["summary"]["n"] == COUNT and report["summary"]["phase_check"] is None
    assert str((out / "report.html").resolve()) in proc.stdout
    again = _check(str(PIPELINES / "style_blur127.py"), "--count", str(COUNT), "--out",
                   str(tmp_path / "again"), cache=cache)
    assert again.returncode == 0 and f"reused twin set {twin}" in again.stdout


@pytest.mark.integration
def test_a_canny_script_fails_by_luck(cache, tmp_path):
    out = tmp_path / "report"
    proc = _check(str(PIPELINES / "style_canny.py"), "--count", str(COUNT), "--out", str(out),
                  cache=cache)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "FAIL: pass rate 62.5 % (5/8" in proc.stdout
    assert "robust failures: 0" in proc.stdout
    assert "phase-dependent failures: 3 (37.5 %)" in proc.stdout
    assert "would have depended on luck" in proc.stdout
    report = json.loads((out / "report.json").read_text())
    failing = [i for i in report["images"] if not i["pass"]]
    assert [i["id"] for i in failing] == ["000001", "000006", "000007"]
    for image in failing:
        phase = image["phase"]
        assert image["category"] == "wrong_count"
        assert phase["phases"] == 8 and 0 < phase["passes"] and phase["class"] == "phase_dependent"
    assert [i["phase"]["passes"] for i in failing] == [8, 4, 5]
    assert report["summary"]["phase_dependent_failure_rate"] == 0.375
    # passing with a lower threshold
    ok = _check(str(PIPELINES / "style_canny.py"), "--count", str(COUNT), "--min-pass-rate",
                "0.5", "--phase-check", "off", "--out", str(tmp_path / "off"), cache=cache)
    assert ok.returncode == 0 and "phase-dependent" not in ok.stdout


@pytest.mark.integration
def test_a_crashing_script_fails_with_its_message(cache, tmp_path):
    proc = _check(str(PIPELINES / "crash.py"), "--count", str(COUNT), "--out",
                  str(tmp_path / "report"), cache=cache)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert f"FAIL: pass rate 0.0 % (0/{COUNT}" in proc.stdout
    assert f"failures: {COUNT} (crash {COUNT})" in proc.stdout
    assert (f"not phase-checked (markers_not_found, crash, timeout, limit, bad_output): "
            f"{COUNT}") in proc.stdout
    assert "deliberate crash" in proc.stdout


@pytest.mark.parametrize(("args", "needle"), [
    (["missing.py"], "missing.py: no such file"),
    (["{pipelines}"], "not a file"),
    (["{pipelines}/crash.py", "--count", "0"], "argument --count: must be an integer in [1, "),
    (["{pipelines}/crash.py", "--workers", "0"], "argument --workers: must be an integer in [1, "),
    (["{pipelines}/crash.py", "--preset", "nope"], "--preset: unknown preset 'nope'"),
    (["{pipelines}/crash.py", "--min-pass-rate", "1.5"],
     "--min-pass-rate 1.5: must be a fraction in [0, 1]"),
    (["{pipelines}/crash.py", "--min-pass-rate", "95"],
     "must be a fraction in [0, 1]; 95 % is 0.95"),
    (["{pipelines}/crash.py", "--phase-check", "zero"], "--phase-check"),
])
def test_bad_input_exits_2_before_any_work(args, needle, tmp_path):
    cache = tmp_path / "cache"
    proc = _check(*(a.format(pipelines=PIPELINES) for a in args), cache=cache)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert needle in proc.stderr.strip().splitlines()[-1]
    assert not cache.exists()


@pytest.mark.parametrize("value", ["1.5", "pass_rate=1.5"])
def test_the_gates_former_name_still_works_and_says_the_new_one(value, tmp_path):
    cache = tmp_path / "cache"
    proc = _check(str(PIPELINES / "crash.py"), "--fail-under", value, cache=cache)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 2, proc.stderr
    assert lines[0] == "arenabench check: --fail-under is now --min-pass-rate (the same pass rate)"
    assert "--min-pass-rate 1.5: must be a fraction in [0, 1]" in lines[1]
    assert not cache.exists()


@pytest.mark.integration
@pytest.mark.parametrize("warm", ["warm", "--no-warm"])
def test_a_script_reads_files_beside_it_from_its_working_directory(cache, tmp_path, warm):
    """As when the competition ran map.py in its folder: the working directory holds (a copy
    of) the script's files, and obstacles.txt is written there, never into the original."""
    import shutil

    team = tmp_path / "team"
    team.mkdir()
    for name in ("style_blur127.py", "competition_style.py"):
        shutil.copy(PIPELINES / name, team / name)
    (team / "settings.txt").write_text("blur127\n")
    (team / "map.py").write_text(
        "import runpy\nfrom pathlib import Path\n"
        "assert Path('settings.txt').read_text() == 'blur127\\n'  # relative to the cwd\n"
        "runpy.run_path(str(Path(__file__).with_name('style_blur127.py')), "
        "run_name='__main__')\n")
    before = sorted(p.name for p in team.iterdir())
    extra = () if warm == "warm" else ("--no-warm",)
    proc = _check(str(team / "map.py"), "--count", "2", "--out", str(tmp_path / "r"), *extra,
                  cache=cache)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "PASS: pass rate 100.0 % (2/2" in proc.stdout
    assert sorted(p.name for p in team.iterdir()) == before  # the original is untouched


# ----------------------------------------------------------------------------- interpreters


def _bare_venv(folder: Path) -> Path:
    """A real virtual environment without any package (no numpy, no OpenCV)."""
    import subprocess
    import sys

    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True,
                   timeout=120)
    return folder / "bin" / "python"


def _own_versions() -> tuple[str, str, str]:
    import platform

    import cv2
    import numpy

    return platform.python_version(), numpy.__version__, cv2.__version__


@pytest.mark.integration
def test_an_old_api_script_passes_under_the_competition_opencv_by_default(cache, tmp_path):
    """A script calling cv2.aruco.detectMarkers (OpenCV 4.x; removed in 5) runs, by default,
    under the competition's numpy and OpenCV, and says so in its output and its reports."""
    from arenabench.eval.runs.competition_env import COMPETITION_PINS

    out = tmp_path / "report"
    script = str(PIPELINES / "style_legacy_aruco.py")
    proc = _check(script, "--count", "2", "--out", str(out), cache=cache)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "PASS: pass rate 100.0 % (2/2" in proc.stdout
    numpy_pin, cv_pin = (p.version for p in COMPETITION_PINS)
    line = next(x for x in proc.stdout.splitlines() if x.startswith("interpreter:"))
    assert f"numpy {numpy_pin}" in line and f"OpenCV {cv_pin[:len('4.10.0')]}" in line
    assert "competition" in line and str(cache / "envs") in line
    interp = json.loads((out / "report.json").read_text())["interpreter"]
    assert interp["source"] == "competition"
    assert interp["numpy"] == numpy_pin and cv_pin.startswith(interp["cv2"])
    assert interp["executable"].startswith(str(cache / "envs"))
    for name in ("report.md", "report.html"):
        assert f"numpy {numpy_pin}" in (out / name).read_text()
    # --python still chooses: arenabench's own interpreter, whatever its OpenCV
    own = _check(script, "--count", "2", "--python", "{python}", "--out", str(tmp_path / "own"),
                 "--phase-check", "off", cache=cache)
    python, np_version, cv_version = _own_versions()
    assert f"interpreter: Python {python}, numpy {np_version}, OpenCV {cv_version}" in own.stdout
    import cv2

    if not hasattr(cv2.aruco, "detectMarkers"):  # OpenCV 5: the failure teams saw
        assert own.returncode == 1 and "has no attribute 'detectMarkers'" in own.stdout


def test_a_python_without_cv2_is_refused_before_any_scene_is_rendered(tmp_path):
    python = _bare_venv(tmp_path / "bare")
    cache = tmp_path / "cache"
    proc = _check(str(PIPELINES / "style_blur127.py"), "--count", "2", "--python", str(python),
                  cache=cache)
    err = proc.stderr.strip()
    assert proc.returncode == 2, proc.stdout + err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "cv2" in err and str(python) in err and "--python" in err
    assert not (cache / "sets").exists()  # nothing rendered
    assert not (cache / "reports").exists()  # nothing run or written


@pytest.mark.integration
def test_offline_the_check_falls_back_in_one_line_naming_the_versions_that_ran(tmp_path):
    """No package index (a closed local port): one line says the competition environment
    cannot be made and names the versions that ran instead; nothing half-made is left."""
    import socket

    from arenabench.eval.runs.competition_env import COMPETITION_PINS

    closed = socket.socket()  # bound, never listening: connections are refused
    closed.bind(("127.0.0.1", 0))
    try:
        port = closed.getsockname()[1]
        cache = tmp_path / "cache"
        proc = run_cli("check", str(PIPELINES / "style_blur127.py"), "--count", "1",
                       "--no-progress", "--phase-check", "off",
                       env={"ARENABENCH_CACHE_DIR": str(cache),
                            "PIP_INDEX_URL": f"http://127.0.0.1:{port}/simple/",
                            "PIP_EXTRA_INDEX_URL": "", "PIP_FIND_LINKS": "", "PIP_RETRIES": "0",
                            "PIP_CONFIG_FILE": os.devnull})
    finally:
        closed.close()
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
    python, np_version, cv_version = _own_versions()
    making, line = proc.stderr.strip().splitlines()  # the progress line, then the one line
    assert making.startswith("arenabench check: making the competition's Python environment")
    assert "cannot be made" in line and "No matching distribution" in line
    for pin in COMPETITION_PINS:
        assert pin.version in line
    assert f"Python {python}, numpy {np_version}, OpenCV {cv_version}" in line
    assert f"interpreter: Python {python}, numpy {np_version}, OpenCV {cv_version}" in proc.stdout
    envs = cache / "envs"
    assert [p.name for p in envs.iterdir() if not p.name.endswith(".lock")] == []


# ----------------------------------------------------------------------------- report folders


@pytest.mark.integration
def test_report_folders_are_keyed_by_what_changes_the_result_and_sets_are_reused(tmp_path):
    """check then check --count N (another count, preset or interpreter) keeps both reports;
    a smaller count reuses the first scenes of a larger cached set, which are the scenes a set
    of that count holds."""
    cache = tmp_path / "cache"
    script = str(PIPELINES / "style_blur127.py")
    common = ("--python", "{python}", "--phase-check", "off")
    first = _check(script, "--count", "3", *common, cache=cache)
    assert first.returncode == 0, first.stdout + first.stderr
    second = _check(script, "--count", "2", *common, cache=cache)
    assert second.returncode == 0, second.stdout + second.stderr
    big = cache / "sets" / f"eyrc-0-3-v{GENERATOR_VERSION}"
    assert f"reused twin set {big}" in second.stdout and "first 2 of 3" in second.stdout
    assert not (cache / "sets" / f"eyrc-0-2-v{GENERATOR_VERSION}").exists()  # nothing rendered

    def report_dir(proc: CliResult) -> Path:
        line = next(x for x in proc.stdout.splitlines() if x.strip().startswith("report:"))
        return Path(line.split("report:", 1)[1].strip()).parent

    a, b = report_dir(first), report_dir(second)
    assert a != b and a.parent == b.parent == cache / "reports"
    assert json.loads((a / "report.json").read_text())["summary"]["n"] == 3
    assert json.loads((b / "report.json").read_text())["summary"]["n"] == 2
    # the first 2 scenes of the 3-scene set are the scenes of a 2-scene set
    fresh = tmp_path / "fresh"
    gen = run_cli("generate", "--preset", "eyrc", "--count", "2", "--seed", "0", "--out",
                  str(fresh), "--no-progress", "--workers", "1")
    assert gen.returncode == 0, gen.stderr
    entries = [json.loads(x) for x in (big / "manifest.jsonl").read_text().splitlines()][:2]
    assert entries == [json.loads(x) for x in (fresh / "manifest.jsonl").read_text().splitlines()]
    again = _check(script, "--count", "2", *common, cache=cache)
    assert report_dir(again) == b  # the same options: the same folder
    other = _check(script, "--count", "2", "--preset", "eyrc-upright", *common, cache=cache)
    assert report_dir(other) not in (a, b)
    # an edit of the script (the same path): a report of its own, the one before kept
    mine = tmp_path / "map.py"
    mine.write_text(Path(script).read_text())
    before = report_dir(_check(str(mine), "--count", "2", *common, cache=cache))
    mine.write_text(Path(script).read_text() + "\n# fixed\n")
    after = report_dir(_check(str(mine), "--count", "2", *common, cache=cache))
    assert after != before and (before / "report.json").is_file()
    assert (after / "report.json").is_file()


def test_help_keeps_the_scripts_conventions_apart_from_the_exit_statuses():
    """The script's convention (exit 3: markers not found) is the script's, in a paragraph of
    its own; arenabench's exit statuses have their own line."""
    proc = run_cli("check", "--help")
    assert proc.returncode == 0
    paragraphs = [" ".join(p.split()) for p in proc.stdout.split("\n\n")]  # wrapped prose
    status = [p for p in paragraphs if "130/143" in p]
    assert len(status) == 1, status
    assert status[0].startswith("arenabench's exit status") and "markers" not in status[0]
    script = [p for p in paragraphs if "markers not found" in p]
    assert len(script) == 1 and script[0].lower().startswith("the script")
    assert "obstacles.txt" in script[0] and "cache" not in script[0]
    assert "{competition_python}" in proc.stdout


@pytest.mark.integration
def test_a_pass_that_leans_on_the_detection_order_gets_one_line_of_advice(tmp_path):
    """A script that warps by detection index passes every twin scene (the camera is fixed);
    the probe on a few jittered scenes finds it fails where the markers are listed in another
    order, and says so in one line; the verdict and exit status stay a PASS. The reference
    gets no advice, and --no-probe runs no probe."""
    cache = tmp_path / "cache"
    common = ("--count", "6", "--python", "{python}", "--phase-check", "off")
    index = _check(str(PIPELINES / "style_detection_index.py"), *common, cache=cache)
    assert index.returncode == 0, index.stdout + index.stderr
    advice = [x for x in index.stdout.splitlines() if x.startswith("robustness:")]
    assert len(advice) == 1 and "another order than on the twin" in advice[0], index.stdout
    assert "by marker id, not by detection index" in advice[0]
    reference = tmp_path / "map.py"
    reference.write_text("import sys\nfrom arenabench.detect import main\n"
                         "sys.exit(main(sys.argv[1:]))\n")
    good = _check(str(reference), *common, cache=cache)
    assert good.returncode == 0 and "robustness:" not in good.stdout, good.stdout
    quiet = _check(str(PIPELINES / "style_detection_index.py"), *common, "--no-probe",
                   cache=cache)
    assert quiet.returncode == 0 and "robustness:" not in quiet.stdout, quiet.stdout
