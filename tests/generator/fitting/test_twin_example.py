"""``arenabench twin`` on the competition's published example, given the competition's texture,
reproduces ``eyrc``'s preset file (generator/assets/presets/eyrc.toml, its only source): the
camera, the greys, the edges and the JPEG settings, and the camera the competition's world
file puts there (generator/fitting/competition_world.py). The hand-found facts are evidence the twin
finds again from the image. Given no texture, only the floor's size, it finds the same camera
and matches the example's marker squares within the same bound."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from paths import ROOT

from arenabench.generator.fitting.competition_world import competition_camera
from arenabench.generator.model import camera as cam
from arenabench.generator.model.scene import CameraSpec
from arenabench.generator.parameters.preset_files import load_preset_file
from arenabench.generator.parameters.presets import PRESET_FILES

IMAGE = ROOT / "tests" / "data" / "task1c_image.jpg"
TEXTURE = ROOT / "generator" / "assets" / "arena_texture.png"
#: The bounds the twin is held to: camera position (m) and angles (deg), greys (levels), the
#: marker squares of the fitted scene's render (mean absolute grey difference).
METRES, DEGREES, GREYS, MARKER_SQUARES = 0.05, 0.1, 2, 1.0

# the module's twins are built once: its tests stay on one worker of make acceptance
pytestmark = [pytest.mark.acceptance, pytest.mark.xdist_group("twin_example")]


@pytest.fixture(scope="module")
def twin(tmp_path_factory) -> Path:
    """The twin of the example with the competition's texture, as a user makes it."""
    out = tmp_path_factory.mktemp("twin") / "example"
    proc = subprocess.run([sys.executable, "-m", "arenabench", "twin", str(IMAGE), "--out",
                           str(out), "--texture", str(TEXTURE), "--arena-size", "3.7,3.7",
                           "--no-progress"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def own(tmp_path_factory) -> Path:
    """The twin of the example given no texture, only the floor's size (its markers painted
    into a texture rectified from the image)."""
    out = tmp_path_factory.mktemp("twin") / "own"
    proc = subprocess.run([sys.executable, "-m", "arenabench", "twin", str(IMAGE), "--out",
                           str(out), "--arena-size", "3.7,3.7"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    (out.parent / "own.log").write_text(proc.stderr)  # its log, read by a test below
    return out


@pytest.fixture(scope="module")
def params(twin) -> dict:
    return load_preset_file(twin / "preset.toml").params


@pytest.fixture(scope="module")
def eyrc() -> dict:
    return load_preset_file(PRESET_FILES["eyrc"]).params


def _camera(p: dict) -> CameraSpec:
    return CameraSpec(width=p["camera.width"], height=p["camera.height"],
                      fov_deg=p["camera.fov_deg"], altitude_m=p["camera.altitude_m"],
                      tilt_deg=p["camera.tilt_deg"], yaw_deg=p["camera.yaw_deg"],
                      roll_deg=p["camera.roll_deg"],
                      target_m=(p["camera.target_x_m"], p["camera.target_y_m"]))


def _apart(a: CameraSpec, b: CameraSpec) -> tuple[float, float]:
    """Distance (m) between the two cameras' centres and the angle (deg) between their
    orientations."""
    pa, pb = cam.world_from_camera(a), cam.world_from_camera(b)
    turn = (np.trace(pa[:3, :3].T @ pb[:3, :3]) - 1) / 2
    return (float(np.linalg.norm(pa[:3, 3] - pb[:3, 3])),
            math.degrees(math.acos(float(np.clip(turn, -1, 1)))))


@pytest.mark.parametrize("source", ["eyrc.toml", "competition_world"])
def test_the_camera_is_eyrcs_and_the_world_files(params, eyrc, source):
    want = _camera(eyrc) if source == "eyrc.toml" else competition_camera()
    got = _camera(params)
    metres, degrees = _apart(got, want)
    assert metres <= METRES and degrees <= DEGREES, (metres, degrees, got, want)
    assert abs(got.fov_deg - want.fov_deg) <= DEGREES
    assert abs(got.tilt_deg - want.tilt_deg) <= DEGREES


def test_the_greys_are_eyrcs(twin, params, eyrc):
    for key in ("arena.floor_rgb", "background.gray", "obstacles.gray"):
        got, want = np.atleast_1d(params[key]), np.atleast_1d(eyrc[key])
        assert np.abs(got.astype(float) - want).max() <= GREYS, (key, got, want)
    faces = {f["direction"]: f["gray"] for f in json.loads((twin / "twin.json").read_text())
             ["shades"]["faces"]}
    assert abs(faces["south"] - 71) <= GREYS and abs(faces["north"] - 100) <= GREYS, faces


def test_the_edges_and_the_file_are_eyrcs(params, eyrc):
    for key in ("render.edge_samples", "render.edge_resolve", "output.format",
                "output.jpeg_quality", "output.jpeg_subsampling", "markers.dictionary",
                "markers.ids", "markers.rotation_deg", "arena.texture"):
        assert params[key] == eyrc[key], (key, params[key], eyrc[key])


def test_the_fitted_scene_matches_the_examples_marker_squares(twin):
    figures = json.loads((twin / "twin.json").read_text())["figures"]
    assert figures["mad"]["markers"] <= MARKER_SQUARES, figures


def test_the_default_detector_sees_the_markers_at_the_examples_pixels(twin):
    """Scripts that warp from the default detector's whole-pixel corners see the example's
    frame on the twin's render."""
    figures = json.loads((twin / "twin.json").read_text())["figures"]
    assert figures["detector_corners_px"] == {"80": 0.0, "85": 0.0, "90": 0.0, "95": 0.0}
    assert "at the same pixels" in (twin / "report.html").read_text()


def test_the_box_ranges_are_eyrcs(params, eyrc):
    """What varies, drawn around the example's two boxes, lands on the ranges found by hand
    from the competition's world files."""
    for key in ("obstacles.count", "obstacles.length_m", "obstacles.width_m",
                "obstacles.height_m", "obstacles.yaw_deg", "obstacles.yaw_step_deg",
                "obstacles.min_gap_m", "obstacles.edge_margin_m"):
        assert params[key] == eyrc[key], (key, params[key], eyrc[key])


def test_the_field_of_view_is_varied_with_the_camera_that_keeps_the_markers(twin, params):
    """The example leaves the field of view open but pins its trade with the altitude (and
    the tilt): the preset's fov entry names what moves with it, so a variant at either end
    keeps the markers where the example has them, which the field of view alone does not;
    the altitude, open too, is not varied on its own."""
    from arenabench.frame import CORNER_ORDER
    from arenabench.generator.model.layout import marker_corners_world
    from arenabench.generator.model.scene import load_scene

    entry = load_preset_file(twin / "preset.toml").open["camera.fov_deg"]
    assert dict(entry.moves_with).keys() >= {"camera.altitude_m", "camera.tilt_deg"}
    scene = load_scene(twin / "scene.json")
    world = np.vstack([np.c_[marker_corners_world(scene.arena, scene.markers, c), np.zeros(4)]
                       for c in CORNER_ORDER])

    def corners(p: dict) -> np.ndarray:
        c = _camera(p)
        return cam.project(world, cam.intrinsics(c), cam.world_from_camera(c))

    base = corners(params)
    for end in (entry.range.lo, entry.range.hi):
        alone = np.linalg.norm(corners({**params, "camera.fov_deg": end}) - base, axis=1)
        moved = np.linalg.norm(corners({**params, "camera.fov_deg": end, **entry.at(end)})
                               - base, axis=1)
        assert alone.max() > 2.0 and moved.max() < 0.5, (end, alone.max(), moved.max())


@pytest.mark.parametrize("source", ["eyrc.toml", "competition_world"])
def test_without_a_texture_the_camera_is_eyrcs(own, eyrc, source):
    want = _camera(eyrc) if source == "eyrc.toml" else competition_camera()
    got = _camera(load_preset_file(own / "preset.toml").params)
    metres, degrees = _apart(got, want)
    assert metres <= METRES and degrees <= DEGREES, (metres, degrees, got, want)
    assert abs(got.fov_deg - want.fov_deg) <= DEGREES


def test_without_a_texture_the_fitted_scene_matches_the_examples_marker_squares(own):
    """The markers painted into the rectified texture, on the texel grid the image picks and
    under the camera refined on their render."""
    figures = json.loads((own / "twin.json").read_text())["figures"]
    assert figures["mad"]["markers"] <= MARKER_SQUARES, figures
    assert figures["detector_corners_px"] == {"80": 0.0, "85": 0.0, "90": 0.0, "95": 0.0}


def test_the_log_says_lengths_in_the_presets_metres_and_tilt_in_degrees(own):
    """Without a texture the size is known only once the floor's edge is placed: the log says
    the camera's height in arena sides until then, and metres of the preset after."""
    log = (own.parent / "own.log").read_text()
    p = load_preset_file(own / "preset.toml").params
    texture = re.search(r"twin: texture: .* camera ([0-9.]+) m up, marker side ([0-9.]+) m",
                        log)
    assert texture, log
    assert float(texture.group(1)) == pytest.approx(p["camera.altitude_m"], rel=0.02)
    assert float(texture.group(2)) == pytest.approx(p["markers.side_m"], rel=0.02)
    camera = re.search(r"twin: camera: .*, ([0-9.]+) arena sides up", log)
    assert camera, log
    for line in re.findall(r"tilt_deg snapped to .*", log):
        assert re.fullmatch(r"tilt_deg snapped to [-0-9.]+ deg \(pitch [-0-9.e]+ (rad|deg)\)",
                            line), line
    records = re.search(r"(\d+) open \((\d+) in the preset's \[open\] table: ([^;]+);", log)
    assert records, log
    named = records.group(3).split(", ")
    assert len(named) == int(records.group(2)) <= int(records.group(1))
    assert set(named) == set(load_preset_file(own / "preset.toml").open)


@pytest.mark.parametrize("which", ["twin", "own"])
def test_the_examples_twins_are_good(which, request):
    """The example's twins, with and without the texture, hold every bound: verdict good, in
    twin.json, the preset's evidence and first in the report."""
    folder = request.getfixturevalue(which)
    doc = json.loads((folder / "twin.json").read_text())
    assert doc["verdict"]["verdict"] == "good" and doc["verdict"]["off"] == [], doc["verdict"]
    preset = load_preset_file(folder / "preset.toml")
    assert preset.evidence["verdict"].startswith("good") and preset.poor_fit is None
    html = (folder / "report.html").read_text()
    assert html.index("Fit: good") < html.index("Region by region")


def test_a_blurred_example_is_a_poor_twin_that_names_the_blur(tmp_path):
    """The example blurred (Gaussian, sigma 3), with its texture: the twin is written, its
    verdict poor with the marker squares off and blur named, exit 6; --accept-poor-fit 0."""
    import cv2

    blurred = tmp_path / "blurred.png"
    cv2.imwrite(str(blurred), cv2.GaussianBlur(cv2.imread(str(IMAGE)), (0, 0), 3))
    argv = [sys.executable, "-m", "arenabench", "twin", str(blurred), "--texture",
            str(TEXTURE), "--arena-size", "3.7,3.7", "--no-progress"]
    proc = subprocess.run([*argv, "--out", str(tmp_path / "t")], capture_output=True,
                          text=True)
    assert proc.returncode == 6, proc.stderr
    doc = json.loads((tmp_path / "t" / "twin.json").read_text())
    verdict = doc["verdict"]
    assert verdict["verdict"] == "poor"
    assert "marker squares" in {o["figure"] for o in verdict["off"]}
    assert any(c["kind"] == "blur" for c in verdict["causes"]), verdict
    assert proc.stdout.splitlines()[0].startswith("twin twin-blurred: fit: poor: marker squares")
    assert doc["parameters"]["degrade.defocus_px"]["status"] == "open"
    assert "blur" in doc["parameters"]["degrade.defocus_px"]["reason"]
    assert load_preset_file(tmp_path / "t" / "preset.toml").poor_fit is not None
    accepted = subprocess.run([*argv, "--out", str(tmp_path / "a"), "--accept-poor-fit"],
                              capture_output=True, text=True)
    assert accepted.returncode == 0, accepted.stderr
