"""The e-Yantra competition's own arena texture and the geometry measured on it.

``assets/arena_texture.png`` is ``arena1.7.png`` of the public competition repository
(eYantra-Robotics-Competition/eyrc-24-25-warehouse-drone,
``swift_pico_description/models/arena/meshes/``), byte for byte: 2880 x 2880 RGBA (alpha all
255). The arena model is a flat plane from -1 to 1 scaled 1.85 (``model.sdf``), so the texture
covers a 3.7 m square. Measured on the texture (1 texel = 3.7 / 2880 m = 1.285 mm): the four
markers (DICT_4X4_100, ids 80 NW, 85 NE, 90 SE, 95 SW, all printed rotated 180 deg) are 176.5
texels a side with their outer corners 1296 texels from the centre on each axis, i.e. on the
outer edge of the 4-texel border line. Hence the scene values below: ``arena.side_m`` 3.33
(2592 texels), ``arena.margin_m`` 0.185, ``markers.side_m`` 0.2268.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

#: Name of the floor texture (``arena.texture``) that is the competition's arena image.
TEXTURE_NAME = "competition"
#: The texture file shipped with the package.
TEXTURE_PATH = Path(__file__).resolve().parent / "arena_texture.png"
#: Side (m) of the square the texture covers.
TEXTURE_SIDE_M = 3.7
#: Side (m) of the square through the markers' outer corners (2592 of 2880 texels).
ARENA_SIDE_M = 3.33
#: Floor beyond that square on each side (m).
ARENA_MARGIN_M = round((TEXTURE_SIDE_M - ARENA_SIDE_M) / 2.0, 6)
#: Marker side (m), black border included (176.5 texels).
MARKER_SIDE_M = 0.2268
#: Horizontal field of view (rad) of the camera that rendered the competition's example
#: (1000 x 1000 px): 1.2, fixed by the example's markers; the public world files
#: (``swift_pico/worlds/*.sdf``) give 1.047 (:mod:`arenabench.generator.fitting.competition_world`).
CAMERA_HFOV_RAD = 1.2
#: Its vertical field of view (deg): square pixels and a square image, so the same angle.
CAMERA_FOV_DEG = round(math.degrees(CAMERA_HFOV_RAD), 6)
#: The markers printed on the texture: dictionary, ids (NW, NE, SE, SW), rotation (deg).
MARKER_DICTIONARY = "DICT_4X4_100"
MARKER_IDS = (80, 85, 90, 95)
MARKER_ROTATION_DEG = 180.0


def markers_are_printed(dictionary: str, ids: tuple[int, ...], side_m: float,
                        rotation_deg: float) -> bool:
    """Whether these markers are exactly the ones printed on the texture (nothing to draw)."""
    return (dictionary == MARKER_DICTIONARY and tuple(ids) == MARKER_IDS
            and abs(float(side_m) - MARKER_SIDE_M) < 1e-9
            and float(rotation_deg) % 360.0 == MARKER_ROTATION_DEG)


def texture_rgb() -> np.ndarray:
    """The texture as (2880, 2880, 3) uint8 RGB, row 0 north (read from the file each call:
    the tinted floor texture built from it is what gets cached).

    Raises
    ------
    ValueError
        When the packaged file is missing or unreadable (a broken installation).
    """
    bgr = cv2.imread(str(TEXTURE_PATH), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f"arena.texture={TEXTURE_NAME}: cannot read {TEXTURE_PATH}")
    return np.ascontiguousarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
