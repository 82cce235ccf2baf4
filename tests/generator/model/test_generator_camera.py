"""Camera geometry against OpenCV: projection, poses, the OpenGL conversion, the homography."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import reference_corners_world
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.model.scene import CameraSpec
from arenabench.generator.truth.groundtruth import image_to_frame_homography

POSES = [
    CameraSpec(),
    CameraSpec(tilt_deg=25, yaw_deg=40, roll_deg=5, target_m=(0.5, -0.3), altitude_m=9),
    CameraSpec(width=640, height=480, fov_deg=50, tilt_deg=10, yaw_deg=-170),
    CameraSpec(width=1920, height=1080, K=((1500, 0, 950), (0, 1490, 545), (0, 0, 1)),
               tilt_deg=5),
    CameraSpec(eye_m=(1.0, -6.0, 7.0), look_at_m=(0.0, 0.0, 0.0)),
]


@pytest.mark.parametrize("spec", POSES)
def test_project_matches_cv2_project_points(spec):
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-4, 4, (50, 2)), rng.uniform(0, 1, 50)])
    K, pose = cam.intrinsics(spec), cam.world_from_camera(spec)
    rvec, tvec = cam.rvec_tvec(pose)
    ref, _ = cv2.projectPoints(pts, rvec, tvec, K, np.zeros(5))
    np.testing.assert_allclose(cam.project(pts, K, pose), ref.reshape(-1, 2), atol=1e-7)


@pytest.mark.parametrize("spec", POSES)
def test_pose_is_a_rotation_above_the_floor(spec):
    pose = cam.world_from_camera(spec)
    r = pose[:3, :3]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert pose[2, 3] > 0
    assert r[2, 2] < 0  # the optical axis points down


def test_orbit_pose_conventions():
    nadir = cam.world_from_camera(CameraSpec(altitude_m=5))
    np.testing.assert_allclose(nadir[:3, 3], [0, 0, 5], atol=1e-12)
    np.testing.assert_allclose(nadir[:3, 0], [1, 0, 0], atol=1e-12)  # image x = east
    np.testing.assert_allclose(nadir[:3, 1], [0, -1, 0], atol=1e-12)  # image down = south
    tilted = cam.world_from_camera(CameraSpec(altitude_m=5, tilt_deg=30, target_m=(0, 0)))
    # tilted towards north: camera south of the target, optical axis through it
    assert tilted[1, 3] == pytest.approx(-5 * np.tan(np.radians(30)))
    axis = tilted[:3, 2]
    hit = tilted[:3, 3] + axis * (tilted[2, 3] / -axis[2])
    np.testing.assert_allclose(hit, [0, 0, 0], atol=1e-12)


def test_gl_pose_flips_y_and_z_only():
    pose = cam.world_from_camera(POSES[1])
    gl = cam.gl_pose(pose)
    np.testing.assert_allclose(gl[:3, 0], pose[:3, 0])
    np.testing.assert_allclose(gl[:3, 1], -pose[:3, 1])
    np.testing.assert_allclose(gl[:3, 2], -pose[:3, 2])
    np.testing.assert_allclose(gl[:3, 3], pose[:3, 3])


def test_homography_sends_reference_corners_to_frame_corners():
    sc = sample_scene("eyrc", seed=0, index=3).scene
    K, pose = cam.intrinsics(sc.camera), cam.world_from_camera(sc.camera)
    ref = reference_corners_world(sc.arena, sc.markers)
    img = cam.project(np.column_stack([ref, np.zeros(4)]), K, pose)
    H = image_to_frame_homography(sc)
    out = cv2.perspectiveTransform(img.reshape(-1, 1, 2), H).reshape(-1, 2)
    np.testing.assert_allclose(out, [[0, 0], [1000, 0], [1000, 1000], [0, 1000]], atol=1e-6)
