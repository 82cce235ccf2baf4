"""The competition's Gazebo world (generator/fitting/competition_world.py): the camera that
rendered the
example, read from its mount, and boxes on the world files' grid."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from paths import ROOT

from arenabench.generator.fitting import competition_world as world
from arenabench.generator.fitting.scene_fit import FitOptions, fit_scene
from arenabench.generator.model import camera as cam
from arenabench.generator.model.scene import Obstacle, load_scene

SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"
IMAGE = ROOT / "tests" / "data" / "task1c_image.jpg"


def _to_world(xy) -> np.ndarray:
    """Package floor metres -> Gazebo world metres (x, y)."""
    yaw = world.ARENA_MODEL_POSE[5]
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = (v * world.ARENA_MESH_SCALE for v in xy)
    return np.array([c * x - s * y, s * x + c * y])


def test_camera_sits_on_its_mount():
    """The pose is the mount's, read in the arena's frame: 20 m up plus the link offset turned
    by 1.5 rad of pitch, minus the arena's 0.02 m; 4.06 deg from the nadir, tilted towards the
    world's +x (the arena's north, the arena being turned by -1.57 rad)."""
    pose = world.competition_pose()
    centre_world = _to_world(pose[:2, 3])
    assert centre_world == pytest.approx([0.0534, 0.05], abs=1e-3)
    assert pose[2, 3] * world.ARENA_MESH_SCALE == pytest.approx(19.934, abs=1e-3)
    camera = world.competition_camera()
    assert camera.tilt_deg == pytest.approx(math.degrees(math.pi / 2 - 1.5), abs=1e-5)
    assert camera.fov_deg == pytest.approx(math.degrees(1.2), abs=1e-5)
    assert camera.target_m[1] > pose[1, 3]  # the axis leans north
    assert abs(camera.roll_deg) < 1e-6


def test_example_scene_uses_the_competition_camera():
    assert load_scene(SCENE).camera == world.competition_camera()


def test_camera_puts_the_markers_on_the_examples_corners():
    """The texture's marker corners, projected, fall within 1.1 px RMS of cv2.aruco's sub-pixel
    corners on the example (the corners of a rendered marker come out the same way)."""
    from arenabench.generator.fitting.camera_fit import world_corners as _world_points
    from arenabench.generator.fitting.scene_fit import detect_marker_corners

    scene = load_scene(SCENE)
    corners = detect_marker_corners(cv2.imread(str(IMAGE)), scene.markers)
    got = np.vstack(list(corners.values()))
    proj = cam.project(_world_points(scene.arena, scene.markers),
                       cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera))
    assert float(np.sqrt(np.mean(np.sum((proj - got) ** 2, axis=1)))) <= 1.1


def test_example_boxes_are_on_the_world_grid():
    """Both boxes, read in Gazebo metres: (3, 3) 2 x 5 and (-7, -3) 2 x 4, 1.5 m above the arena,
    axis-aligned in the world."""
    boxes = load_scene(SCENE).obstacles
    want = [((3.0, 3.0), 5.0, 2.0), ((-7.0, -3.0), 4.0, 2.0)]
    for box, (centre, length, width) in zip(boxes, want, strict=True):
        assert _to_world(box.center_m) == pytest.approx(centre, abs=1e-4)
        s = world.ARENA_MESH_SCALE
        assert (box.length_m * s, box.width_m * s, box.height_m * s) == pytest.approx(
            (length, width, 1.5), abs=1e-4)
        assert (box.yaw_deg + math.degrees(world.ARENA_MODEL_POSE[5])) % 90.0 == pytest.approx(
            0.0, abs=1e-5)
        assert world.snap_obstacle(box) == box  # on the grid already


def test_snap_rounds_in_world_metres():
    s = world.ARENA_MESH_SCALE
    box = Obstacle(center_m=(-2.96 / s, 3.07 / s), yaw_deg=1.0, length_m=4.8 / s,
                   width_m=0.1 / s, height_m=1.6 / s)
    snapped = world.snap_obstacle(box)
    assert _to_world(snapped.center_m) == pytest.approx((3.0, 3.0), abs=1e-4)
    assert snapped.length_m * s == pytest.approx(5.0, abs=1e-4)
    assert snapped.width_m * s == pytest.approx(0.5, abs=1e-4)  # never 0
    assert snapped.height_m * s == pytest.approx(1.5, abs=1e-4)
    assert snapped.yaw_deg == pytest.approx(-math.degrees(world.ARENA_MODEL_POSE[5]) - 90.0,
                                            abs=1e-6)


def test_known_camera_of_another_size_is_refused():
    camera = replace(world.competition_camera(), width=800)
    with pytest.raises(ValueError, match="known camera 800 x 1000"):
        fit_scene(cv2.imread(str(IMAGE)), options=FitOptions(camera=camera))


@pytest.mark.integration
def test_fit_writes_the_shipped_example():
    """``arenabench fit`` (the known camera, boxes snapped when the render gets closer) gives
    the shipped scene's camera and boxes."""
    result = fit_scene(cv2.imread(str(IMAGE)), options=FitOptions(
        camera=world.competition_camera(), snap=world.snap_obstacle))
    shipped = load_scene(SCENE)
    assert result.scene.camera == shipped.camera
    assert result.scene.obstacles == shipped.obstacles
    assert result.ssim >= 0.998  # measured 0.9990
