"""`arenabench detect` / `python -m arenabench.detect`: competition I/O and exit codes."""

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
from drawing import STANDARD_BOXES, draw_arena
from paths import TESTS

from arenabench.cli import main as cli_main
from arenabench.competition import parse_obstacles_txt
from arenabench.detect import main

EXAMPLE = TESTS / "data" / "task1c_image.jpg"


def run_module(args, cwd):
    return subprocess.run([sys.executable, "-m", "arenabench.detect", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_module_writes_competition_file_in_cwd(tmp_path):
    proc = run_module(["--image", str(EXAMPLE)], tmp_path)
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "obstacles.txt").read_text()
    assert text.startswith("Aruco ID: [80, 85, 90, 95]\nObstacles: 2\nArea: ")
    out = parse_obstacles_txt(text)
    assert out.count == 2 and out.marker_ids == [80, 85, 90, 95]
    assert out.area == pytest.approx(72141.5, rel=0.01)
    assert [p.name for p in tmp_path.iterdir()] == ["obstacles.txt"]  # atomic: no temporaries


def test_json_output_and_output_option(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    target = tmp_path / "sub" / "result.txt"
    assert main(["--image", str(EXAMPLE), "--output", str(target), "--json",
                 "--profile", "seed"]) == 0
    data = json.loads(capsys.readouterr().out)
    for key in ("status", "dictionary", "marker_ids", "count", "total_area"):
        assert key in data
    assert (data["status"], data["dictionary"], data["count"]) == ("ok", "DICT_4X4_100", 2)
    assert data["profile"] == "seed"
    assert parse_obstacles_txt(target.read_text()).count == 2
    assert not (tmp_path / "obstacles.txt").exists()


def test_dispatcher_runs_detect(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli_main(["detect", "--image", str(EXAMPLE), "--corners", "outer",
                     "--frame-size", "500", "--min-area", "100"]) == 0
    out = parse_obstacles_txt((tmp_path / "obstacles.txt").read_text())
    assert out.count == 2


@pytest.mark.integration
def test_markers_not_found_exit_3_with_parseable_file(tmp_path, capsys, monkeypatch):
    img, _ = draw_arena(obstacles=STANDARD_BOXES)
    img[860:930, 860:930] = 248  # erase marker 90
    path = tmp_path / "three.png"
    cv2.imwrite(str(path), img)
    monkeypatch.chdir(tmp_path)
    assert main(["--image", str(path), "--json"]) == 3
    captured = capsys.readouterr()
    assert json.loads(captured.out)["status"] == "markers_not_found"
    assert "markers not found" in captured.err
    text = (tmp_path / "obstacles.txt").read_text()
    assert text == "Aruco ID: [80, 85, 95]\nObstacles: 0\nArea: 0.0\n"


def _write(path, data):
    path.write_bytes(data)
    return path


def _bad_inputs(d):
    png16 = d / "deep.png"
    cv2.imwrite(str(png16), np.full((50, 50), 1000, np.uint16))
    data = EXAMPLE.read_bytes()
    return {
        "missing": (d / "nope.jpg", "no such file"),
        "directory": (d, "is a directory"),
        "empty": (_write(d / "empty.jpg", b""), "empty file"),
        "truncated": (_write(d / "cut.jpg", data[: len(data) // 2]), "truncated JPEG"),
        "text": (_write(d / "notes.png", b"hello\n"), "not a decodable image"),
    }


@pytest.mark.parametrize("case", ["missing", "directory", "empty", "truncated", "text"])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    path, fragment = _bad_inputs(tmp_path)[case]
    assert main(["--image", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("arenabench detect: error: ")
    assert fragment in err
    assert not (tmp_path / "obstacles.txt").exists()


@pytest.mark.parametrize("kind", ["gray16", "gray8", "rgba"])
def test_unusual_but_valid_images_are_handled(tmp_path, monkeypatch, kind):
    img = cv2.imread(str(EXAMPLE))
    gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    converted = {
        "gray16": gray.astype(np.uint16) * 257,
        "gray8": gray,
        "rgba": cv2.cvtColor(img, cv2.COLOR_BGR2BGRA),
    }[kind]
    path = tmp_path / f"{kind}.png"
    cv2.imwrite(str(path), converted)
    monkeypatch.chdir(tmp_path)
    assert main(["--image", str(path)]) == 0
    out = parse_obstacles_txt((tmp_path / "obstacles.txt").read_text())
    assert out.count == 2 and out.area == pytest.approx(72141.5, rel=0.01)


@pytest.mark.parametrize(
    "args, fragment",
    [
        ([], "required: --image"),
        (["--image", "x.png", "--profile", "fast"], "invalid choice"),
        (["--image", "x.png", "--threshold", "300"], "threshold"),
        (["--image", "x.png", "--frame-size", "3"], "frame size"),
        (["--image", "x.png", "--min-area", "-5"], "min_area"),
    ],
)
def test_usage_errors_exit_2_one_line(args, fragment, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and fragment in err


def test_module_exit_codes_via_subprocess(tmp_path):
    proc = run_module(["--image", str(tmp_path / "missing.png")], tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"arenabench detect: error: {tmp_path / 'missing.png'}: no such file"
    ]
