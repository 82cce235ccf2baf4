"""Camera geometry: intrinsics, pose, projection, and the one OpenCV <-> OpenGL conversion.

Conventions
-----------
- OpenCV camera: x right, y down, z forward (the optical axis); pixel centres at integer
  coordinates. Every matrix this module returns uses it.
- ``world_from_camera`` is the 4x4 pose of the camera (columns: camera axes in world, then C).
- pyrender (OpenGL) looks down its -z with +y up, and its pixel centres sit at half-integers:
  :func:`gl_pose` and :func:`gl_intrinsics` are the only places where that is handled.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from arenabench.generator.model.scene import CameraSpec

#: OpenCV camera axes (x right, y down, z forward) of a nadir camera with heading 0.
_NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
#: Flip of the y and z axes between the OpenCV and OpenGL camera frames.
_CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


def _rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def intrinsics(camera: CameraSpec) -> np.ndarray:
    """The 3x3 intrinsic matrix K (OpenCV convention).

    ``camera.K`` when given, else square pixels from the vertical field of view with the
    principal point at the image centre ((W - 1) / 2, (H - 1) / 2).
    """
    if camera.K is not None:
        return np.array(camera.K, dtype=np.float64)
    f = (camera.height / 2.0) / math.tan(math.radians(camera.fov_deg) / 2.0)
    return np.array(
        [[f, 0.0, (camera.width - 1) / 2.0], [0.0, f, (camera.height - 1) / 2.0], [0, 0, 1.0]]
    )


def world_from_camera(camera: CameraSpec) -> np.ndarray:
    """The camera's 4x4 pose in the world (OpenCV camera axes).

    Orbit form: ``R = Rz(yaw) Rx(tilt) R_nadir Rz_cam(roll)`` and the camera centre sits on the
    optical axis through ``target_m`` at height ``altitude_m``. Look-at form: the optical axis
    runs from ``eye_m`` to ``look_at_m``, image up as close to north (+y) as possible, then
    ``roll_deg`` about the optical axis.
    """
    roll = _rot_z(camera.roll_deg)
    if camera.eye_m is not None:
        eye = np.array(camera.eye_m, dtype=np.float64)
        z = np.array(camera.look_at_m, dtype=np.float64) - eye
        norm = np.linalg.norm(z)
        if norm == 0:
            raise ValueError("camera.eye_m and camera.look_at_m must differ")
        z /= norm
        up = np.array([0.0, 1.0, 0.0])
        if abs(z @ up) > 0.999:
            up = np.array([0.0, 0.0, 1.0])
        x = np.cross(z, up)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        rot = np.stack([x, y, z], axis=1) @ roll
        centre = eye
    else:
        rot = _rot_z(camera.yaw_deg) @ _rot_x(camera.tilt_deg) @ _NADIR @ roll
        axis = rot @ np.array([0.0, 0.0, 1.0])
        if axis[2] >= 0:
            raise ValueError(f"camera.tilt_deg={camera.tilt_deg}: the camera must look down")
        target = np.array([camera.target_m[0], camera.target_m[1], 0.0])
        centre = target - axis * (camera.altitude_m / -axis[2])
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = centre
    return pose


def gl_pose(pose_cv: np.ndarray) -> np.ndarray:
    """Convert an OpenCV ``world_from_camera`` pose to pyrender's (OpenGL) camera pose."""
    return np.asarray(pose_cv, dtype=np.float64) @ _CV_TO_GL


def gl_intrinsics(K: np.ndarray) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) for ``pyrender.IntrinsicsCamera`` reproducing OpenCV's ``K``.

    OpenGL window coordinates put pixel centres at half-integers, OpenCV at integers.
    """
    return float(K[0, 0]), float(K[1, 1]), float(K[0, 2]) + 0.5, float(K[1, 2]) + 0.5


def rvec_tvec(pose_cv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rvec, tvec) of the camera-from-world transform, as cv2.projectPoints expects."""
    import cv2

    r_wc = pose_cv[:3, :3]
    r_cw = r_wc.T
    t_cw = -r_cw @ pose_cv[:3, 3]
    rvec, _ = cv2.Rodrigues(r_cw)
    return rvec.reshape(3), t_cw


def project(points_world: np.ndarray, K: np.ndarray, pose_cv: np.ndarray) -> np.ndarray:
    """Project (N, 3) world points to (N, 2) image px (pinhole, no distortion).

    Points must lie in front of the camera.
    """
    pts = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    r_cw = pose_cv[:3, :3].T
    cam = (pts - pose_cv[:3, 3]) @ r_cw.T
    if np.any(cam[:, 2] <= 1e-9):
        raise ValueError("project: a point lies behind the camera")
    uvw = cam @ np.asarray(K, dtype=np.float64).T
    return uvw[:, :2] / uvw[:, 2:3]


def floor_homography(K: np.ndarray, pose_cv: np.ndarray) -> np.ndarray:
    """3x3 homography from floor coordinates (x, y, 1) at z = 0 to image px: K [r1 r2 t]."""
    r_cw = pose_cv[:3, :3].T
    t_cw = -r_cw @ pose_cv[:3, 3]
    return np.asarray(K, dtype=np.float64) @ np.column_stack([r_cw[:, 0], r_cw[:, 1], t_cw])


def camera_from_pose(
    pose: np.ndarray, *, fov_deg: float, width: int, height: int
) -> CameraSpec:
    """An orbit-form :class:`CameraSpec` reproducing an OpenCV ``world_from_camera`` pose.

    Intrinsics: square pixels, centred principal point, vertical field of view ``fov_deg``.
    ``target_m`` is where the optical axis meets the floor, ``altitude_m`` the camera's
    height, ``tilt_deg`` and ``yaw_deg`` the axis' angle from the nadir and its heading, and
    ``roll_deg`` the rest of the rotation (the same parameters as the presets').
    """
    eye = pose[:3, 3]
    axis = pose[:3, 2] / np.linalg.norm(pose[:3, 2])
    look_at = eye + axis * (eye[2] / max(-axis[2], 1e-9))
    tilt = math.degrees(math.acos(float(np.clip(-axis[2], -1.0, 1.0))))
    yaw = math.degrees(math.atan2(-axis[0], axis[1])) if tilt > 1e-9 else 0.0
    base = CameraSpec(width=width, height=height, fov_deg=round(float(fov_deg), 6),
                      altitude_m=round(float(eye[2]), 6), tilt_deg=round(tilt, 6),
                      yaw_deg=round(yaw, 6),
                      target_m=tuple(round(float(c), 6) for c in look_at[:2]))
    r0 = world_from_camera(base)[:3, :3]
    m = r0.T @ pose[:3, :3]
    roll = math.degrees(math.atan2(m[1, 0], m[0, 0]))
    return replace(base, roll_deg=round(roll, 6))
