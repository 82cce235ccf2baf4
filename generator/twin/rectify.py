"""Without an arena texture: one rectified from the image itself, the boxes masked out.

Each texel of the floor square is looked up in the image through the fitted camera (the floor's
homography); texels the image does not show, or shows under a box, are filled from their
neighbours (``cv2.inpaint``) or with the floor's grey. The texture is stored relative to the
floor's grey (the floor's commonest grey becomes white, and ``arena.floor_rgb`` tints it back),
so the floor grey stays a parameter of its own.

Sampling a texture twice (once by the camera that took the image, once by the twin's renderer)
blurs it twice; so the texture is then corrected by back-projection (:data:`ROUNDS` rounds): the
twin's render of the floor, boxes left out, is compared with the image, and the difference,
looked up through the same map, is added to the texture.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from dataclasses import replace

import cv2
import numpy as np

from arenabench.generator import camera as cam
from arenabench.generator.layout import floor_extent
from arenabench.generator.scene import IMAGE_TEXTURE, Scene
from arenabench.interrupts import checkpoint

#: Back-projection rounds.
ROUNDS = 4
#: Texels per image pixel across the floor (at least; a power of two a side, at most
#: :data:`MAX_TEXELS`).
TEXELS_PER_PX = 2.0
#: The largest texture side.
MAX_TEXELS = 4096
#: Pixels around the boxes left out of the texture (their edges blend with the floor).
BOX_PAD_PX = 4


def texel_map(scene: Scene, texels: int) -> tuple[np.ndarray, np.ndarray]:
    """Image px (x map, y map; float32 (texels, texels)) of each texel centre of the floor
    square (row 0 north)."""
    e = floor_extent(scene.arena)
    centres = (np.arange(texels) + 0.5) * (2.0 * e / texels) - e
    x, y = np.meshgrid(centres, -centres)
    h = cam.floor_homography(cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera))
    den = h[2, 0] * x + h[2, 1] * y + h[2, 2]
    u = (h[0, 0] * x + h[0, 1] * y + h[0, 2]) / den
    v = (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / den
    return u.astype(np.float32), v.astype(np.float32)


def texture_side(scene: Scene) -> int:
    """Texels a side: a power of two giving at least :data:`TEXELS_PER_PX` texels per image
    px across the floor."""
    mx, _ = texel_map(scene, 64)
    px_per_side = float(np.nanmax(mx) - np.nanmin(mx))
    n = 256
    while n < TEXELS_PER_PX * px_per_side and n < MAX_TEXELS:
        n *= 2
    return n


def _write(texture_rgb: np.ndarray, folder: str, k: int) -> str:
    path = os.path.join(folder, f"arena-{k}.png")
    cv2.imwrite(path, cv2.cvtColor(texture_rgb, cv2.COLOR_RGB2BGR),
                [cv2.IMWRITE_PNG_COMPRESSION, 1])
    return path


def rectified_arena(real_bgr: np.ndarray, scene: Scene, box_mask: np.ndarray, renderer, *,
                    rounds: int = ROUNDS, progress: Callable[[str], None] | None = None,
                    folder: str | None = None) -> tuple[np.ndarray, Scene]:
    """The texture (RGB uint8, row 0 north) and ``scene`` showing it (``arena.texture`` image,
    its file in ``folder``, a temporary one by default, which the caller replaces when it
    writes the twin)."""
    folder = folder or tempfile.mkdtemp(prefix="arenabench-twin-")
    n = texture_side(scene)
    mx, my = texel_map(scene, n)
    h, w = real_bgr.shape[:2]
    seen = (mx >= 0) & (mx <= w - 1) & (my >= 0) & (my <= h - 1)
    k = 2 * BOX_PAD_PX + 1
    boxes = cv2.dilate(box_mask.astype(np.uint8), np.ones((k, k), np.uint8))
    hidden = cv2.remap(boxes, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                       borderValue=1).astype(bool)
    floor = np.asarray(scene.arena.floor_rgb, np.float64)
    rgb = cv2.cvtColor(real_bgr, cv2.COLOR_BGR2RGB).astype(np.float32)
    raw = cv2.remap(rgb, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
    scale = 255.0 / np.maximum(floor, 1.0)
    texture = np.clip(raw * scale, 0, 255)
    unknown = (~seen) | hidden
    texture[~seen] = 255.0
    texture = texture.astype(np.uint8)
    if hidden.any():
        texture = cv2.inpaint(texture, (hidden & seen).astype(np.uint8), 5, cv2.INPAINT_TELEA)
    path = _write(texture, folder, 0)
    arena = replace(scene.arena, texture=IMAGE_TEXTURE, texture_file=path, border_width_m=0.0,
                    logo_text="", grid_step_m=0.0)
    current = replace(scene, arena=arena)
    empty = replace(current, obstacles=())
    grown = cv2.dilate(box_mask.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
    work = texture.astype(np.float32)
    for r in range(1, rounds + 1):
        checkpoint()
        render = renderer.render(empty).rgb.astype(np.float32)
        diff = (rgb - render) * scale.astype(np.float32)
        diff[grown] = 0.0
        back = cv2.remap(diff, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=0)
        back[unknown] = 0.0
        work = np.clip(work + back, 0, 255)
        texture = np.rint(work).astype(np.uint8)
        path = _write(texture, folder, r)
        arena = replace(arena, texture_file=path)
        empty = replace(empty, arena=arena)
        if progress:
            shown = ~grown
            progress(f"texture round {r}: floor difference "
                     f"{float(np.abs(rgb - render)[shown].mean()):.2f} grey levels before it")
    return texture, replace(current, arena=arena)
