"""Text parameters have bounds: at most ``MAX_TEXT_CHARS`` printable characters,
in a preset file, ``--set`` and a scene file alike; a value past them is refused with one line
naming the file, the key and (cut short) the value, before anything is made."""

from __future__ import annotations

import json

import pytest
from clirun import run_cli

from arenabench.generator.model.sampler import sample_scene
from arenabench.limits import MAX_SHOWN_CHARS, MAX_TEXT_CHARS

BAD = {"long": "y" * 100_000, "nul": "a\0b", "newline": "a\nb", "just_too_long":
       "z" * (MAX_TEXT_CHARS + 1)}


def _one_line(r, *names):
    err = r.stderr.strip()
    assert r.returncode == 2 and len(err.splitlines()) == 1, (r.returncode, err[:500])
    assert len(err) < 400 + MAX_SHOWN_CHARS  # the value is cut short, never echoed whole
    for name in names:
        assert name in err, err
    return err


@pytest.mark.parametrize("kind", list(BAD))
def test_a_preset_files_text_is_bounded(tmp_path, kind):
    preset = tmp_path / "p.toml"
    preset.write_text('schema = "arenabench.preset/1"\n[preset]\nname = "p"\n[arena]\n'
                      f"logo_text = {json.dumps(BAD[kind])}\n")
    r = run_cli("generate", "--preset", str(preset), "--count", "1", "--out",
                str(tmp_path / "set"))
    _one_line(r, str(preset), "arena.logo_text")
    assert not (tmp_path / "set").exists()


@pytest.mark.parametrize("kind", ["nul", "newline", "just_too_long"])
def test_a_set_text_is_bounded(tmp_path, kind):
    r = run_cli("generate", "--preset", "eyrc", "--set", f"arena.logo_text={BAD[kind]}",
                "--count", "1", "--out", str(tmp_path / "set"))
    _one_line(r, "--set arena.logo_text")
    assert not (tmp_path / "set").exists()


@pytest.mark.parametrize("kind", list(BAD))
def test_a_scene_files_text_is_bounded(tmp_path, kind):
    scene = sample_scene("eyrc", seed=1, index=0).scene.to_dict()
    scene["arena"]["logo_text"] = BAD[kind]
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    r = run_cli("render", str(path), "--out", str(tmp_path / "out"))
    _one_line(r, str(path), "arena.logo_text")
    assert not (tmp_path / "out").exists()


def test_the_longest_text_allowed_is_accepted():
    scene = sample_scene("eyrc", seed=1, index=0).scene
    arena = scene.arena.__class__(**{**scene.arena.__dict__, "logo_text": "W" * MAX_TEXT_CHARS})
    assert arena.logo_text == "W" * MAX_TEXT_CHARS
