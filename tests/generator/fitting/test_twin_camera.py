"""The twin's first steps, from the image alone: the markers (dictionary, ids, layout,
rotation) and the camera (fitted freely to the marker pixels, then snapped to round values)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from paths import ROOT

from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.fitting import camera_fit as cf
from arenabench.generator.fitting.markers import (
    DICTIONARIES,
    MarkersNotFoundError,
    detector_corner_offsets,
    detector_offset_text,
    find_markers,
)
from arenabench.generator.model import camera as cam
from arenabench.generator.model.scene import (
    ArenaSpec,
    CameraSpec,
    LightingSpec,
    MarkerSpec,
    Scene,
    load_scene,
)

IMAGE = ROOT / "tests" / "data" / "task1c_image.jpg"
SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"


@pytest.fixture(scope="module")
def example() -> np.ndarray:
    return cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE)


def test_the_examples_markers_are_found_in_every_dictionary_tried(example):
    found = find_markers(example)
    assert found.dictionary == "DICT_4X4_100"  # the smallest 4x4 dictionary holding id 95
    assert found.family == ("DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000")
    assert found.ids == (80, 85, 90, 95)
    assert found.rotation_deg == 180.0
    assert found.bit_errors == 0
    assert set(found.tried) == set(DICTIONARIES) and len(found.tried) >= 20


def test_no_markers_names_every_dictionary_tried():
    with pytest.raises(MarkersNotFoundError) as err:
        find_markers(np.full((300, 300), 240, np.uint8))
    message = str(err.value)
    assert "no ArUco markers found" in message
    for name in ("DICT_4X4_50", "DICT_7X7_1000", "DICT_APRILTAG_36h11", "DICT_ARUCO_ORIGINAL"):
        assert name in message


def test_two_markers_are_not_an_arena(example):
    half = example.copy()
    half[500:] = 248  # the south markers gone
    with pytest.raises(MarkersNotFoundError, match=r"found 2 marker\(s\) of DICT_4X4_100 "
                                                   r"\(ids 80, 85\), not four"):
        find_markers(half)


def test_the_default_detectors_corners_are_compared_in_whole_pixels(example):
    found = find_markers(example)
    same = detector_corner_offsets(example, found)
    assert same == {80: 0.0, 85: 0.0, 90: 0.0, 95: 0.0}
    assert detector_offset_text(same) == "at the same pixels"
    # the image moved by one pixel right and two down: every corner moves by sqrt(5) px
    moved = np.full_like(example, 248)
    moved[2:, 1:] = example[:-2, :-1]
    assert detector_corner_offsets(moved, found) == {k: round(5 ** 0.5, 3) for k in same}
    assert detector_offset_text(detector_corner_offsets(moved, found)).startswith("within 2.236 px")
    # one marker painted over: named, not a distance
    quad = found.detector_corners["se"]
    (x0, y0), (x1, y1) = quad.min(0).astype(int) - 4, quad.max(0).astype(int) + 4
    hidden = example.copy()
    hidden[y0:y1, x0:x1] = 248
    gone = detector_corner_offsets(hidden, found)
    assert gone[found.ids[2]] is None and gone[found.ids[0]] == 0.0
    assert detector_offset_text(gone) == (f"marker(s) {found.ids[2]} not found by the default "
                                          "detector")


def test_the_twins_report_says_what_the_detectors_corners_mean():
    from arenabench.generator.fitting.report import _detector_note

    assert "at the same pixels" in _detector_note({"80": 0.0, "85": 0.0})
    off = _detector_note({"80": 2.236, "85": 0.0})
    assert "class=warn" in off and "within 2.236 px (80: 2.236, 85: 0)" in off
    missed = _detector_note({"80": None, "85": 0.0})
    assert "class=warn" in missed and "marker(s) 80 not found" in missed


@pytest.mark.integration
@pytest.mark.parametrize(("dictionary", "ids", "rotation"), [
    ("DICT_5X5_250", (3, 17, 42, 199), 90.0),
    ("DICT_6X6_50", (0, 1, 2, 3), 0.0),
    ("DICT_APRILTAG_36h11", (5, 6, 7, 8), 270.0),
])
def test_other_dictionaries_ids_and_rotations(dictionary, ids, rotation):
    """A render with other markers, printed in another rotation, under a turned camera: the
    dictionary (the smallest of its family holding the ids), ids by corner and rotation."""
    from arenabench.generator.rendering.render import Renderer

    scene = Scene(arena=ArenaSpec(), markers=MarkerSpec(dictionary=dictionary, ids=ids,
                                                        side_m=0.5, rotation_deg=rotation),
                  obstacles=(), camera=CameraSpec(fov_deg=60.0, yaw_deg=12.0, tilt_deg=5.0))
    with Renderer() as r:
        gray = cv2.cvtColor(r.render(scene).rgb, cv2.COLOR_RGB2GRAY)
    found = find_markers(gray)
    assert found.ids == ids
    assert found.rotation_deg == rotation
    smallest = {"DICT_5X5_250": "DICT_5X5_250", "DICT_6X6_50": "DICT_6X6_50",
                "DICT_APRILTAG_36h11": "DICT_APRILTAG_36h11"}[dictionary]
    assert found.dictionary.upper() == smallest.upper()


def test_focal_length_from_a_homography():
    camera = CameraSpec(fov_deg=55.0, tilt_deg=20.0, yaw_deg=10.0, altitude_m=6.0)
    K, pose = cam.intrinsics(camera), cam.world_from_camera(camera)
    f = cf.focal_from_homography(cam.floor_homography(K, pose), K[0, 2], K[1, 2])
    assert f == pytest.approx(K[0, 0], rel=1e-9)


def test_round_angles():
    assert cf.round_angle(68.59, "rad", 0.1) == pytest.approx(68.754935, abs=1e-6)
    assert cf.round_angle(0.04, "deg", 5.0) == 0.0
    assert cf.round_angle(61.3, "deg", 1.0) == 61.0


class _FloorObjective(cf.Objective):
    """The image distance of floor points from those of a camera off round values, beside a
    large residual the camera does not move (a model unlike the image): 1 % of it is more
    than a third of a pixel's move."""

    def __init__(self, truth: CameraSpec) -> None:
        self.arena = ArenaSpec(side_m=8.0)
        self.width, self.height = truth.width, truth.height
        self.truth = cf.orbit_vector(truth)

    def residuals(self, v, extra):
        return np.concatenate([[300.0], self.floor_move_px(v, self.truth) * np.ones(4)])


def test_a_round_value_that_moves_the_floor_is_not_snapped():
    truth = CameraSpec(width=1000, height=1000, fov_deg=58.18, altitude_m=10.9, tilt_deg=14.3,
                       yaw_deg=-38.06, roll_deg=0.0)
    objective = _FloorObjective(truth)
    v = cf.orbit_vector(truth)
    rms = float(np.sqrt(np.mean(objective.residuals(v, np.zeros(0)) ** 2)))
    tilt = cf.ORBIT.index("tilt_deg")
    assert objective.floor_move_px(v, np.where(np.arange(7) == tilt, 14.0, v)) > 0.5
    _, _, snapped, _ = cf.snap_angles(objective, v, np.zeros(0), rms)
    assert "roll_deg" in snapped  # at a round value already
    assert not {"fov_deg", "tilt_deg", "yaw_deg"} & set(snapped), snapped


@pytest.mark.integration
def test_the_examples_camera_is_rediscovered(example):
    """From the markers alone (the competition texture's geometry given), the camera lands on
    the one that rendered the example: within 0.05 m and 0.1 deg of eyrc's, and with the
    renderer's refinement its round values (roll 0, 1.2 rad field of view, 1.5 rad pitch)."""
    from arenabench.generator.rendering.render import Renderer

    want = load_scene(SCENE).camera
    found = find_markers(example)
    arena = ArenaSpec(side_m=comp.ARENA_SIDE_M, margin_m=comp.ARENA_MARGIN_M,
                      texture=comp.TEXTURE_NAME, border_width_m=0.0, floor_rgb=(248,) * 3)
    markers = MarkerSpec(dictionary=found.dictionary, ids=found.ids, side_m=comp.MARKER_SIDE_M,
                         rotation_deg=found.rotation_deg)
    fit = cf.fit_camera(example, found, arena=arena, markers=markers, fit_marker_side=False)
    _assert_close(fit.camera, want)
    assert fit.snapped["fov_deg"] == ("rad", 1.2)
    mask = np.zeros(example.shape, bool)
    for quad in found.detector_corners.values():
        (x0, y0), (x1, y1) = np.floor(quad.min(0)).astype(int) - 8, np.ceil(quad.max(0)) + 8
        mask[y0:int(y1) + 1, x0:int(x1) + 1] = True
    scene = Scene(arena=arena, markers=markers, obstacles=(), camera=fit.camera,
                  lighting=LightingSpec(ambient=1.0, directional=()))
    with Renderer() as renderer:
        refined = cf.refine_with_renderer(fit, scene, example, mask, renderer)
    assert refined.snapped == {"roll_deg": ("rad", 0.0), "fov_deg": ("rad", 1.2),
                               "tilt_deg": ("rad", 1.5)}
    _assert_close(refined.camera, want, metres=0.002, degrees=0.005)


def _assert_close(got: CameraSpec, want: CameraSpec, *, metres: float = 0.05,
                  degrees: float = 0.1) -> None:
    a, b = cam.world_from_camera(got), cam.world_from_camera(want)
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) <= metres, (got, want)
    for name in ("fov_deg", "tilt_deg"):
        assert abs(getattr(got, name) - getattr(want, name)) <= degrees, (name, got, want)
    # heading and roll: the image's rotation (their difference at a small tilt) and each one
    angle = np.degrees(np.arccos(np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1, 1)))
    assert angle <= degrees, (angle, got, want)
    assert replace(got, target_m=want.target_m) is not None


def test_the_marker_models_blur_stops_at_a_module():
    """A fit that wanders to a huge blur (a photo's did, sigma 8e8 texels: its Gaussian kernel
    took 6 GB) gets the pattern blurred by a module, no more: flat enough to turn the fit
    back, and the same array whatever the blur beyond."""
    from arenabench.generator.fitting import marker_model as mm

    modules = mm.module_pattern("DICT_4X4_50", 7)
    most = mm._blurred_pattern(modules, mm.MAX_BLUR_MODULES * mm.TEXELS_PER_MODULE)
    huge = mm._blurred_pattern(modules, 8e8)
    assert huge.shape == most.shape and np.array_equal(huge, most)
    assert 0.2 < float(most.min()) and float(most.max()) < 1.0  # no module left black
