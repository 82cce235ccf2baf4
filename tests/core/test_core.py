"""Shared data model: competition I/O, atomic writes, frame spec, CLI dispatch."""

import json

import numpy as np
import pytest

from arenabench.cli import main as cli_main
from arenabench.competition import (
    OutputFormatError,
    format_obstacles_txt,
    parse_obstacles_txt,
)
from arenabench.fileio import atomic_write_json, sha256_file
from arenabench.frame import FrameSpec


def test_obstacles_txt_round_trip_exact_format():
    text = format_obstacles_txt([80, 85, 90, 95], 2, 72141.5)
    assert text == "Aruco ID: [80, 85, 90, 95]\nObstacles: 2\nArea: 72141.5\n"
    parsed = parse_obstacles_txt(text)
    assert (parsed.count, parsed.area, parsed.marker_ids) == (2, 72141.5, [80, 85, 90, 95])


def test_parser_accepts_total_area_and_spacing():
    parsed = parse_obstacles_txt("Aruco ID: [80,85]\n\n  Obstacles : 3\nTotal Area: 1.5e3\n")
    assert (parsed.count, parsed.area, parsed.marker_ids) == (3, 1500.0, [80, 85])


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("Obstacles: 2\n", "missing Area"),
        ("hello world\n", "unrecognised line: 'hello world'"),
        ("Obstacles: 2.5\nArea: 3\n", "obstacle count is not an integer"),
        ("", "missing Obstacles and Area"),
    ],
)
def test_parser_rejects_garbage_quoting_it(text, fragment):
    with pytest.raises(OutputFormatError, match=fragment):
        parse_obstacles_txt(text)


def test_atomic_write_leaves_no_temporaries(tmp_path):
    target = tmp_path / "sub" / "x.json"
    atomic_write_json(target, {"b": 1, "a": [1.5]})
    assert json.loads(target.read_text()) == {"a": [1.5], "b": 1}
    assert [p.name for p in target.parent.iterdir()] == ["x.json"]
    assert len(sha256_file(target)) == 64


def test_atomic_write_failure_keeps_old_file(tmp_path):
    target = tmp_path / "x.json"
    atomic_write_json(target, {"ok": True})
    with pytest.raises(TypeError):
        atomic_write_json(target, {"bad": object()})
    assert json.loads(target.read_text()) == {"ok": True}
    assert [p.name for p in tmp_path.iterdir()] == ["x.json"]


def test_frame_spec_validates_and_orders_corners():
    corners = FrameSpec(size=16).corners_px()
    np.testing.assert_array_equal(corners, [[0, 0], [16, 0], [16, 16], [0, 16]])
    with pytest.raises(ValueError, match="corners"):
        FrameSpec(corners="middle")
    with pytest.raises(ValueError, match="size"):
        FrameSpec(size=3)


def test_cli_unknown_command_is_usage_error(capsys):
    assert cli_main(["frobnicate"]) == 2
    assert "unknown command 'frobnicate'" in capsys.readouterr().err
    assert cli_main(["--help"]) == 0
    assert "detect" in capsys.readouterr().out


def test_atomic_write_gives_ordinary_permissions(tmp_path):
    import os

    target = atomic_write_json(tmp_path / "p.json", {})
    mask = os.umask(0o022)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask
