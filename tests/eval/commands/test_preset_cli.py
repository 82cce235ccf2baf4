"""``--preset FILE`` on the commands: the same bytes as the named preset, one line and exit
status 2 for a bad file before any work, ``dataset.json`` recording the preset (extending a
set with nothing but the set), arena textures from image files the set carries with it."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from clirun import run_cli
from paths import TESTS

from arenabench.generator.parameters.params import PARAMETERS, Range
from arenabench.generator.parameters.preset_files import (
    load_preset_file,
    preset_to_toml,
    write_preset_file,
)
from arenabench.generator.parameters.presets import PRESETS, builtin_preset, preset_key
from arenabench.usercache import CACHE_ENV

PIPELINES = TESTS / "pipelines"


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    """A cache folder of the test's own (textures are put there)."""
    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    return cache


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != ".arenabench.lock"}


def _same_files(a: Path, b: Path) -> None:
    fa, fb = _files(a), _files(b)
    assert sorted(fa) == sorted(fb)
    differ = [name for name in fa if fa[name] != fb[name]]
    assert not differ, differ


def _one_line_error(proc, *needles: str) -> str:
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _texture(path: Path, size=(300, 400)) -> Path:
    """A floor image: light grey with a coloured grid and a dark band along its north edge."""
    img = np.full((*size, 3), 230, np.uint8)
    img[::50, :] = (60, 110, 200)
    img[:, ::50] = (200, 90, 60)
    img[:12, :] = 40
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), img)
    return path


def _image_preset(folder: Path, *, texture: str = "floor/lab.png", **extra) -> Path:
    """A preset file in ``folder``: eyrc-jitter on an image texture named relative to it."""
    base = builtin_preset("eyrc-jitter")
    params = {**base.params, "arena.texture": "image", "arena.border_width_m": 0.0,
              "arena.logo_text": "", "arena.floor_rgb": (255, 255, 255),
              "arena.texture_size_m": (10.0, 7.5), "obstacles.count": Range(1, 2), **extra}
    text = preset_to_toml(params, name="lab", description="a lab floor",
                          evidence={"camera": "eyrc-jitter's"},
                          open={"lighting.azimuth_deg": {"range": [0.0, 360.0],
                                                         "reason": "one image"}})
    text = re.sub(r"^texture_file = .*$", f"texture_file = {json.dumps(texture)}", text,
                  flags=re.M)
    path = folder / "lab.toml"
    folder.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


# ------------------------------------------------------------------------ byte for byte


@pytest.mark.integration
@pytest.mark.parametrize("name", list(PRESETS))
def test_presets_show_writes_a_file_that_generates_the_same_bytes(name, tmp_path):
    toml = tmp_path / f"{name}.toml"
    proc = run_cli("presets", "--show", name, "--format", "toml")
    assert proc.returncode == 0, proc.stderr
    toml.write_text(proc.stdout, encoding="utf-8")
    common = ["--count", "2", "--seed", "0", "--workers", "1", "--no-progress"]
    a = run_cli("generate", "--preset", str(toml), "--out", str(tmp_path / "a"), *common)
    b = run_cli("generate", "--preset", name, "--out", str(tmp_path / "b"), *common)
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    _same_files(tmp_path / "a", tmp_path / "b")  # images, GT, manifest, coco, dataset.json
    meta = json.loads((tmp_path / "a" / "dataset.json").read_text())
    assert meta["preset"] == name and meta["preset_definition"]["preset"]["name"] == name


def test_presets_show_formats(tmp_path):
    text = run_cli("presets", "--show", "eyrc")
    assert text.returncode == 0 and len(text.stdout.splitlines()) == len(PARAMETERS)
    as_json = run_cli("presets", "--show", "warehouse", "--format", "json")
    doc = json.loads(as_json.stdout)
    assert doc["schema"] == "arenabench.preset/1" and doc["arena"]["texture"] == "concrete"
    path = tmp_path / "w.json"
    path.write_text(as_json.stdout)
    assert load_preset_file(path).params == builtin_preset("warehouse").params
    # a preset file shows as a name does
    shown = run_cli("presets", "--show", str(path), "--format", "toml")
    assert shown.stdout == run_cli("presets", "--show", "warehouse", "--format", "toml").stdout
    _one_line_error(run_cli("presets", "--format", "toml"), "--format needs --show")


# --------------------------------------------------------------- one line, before any work


def test_a_bad_preset_file_is_one_line_on_every_command(tmp_path):
    bad = tmp_path / "bad.toml"
    text = run_cli("presets", "--show", "eyrc", "--format", "toml").stdout
    bad.write_text(text.replace("tilt_deg = 4.056331", "tilt_deg = 95.0"))
    needle = f"preset file {bad}: camera.tilt_deg = 95.0: value 95.0 out of range [0, 79]"
    script = tmp_path / "map.py"
    script.write_text("print('never run')\n")
    out = tmp_path / "out"
    runs = {
        "generate": ("generate", "--preset", str(bad), "--count", "1", "--out", str(out)),
        "check": ("check", str(script), "--preset", str(bad), "--out", str(out)),
        "sweep": ("sweep", "--preset", str(bad), "--vary", "degrade.noise_sigma=0,1",
                  "--pipeline", "reference", "--out", str(out)),
        "contact-sheet": ("contact-sheet", "--preset", str(bad), "--out", str(out / "c.png")),
        "presets": ("presets", "--show", str(bad)),
    }
    for name, argv in runs.items():
        flag = "--show" if name == "presets" else "--preset"
        _one_line_error(run_cli(*argv), f"arenabench {name}: error: argument {flag}: {needle}")
        assert not out.exists(), name
    _one_line_error(run_cli("generate", "--preset", str(tmp_path / "gone.toml"), "--count",
                            "1", "--out", str(out)), "no such file")
    _one_line_error(run_cli("generate", "--preset", "eyrc-upriht", "--count", "1", "--out",
                            str(out)), "did you mean 'eyrc-upright'?")
    assert not out.exists()


def test_texture_problems_are_one_line(tmp_path):
    folder = tmp_path / "p"
    out = tmp_path / "out"

    def generate(path: Path, *extra: str):
        return run_cli("generate", "--preset", str(path), "--count", "1", "--out", str(out),
                       *extra)

    missing = _image_preset(folder, texture="nowhere.png")
    _one_line_error(generate(missing), f"preset file {missing}:",
                    'arena.texture_file = "nowhere.png":', "cannot read it")
    (folder / "text.png").write_text("not an image")
    _one_line_error(generate(_image_preset(folder, texture="text.png")),
                    'arena.texture_file = "text.png":', "not a PNG or JPEG image")
    _texture(folder / "floor/lab.png")
    good = _image_preset(folder)
    _one_line_error(generate(good, "--set", "arena.border_width_m=0.02"),
                    "arena.texture=image draws the image as it is: set arena.border_width_m=0")
    _one_line_error(generate(good, "--set", "arena.texture_size_m=0,3"),
                    "arena.texture=image needs arena.texture_size_m")
    _one_line_error(generate(good, "--set", "arena.texture=plain"),
                    "arena.texture_file and arena.texture_size_m need arena.texture=image")
    _one_line_error(generate(good, "--set", "arena.texture_size_m=3"),
                    "--set arena.texture_size_m: expected a width and a height")
    _one_line_error(generate(good, "--set", "arena.texture_file=gone.png"),
                    "--set arena.texture_file: gone.png: cannot read it")
    assert not out.exists()


# ------------------------------------------------------------------- dataset.json records it


def test_a_set_records_its_preset_and_open_table_and_refuses_another(tmp_path):
    folder = tmp_path / "p"
    _texture(folder / "floor/lab.png")
    preset = _image_preset(folder)
    out = tmp_path / "set"
    proc = run_cli("generate", "--preset", str(preset), "--count", "1", "--out", str(out),
                   "--workers", "1", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    meta = json.loads((out / "dataset.json").read_text())
    definition = meta["preset_definition"]
    assert definition["preset"] == {"name": "lab", "description": "a lab floor",
                                    "evidence": {"camera": "eyrc-jitter's"}}
    assert definition["open"] == {"lighting.azimuth_deg": {"range": [0.0, 360.0],
                                                           "reason": "one image"}}
    ref = definition["arena"]["texture_file"]
    assert re.fullmatch(r"textures/[0-9a-f]{64}\.png", ref)
    assert meta["files"]["textures"] == [ref] and (out / ref).is_file()
    assert meta["params"]["arena.texture_file"] == ref
    gt = json.loads((out / "gt" / "000000.json").read_text())
    assert gt["preset"] == "lab" and gt["scene"]["arena"]["texture_file"] == ref
    assert gt["scene"]["arena"]["texture_size_m"] == [10.0, 7.5]
    # the set's dataset.json is the preset it was made from
    again = load_preset_file(out / "dataset.json")
    assert again.params == load_preset_file(preset).params and again.open.keys() == {
        "lighting.azimuth_deg"}
    # a preset of the same name with other parameters does not extend it
    other = preset.read_text().replace("count = [1, 2]", "count = [1, 3]")
    preset.write_text(other)
    _one_line_error(run_cli("generate", "--preset", str(preset), "--count", "2", "--out",
                            str(out)),
                    f"{out} was generated from another preset 'lab': obstacles.count was "
                    "[1, 2], now [1, 3]")


@pytest.mark.integration
def test_a_set_needs_no_texture_file_afterwards(tmp_path, monkeypatch):
    """Generated from a preset file whose texture is a relative path; the file and the preset
    deleted and the cache emptied, the set is extended from its own dataset.json (the same
    bytes as making the larger set at once) and a GT scene is re-rendered from the GT alone,
    as the phase check does."""
    folder = tmp_path / "p"
    _texture(folder / "floor/lab.png")
    preset = _image_preset(folder)
    common = ["--seed", "0", "--workers", "1", "--no-progress"]
    whole = tmp_path / "whole"
    assert run_cli("generate", "--preset", str(preset), "--count", "3", "--out", str(whole),
                   *common).returncode == 0
    part = tmp_path / "part"
    assert run_cli("generate", "--preset", str(preset), "--count", "2", "--out", str(part),
                   *common).returncode == 0
    shutil.rmtree(folder)
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "empty-cache"))
    proc = run_cli("generate", "--preset", str(part / "dataset.json"), "--count", "3",
                   "--out", str(part), *common)
    assert proc.returncode == 0, proc.stderr
    assert "1 rendered; 2 already present" in proc.stdout
    _same_files(part, whole)
    # re-rendering a GT scene: the phase check, on a machine whose cache never saw it
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "other-machine"))
    from arenabench.eval.datasets.reader import load_dataset
    from arenabench.eval.phase_check import render_phases
    from arenabench.generator.dataset.make import worker_renderer
    from arenabench.generator.model.scene import Scene
    from arenabench.imageio import encode_png

    dataset = load_dataset(part)  # puts the set's textures/ into this cache
    item = dataset.samples[1]
    scene = Scene.from_dict(item.gt.to_dict()["scene"])
    rgb = worker_renderer().render(scene).rgb
    assert encode_png(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)) == (part / item.gt.image
                                                                ).read_bytes()
    phases = list(render_phases(item.gt, phases=2, folder=tmp_path))
    assert len(phases) == 2 and all(p.path.is_file() for p in phases)
    floor = cv2.imread(str(phases[0].path))
    assert floor is not None and floor.std() > 10  # the textured floor, not a blank one


@pytest.mark.integration
def test_cluster_workers_get_the_texture_with_their_tasks(tmp_path, monkeypatch):
    """Dask workers whose cache never saw the texture (as on another machine) render the same
    bytes as local workers: the tasks carry it."""
    import os
    import subprocess
    import sys

    distributed = pytest.importorskip("distributed")
    folder = tmp_path / "p"
    _texture(folder / "floor/lab.png")
    preset = _image_preset(folder)
    common = ["--count", "2", "--seed", "3", "--no-progress"]
    local = run_cli("generate", "--preset", str(preset), "--out", str(tmp_path / "local"),
                    "--workers", "1", *common)
    assert local.returncode == 0, local.stderr
    workers_cache = tmp_path / "workers-cache"
    monkeypatch.setenv(CACHE_ENV, str(workers_cache))  # what the worker processes inherit
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        proc = subprocess.run(
            [sys.executable, "-m", "arenabench", "generate", "--preset", str(preset), "--out",
             str(tmp_path / "dask"), "--scheduler", cluster.scheduler_address, *common],
            capture_output=True, text=True, timeout=300,
            env={**os.environ, CACHE_ENV: str(tmp_path / "client-cache")})
    assert proc.returncode == 0, proc.stderr
    _same_files(tmp_path / "dask", tmp_path / "local")
    ref = json.loads((tmp_path / "local" / "dataset.json").read_text())["files"]["textures"][0]
    assert (workers_cache / ref).is_file()


def test_a_scene_file_names_its_texture_relative_to_itself(tmp_path):
    from arenabench.generator.model.sampler import sample_scene

    folder = tmp_path / "p"
    _texture(folder / "floor/lab.png")
    scene = sample_scene(load_preset_file(_image_preset(folder)), seed=0, index=0).scene
    doc = scene.to_dict()
    ref = doc["arena"]["texture_file"]
    doc["arena"]["texture_file"] = "floor/lab.png"
    (folder / "scene.json").write_text(json.dumps(doc))
    proc = run_cli("render", str(folder / "scene.json"), "--out", str(tmp_path / "r"))
    assert proc.returncode == 0, proc.stderr
    gt = json.loads((tmp_path / "r" / "gt" / "000000.json").read_text())
    assert gt["scene"]["arena"]["texture_file"] == ref
    doc["arena"]["texture_file"] = "floor/none.png"
    (folder / "scene.json").write_text(json.dumps(doc))
    _one_line_error(run_cli("render", str(folder / "scene.json"), "--out",
                            str(tmp_path / "r2")), "none.png: cannot read it")


def test_a_written_preset_carries_its_texture(tmp_path):
    folder = tmp_path / "p"
    _texture(folder / "floor/lab.png")
    loaded = load_preset_file(_image_preset(folder))
    out = write_preset_file(tmp_path / "copy" / "lab.toml", loaded.params, name="lab")
    ref = loaded.params["arena.texture_file"]
    assert (out.parent / ref).read_bytes() == (folder / "floor/lab.png").read_bytes()
    shutil.rmtree(folder)
    assert load_preset_file(out).params == loaded.params


def test_phase_images_keep_the_jpeg_quality_of_a_preset_file(tmp_path):
    """A JPEG set whose quality is not the built-in preset's (a preset file): the phase check
    writes its re-rendered images at the original's quality, read from its tables."""
    from arenabench.eval.datasets.reader import load_dataset
    from arenabench.eval.evaluation import evaluate
    from arenabench.eval.phase_check import check_phases
    from arenabench.eval.scoring.results import Prediction
    from arenabench.generator.dataset.dataset_writer import generate_dataset
    from arenabench.imageio import jpeg_quality

    p = builtin_preset("eyrc")
    preset = load_preset_file(write_preset_file(
        tmp_path / "q80.toml", {**p.params, "output.jpeg_quality": 80}, name="q80"))
    generate_dataset(tmp_path / "set", preset=preset, count=1, seed=0, workers=1,
                     progress=False)
    dataset = load_dataset(tmp_path / "set")
    image = tmp_path / "set" / dataset.samples[0].gt.image
    assert jpeg_quality(image.read_bytes()) == 80
    report = evaluate(lambda bgr: {"count": 99, "area": 1.0, "marker_ids": [80, 85, 90, 95]},
                      dataset, workers=1, phases=0)
    seen = []

    def run(path):
        seen.append(jpeg_quality(path.read_bytes()))
        return Prediction(status="ok", count=99, area=1.0)

    checked = check_phases(list(report.images), [s.gt for s in dataset.samples], run,
                           phases=2, tolerance=0.05, area_reference="visible")
    assert checked[0].phase is not None and seen == [80, 80]


# ------------------------------------------------------------------- check, sweep, plugin


@pytest.mark.integration
def test_check_takes_a_preset_file(tmp_path, own_cache):
    preset = tmp_path / "two.toml"
    p = builtin_preset("eyrc")
    write_preset_file(preset, {**p.params, "obstacles.count": 2}, name="eyrc",
                      description=p.description)
    key = preset_key(load_preset_file(preset))
    assert key.startswith("eyrc-") and key != "eyrc"
    proc = run_cli("check", str(PIPELINES / "style_blur127.py"), "--preset", str(preset),
                   "--count", "3", "--python", "{python}", "--phase-check", "off",
                   "--out", str(tmp_path / "report"), "--no-progress")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "of eyrc, seed 0" in proc.stdout
    sets = list((own_cache / "sets").iterdir())
    assert [s.name.rsplit("-", 1)[0] for s in sets] == [f"{key}-0-3"], sets
    twin = sets[0]
    for gt_file in sorted((twin / "gt").glob("*.json")):
        assert json.loads(gt_file.read_text())["count"] == 2
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    assert report["summary"]["n"] == 3


@pytest.mark.integration
def test_sweep_takes_a_preset_file(tmp_path, monkeypatch):
    preset = _image_preset(tmp_path / "p")
    _texture(tmp_path / "p" / "floor/lab.png")
    out = tmp_path / "sweep"
    proc = run_cli("sweep", "--preset", str(preset), "--vary", "degrade.noise_sigma=0,4",
                   "--per-point", "2", "--pipeline", "reference", "--workers", "1",
                   "--no-plots", "--out", str(out), "--no-progress")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["preset"] == "lab"
    assert doc["preset_definition"]["arena"]["texture"] == "image"
    assert sum(p["summary"]["n"] for p in doc["points"]) == 4
    # read back without the preset file or a cache that saw its texture: the same sweep.json
    shutil.rmtree(tmp_path / "p")
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "elsewhere"))
    from arenabench.eval.sweep.outputs import load_sweep, write_sweep

    write_sweep(load_sweep(out), tmp_path / "again", plots=False)
    assert (tmp_path / "again" / "sweep.json").read_bytes() == (out / "sweep.json").read_bytes()


def test_pytest_plugin_keys_a_preset_file_by_name_and_parameters(tmp_path):
    from arenabench.eval.pytest_plugin import dataset_key
    from arenabench.generator.dataset.make import GENERATOR_VERSION

    path = tmp_path / "mine.toml"
    p = builtin_preset("eyrc")
    write_preset_file(path, {**p.params, "obstacles.count": 3}, name="mine")
    assert re.fullmatch(rf"mine-[0-9a-f]{{10}}-n4-s0-v{GENERATOR_VERSION}",
                        dataset_key(str(path), 4, 0))
    assert dataset_key("eyrc", 4, 0) == f"eyrc-n4-s0-v{GENERATOR_VERSION}"
    with pytest.raises(pytest.UsageError, match="--arenabench-preset: unknown preset"):
        dataset_key("nope", 4, 0)
