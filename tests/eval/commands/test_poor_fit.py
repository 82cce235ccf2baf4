"""A preset from a twin whose fit is poor is said in the first line of check, eval, sweep and
grade (eval/commands/poor_fit.py, ResolvedPreset.poor_fit); a good twin's, a built-in preset or
a preset without a verdict says nothing."""

from __future__ import annotations

import pytest
from clirun import run_cli

from arenabench.eval.commands.poor_fit import poor_fit_lines
from arenabench.generator.parameters.preset_files import load_preset_file, preset_to_toml
from arenabench.generator.parameters.presets import builtin_preset

POOR = ("poor: marker squares 13.17 grey levels (bound 1.5); the image shows blur or defocus "
        "(its marker edges 0.41 as sharp as the render's; the twin renders none)")


def _twin_preset(folder, verdict: str | None, name: str = "twin-lab"):
    evidence = {"made_by": "arenabench twin"}
    if verdict is not None:
        evidence["verdict"] = verdict
    path = folder / f"{name}.toml"
    path.write_text(preset_to_toml(builtin_preset("eyrc").params, name=name,
                                   evidence=evidence), encoding="utf-8")
    return path


@pytest.mark.parametrize("verdict, said", [
    (POOR, True), ("good (every region within the bounds the blind round trips hold)", False),
    (None, False)])
def test_only_a_poor_twins_preset_is_said(tmp_path, verdict, said):
    preset = load_preset_file(_twin_preset(tmp_path, verdict))
    lines = poor_fit_lines([preset, preset, builtin_preset("eyrc"), "eyrc"])
    assert len(lines) == (1 if said else 0)  # said once, however often it comes
    if said:
        assert lines[0].startswith("warning: preset twin-lab is a twin whose fit is poor (poor:")
        assert len(lines[0]) < 300  # the verdict cut: the whole is in twin.json


@pytest.mark.integration
def test_eval_and_sweep_say_a_poor_twins_preset_first(tmp_path):
    preset = _twin_preset(tmp_path, POOR)
    made = run_cli("generate", "--preset", str(preset), "--count", "2", "--seed", "0",
                   "--workers", "1", "--no-progress", "--out", str(tmp_path / "set"))
    assert made.returncode == 0, made.stderr
    ran = run_cli("eval", str(tmp_path / "set"), "--pipeline", "reference", "--no-progress",
                  "--phase-check", "off")
    assert ran.returncode == 0, ran.stderr
    first = ran.stderr.splitlines()[0]
    assert first.startswith("arenabench eval: warning: preset twin-lab is a twin whose fit is "
                            "poor"), ran.stderr
    swept = run_cli("sweep", "--preset", str(preset), "--vary", "degrade.noise_sigma=0,2",
                    "--per-point", "1", "--pipeline", "reference", "--no-progress",
                    "--no-plots", "--out", str(tmp_path / "sweep"))
    assert swept.returncode == 0, swept.stderr
    assert swept.stderr.splitlines()[0].startswith("arenabench sweep: warning: preset "
                                                   "twin-lab is a twin whose fit is poor")
    good = _twin_preset(tmp_path, "good (every region within bounds)", name="twin-good")
    made = run_cli("generate", "--preset", str(good), "--count", "1", "--seed", "0",
                   "--workers", "1", "--no-progress", "--out", str(tmp_path / "good"))
    assert made.returncode == 0, made.stderr
    ran = run_cli("eval", str(tmp_path / "good"), "--pipeline", "reference", "--no-progress",
                  "--phase-check", "off")
    assert ran.returncode == 0 and "fit is poor" not in ran.stderr, ran.stderr
