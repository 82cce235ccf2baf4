"""The competition's Gazebo world: the camera that rendered the example, and boxes in its metres.

The public world files (``swift_pico/worlds/*.sdf`` of
eYantra-Robotics-Competition/eyrc-24-25-warehouse-drone) mount the static camera as model pose
``0 0 20 0 1.57 0`` with a link offset ``0.05 0.05 0.05`` and ``horizontal_fov`` 1.047, and place
the arena model at ``0 0 0.02 0 0 -1.57``. The arena's mesh (``arena.dae``) is a plane from -1 to 1
under a node transform scaling x and y by 6.301963, which ``model.sdf`` scales by 1.85 more: the
texture covers 2 x 6.301963 x 1.85 = 23.3 Gazebo metres, 3.7 of this package's metres
(:data:`~arenabench.generator.assets.competition_arena.TEXTURE_SIDE_M`), so one package metre is
:data:`ARENA_MESH_SCALE` Gazebo metres.

The example image was not rendered by that camera: its 16 marker corners and their pixels
(docs/rendering.md, "The camera") fix a horizontal field of view of 1.2 rad and a pitch of
1.5 rad on the same mount. Fitted freely (field of view included) to the marker squares, the
camera lands 19.97 Gazebo metres above the arena (the mount: 19.93), at (-0.050, 0.048) in the
arena's frame (the mount's link offset, turned by the arena's yaw: (-0.050, 0.053)), tilted
4.06 deg (1.5 rad of pitch: 4.06 deg from the nadir), field of view 68.65 deg (1.2 rad: 68.75).
Rendered with these round values, nothing fitted, the markers' squares differ from the example
by 0.5 grey levels (the 1.047 rad camera fitted to the corners: 4.5).

The example's boxes, fitted through this camera and read in Gazebo metres, stand on round
values too: centres (2.98, 2.98) and (-7.00, -3.00) in the world, footprints 1.98 x 4.96 and
1.97 x 4.01, axis-aligned in the world. The public world files place their boxes on the same
kind of grid (positions in 0.25 m, sizes in 0.5 m). :func:`snap_obstacle` puts a fitted box
on that grid; ``arenabench fit`` keeps the snapped box when its render is closer to the image.
On the example: boxes (3, 3) 2 x 5 and (-7, -3) 2 x 4, both 1.5 m above the arena; in the
2-px band around their outlines the render is then 0.64 grey levels from the example, and
moving any one value by 0.02 m makes it worse (docs/rendering.md, "The camera").
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from arenabench.generator.assets.competition_arena import CAMERA_HFOV_RAD
from arenabench.generator.model.camera import camera_from_pose
from arenabench.generator.model.scene import CameraSpec, Obstacle

#: The camera model's pose in the world: x, y, z (m), roll, pitch, yaw (rad). The public world
#: files give pitch 1.57; the example was rendered at 1.5 (module docstring).
CAMERA_MODEL_POSE = (0.0, 0.0, 20.0, 0.0, 1.5, 0.0)
#: The camera link's offset in the camera model's frame (m).
CAMERA_LINK_OFFSET_M = (0.05, 0.05, 0.05)
#: The camera sensor's image size (px).
CAMERA_IMAGE_PX = (1000, 1000)
#: The arena model's pose in the world: x, y, z (m), roll, pitch, yaw (rad).
ARENA_MODEL_POSE = (0.0, 0.0, 0.02, 0.0, 0.0, -1.57)
#: Gazebo metres per package metre: ``arena.dae``'s node scale (model.sdf's 1.85 maps the
#: mesh's -1..1 to the package's 3.7 m texture square).
ARENA_MESH_SCALE = 6.301963


def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """SDF's rotation of a pose: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


#: A Gazebo camera looks along its link's +x with +z up: the OpenCV optical axes (x right,
#: y down, z forward) as columns in the link's frame.
_OPTICAL_IN_LINK = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def competition_pose() -> np.ndarray:
    """The camera's 4x4 ``world_from_camera`` pose (OpenCV axes) in the package's floor frame
    (x east, y north, z up, metres; the texture's centre at the origin)."""
    r_model = _rotation(*CAMERA_MODEL_POSE[3:])
    centre_world = np.array(CAMERA_MODEL_POSE[:3]) + r_model @ np.array(CAMERA_LINK_OFFSET_M)
    r_arena = _rotation(*ARENA_MODEL_POSE[3:])
    pose = np.eye(4)
    pose[:3, :3] = r_arena.T @ r_model @ _OPTICAL_IN_LINK
    pose[:3, 3] = r_arena.T @ (centre_world - np.array(ARENA_MODEL_POSE[:3])) / ARENA_MESH_SCALE
    return pose


def competition_camera() -> CameraSpec:
    """The example's camera as an orbit-form :class:`CameraSpec` (square pixels, centred
    principal point, vertical field of view = horizontal for the square image)."""
    width, height = CAMERA_IMAGE_PX
    hfov = CAMERA_HFOV_RAD
    fov_v = math.degrees(2.0 * math.atan(math.tan(hfov / 2.0) * height / width))
    return camera_from_pose(competition_pose(), fov_deg=fov_v, width=width, height=height)


#: Grids (Gazebo metres) of box positions and of box sizes and heights in the competition's
#: world files (``warehouse_world.sdf``: positions such as 5.5, -3.5, 2.75; sizes 1-6 and 4.5).
BOX_POSITION_GRID_M = 0.25
BOX_SIZE_GRID_M = 0.5


def _snap(value: float, grid: float) -> float:
    return round(value / grid) * grid


def snap_obstacle(obstacle: Obstacle) -> Obstacle:
    """``obstacle`` (package metres, floor frame) put on the world files' grid: axis-aligned in
    the world, centre on :data:`BOX_POSITION_GRID_M`, footprint and height (above the arena)
    on :data:`BOX_SIZE_GRID_M`, then back in package metres. Sizes never snap to 0."""
    arena_yaw = math.degrees(ARENA_MODEL_POSE[5])
    quarter = round((obstacle.yaw_deg + arena_yaw) / 90.0)
    c, s = math.cos(math.radians(arena_yaw)), math.sin(math.radians(arena_yaw))
    x, y = (v * ARENA_MESH_SCALE for v in obstacle.center_m)
    world = (_snap(c * x - s * y, BOX_POSITION_GRID_M), _snap(s * x + c * y, BOX_POSITION_GRID_M))
    centre = (c * world[0] + s * world[1], -s * world[0] + c * world[1])

    def size(v: float) -> float:
        return max(_snap(v * ARENA_MESH_SCALE, BOX_SIZE_GRID_M), BOX_SIZE_GRID_M) / ARENA_MESH_SCALE

    return replace(obstacle, center_m=tuple(round(v / ARENA_MESH_SCALE, 6) for v in centre),
                   yaw_deg=round(quarter * 90.0 - arena_yaw, 6),
                   length_m=round(size(obstacle.length_m), 6),
                   width_m=round(size(obstacle.width_m), 6),
                   height_m=round(size(obstacle.height_m), 6))
