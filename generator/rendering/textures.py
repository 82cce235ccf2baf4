"""Procedural textures: the arena floor and the ArUco marker sheets (cached, deterministic).

Texture arrays are RGB uint8 with row 0 at the top of the image: north for the floor, the
marker image's top for a marker sheet (before the sheet is rotated on the floor).
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from arenabench.aruco import aruco_dictionary
from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.assets.texture_store import IMAGE_TEXTURE, texture_rgb
from arenabench.generator.model.layout import floor_extent
from arenabench.generator.model.scene import ArenaSpec
from arenabench.generator.rendering.edges import linear_to_srgb, srgb_to_linear

#: Floor texture side in texels.
FLOOR_TEXELS = 2048
#: Texels per marker module (cell): 4x4 markers are 6 modules wide with the black border.
MODULE_TEXELS = 32


def marker_texture(dictionary: str, marker_id: int, side_m: float, quiet_zone_m: float):
    """A marker sheet: the marker image with a white quiet zone.

    Returns
    -------
    image : numpy.ndarray
        (N, N, 3) uint8 RGB, N = marker px + 2 * quiet px.
    pad_m : float
        The quiet zone actually drawn, in metres (rounded to whole texels), so that the sheet's
        outline is the marker square grown by ``pad_m``.
    """
    d = aruco_dictionary(dictionary, field="markers.dictionary")
    if not 0 <= marker_id < d.bytesList.shape[0]:
        raise ValueError(f"markers.ids: id {marker_id} is not in {dictionary}")
    side_px = (d.markerSize + 2) * MODULE_TEXELS
    pad_px = round(quiet_zone_m / side_m * side_px)
    # the sheet depends on the marker size only through the whole-texel padding, so scenes
    # with other marker sizes share one cached array (and the renderer one GL texture)
    return _marker_sheet(dictionary, int(marker_id), side_px, pad_px), pad_px * side_m / side_px


@functools.lru_cache(maxsize=256)
def _marker_sheet(dictionary: str, marker_id: int, side_px: int, pad_px: int) -> np.ndarray:
    d = aruco_dictionary(dictionary, field="markers.dictionary")
    img = cv2.aruco.generateImageMarker(d, marker_id, side_px, borderBits=1)
    img = cv2.copyMakeBorder(img, pad_px, pad_px, pad_px, pad_px, cv2.BORDER_CONSTANT, value=255)
    rgb = np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))
    rgb.setflags(write=False)
    return rgb


_STRIP_ROWS = 64


def halve_in_linear_light(image: np.ndarray) -> np.ndarray:
    """An 8-bit sRGB ``image`` halved by 2 x 2 means in linear light (odd last rows and
    columns dropped): the next level of the mip chain GL makes of an sRGB texture."""
    h, w = image.shape[0] // 2, image.shape[1] // 2
    to_linear = srgb_to_linear(np.arange(256)).astype(np.float32).reshape(256, 1)
    out = np.empty((h, w, *image.shape[2:]), np.uint8)
    for y in range(0, h, _STRIP_ROWS):  # in strips: a float copy of the whole is 100 MB
        y1 = min(y + _STRIP_ROWS, h)
        lin = cv2.LUT(np.ascontiguousarray(image[2 * y:2 * y1, :2 * w]), to_linear)
        out[y:y1] = linear_to_srgb(cv2.resize(lin, (w, y1 - y), interpolation=cv2.INTER_AREA))
    return out


def floor_texture(arena: ArenaSpec, *, texels: int = FLOOR_TEXELS) -> np.ndarray:
    """The floor texture (albedo, unlit) covering the floor square, or an image texture's
    rectangle (:func:`arenabench.generator.model.layout.floor_corners`); cached by ``arena``."""
    if arena.texture == IMAGE_TEXTURE:
        return _image_texture(arena.texture_file, tuple(arena.floor_rgb))
    return _floor_texture(arena, texels)


@functools.lru_cache(maxsize=4)
def _image_texture(ref: str, floor_rgb: tuple[int, int, int]) -> np.ndarray:
    """An image texture at its own resolution (the renderer builds its mip chain as ogre2
    does, in linear light), tinted by the floor colour as the competition's texture is."""
    rgb = texture_rgb(ref)
    if floor_rgb == (255, 255, 255):
        return rgb
    levels = np.arange(256, dtype=np.float64)[:, None] * np.asarray(floor_rgb) / 255.0
    lut = np.rint(levels).astype(np.uint8).reshape(256, 1, 3)
    img = cv2.LUT(rgb, lut)
    img.setflags(write=False)
    return img


@functools.lru_cache(maxsize=8)
def _floor_texture(arena: ArenaSpec, texels: int) -> np.ndarray:
    e = floor_extent(arena)
    scale = texels / (2.0 * e)  # texels per metre
    centres = (np.arange(texels) + 0.5) / scale - e  # x of column centres; y = -x of rows
    x = centres[None, :]
    y = -centres[:, None]
    if arena.texture == comp.TEXTURE_NAME:  # the printed arena, tinted by the floor colour
        levels = np.arange(256, dtype=np.float64)[:, None] * np.asarray(arena.floor_rgb) / 255.0
        lut = np.rint(levels).astype(np.uint8).reshape(256, 1, 3)
        # halved by 2 x 2 averages in linear light: exactly the first mip level that GL (and
        # ogre2, docs/rendering.md) makes of the sRGB original, so the GPU samples the same
        # levels below it as from the original. The arena spans about 1000 px of the 2880
        # texels, so the level of detail stays above 1 and the original's level 0 is never
        # sampled (a full-size upload renders the example the same, measured); a quarter of
        # the memory (the original would cost a rendering worker about 100 MB)
        full = cv2.LUT(comp.texture_rgb(), lut)
        img = halve_in_linear_light(full)
    else:
        img = np.empty((texels, texels, 3), np.uint8)
        img[:] = arena.floor_rgb
    if arena.texture == "speckle":
        rng = np.random.default_rng(arena.texture_seed)
        noise = rng.normal(0.0, 2.0, size=(texels // 4, texels // 4)).astype(np.float32)
        noise = cv2.resize(noise, (texels, texels), interpolation=cv2.INTER_LINEAR)
        img = np.clip(img.astype(np.float32) + noise[:, :, None], 0, 255).astype(np.uint8)
    if arena.texture == "concrete":
        img = _concrete(img, arena, x, y, scale)
    if arena.grid_step_m > 0:
        half = max(0.5 / scale, 0.005)
        on_x = np.abs((x + half) % arena.grid_step_m - half) < half
        on_y = np.abs((y + half) % arena.grid_step_m - half) < half
        img[on_x | on_y] = arena.grid_rgb
    if arena.border_width_m > 0:
        h, w = arena.side_m / 2.0, arena.border_width_m / 2.0
        ax, ay = np.abs(x), np.abs(y)
        outer = (ax <= h + w) & (ay <= h + w)
        inner = (ax < h - w) & (ay < h - w)
        img[outer & ~inner] = arena.border_rgb
    if arena.logo_text and arena.margin_m > 0:
        _draw_logo(img, arena, scale)
    img.setflags(write=False)
    return img


def _concrete(img: np.ndarray, arena: ArenaSpec, x: np.ndarray, y: np.ndarray,
              scale: float) -> np.ndarray:
    """Warehouse concrete: large and fine mottling, a few faint stains, and yellow lane lines
    painted across the margin (outside the arena, so they never touch the ground truth)."""
    texels = img.shape[0]
    rng = np.random.default_rng(np.random.SeedSequence([int(arena.texture_seed), 7]))
    coarse = rng.normal(0.0, 6.0, size=(16, 16)).astype(np.float32)
    medium = rng.normal(0.0, 3.0, size=(128, 128)).astype(np.float32)
    fine = rng.normal(0.0, 2.0, size=(texels // 2, texels // 2)).astype(np.float32)
    shade = sum(cv2.resize(n, (texels, texels), interpolation=cv2.INTER_CUBIC)
                for n in (coarse, medium, fine))
    stains = np.zeros((texels, texels), np.float32)
    for _ in range(int(rng.integers(2, 6))):
        centre = (int(rng.integers(0, texels)), int(rng.integers(0, texels)))
        axes = (int(rng.integers(texels // 60, texels // 18)),
                int(rng.integers(texels // 80, texels // 25)))
        cv2.ellipse(stains, centre, axes, float(rng.uniform(0, 180)), 0, 360,
                    float(rng.uniform(8.0, 16.0)), -1)
    stains = cv2.GaussianBlur(stains, (0, 0), texels / 300)
    out = img.astype(np.float32) + (shade - stains)[:, :, None]
    if arena.margin_m > 0:  # lane lines centred in the margin on the east and west sides
        half_w = 0.25 * arena.margin_m
        lane = np.abs(np.abs(x) - (arena.side_m / 2.0 + arena.margin_m / 2.0)) < half_w / 2.0
        lane = np.broadcast_to(lane, (texels, texels))
        paint = np.array((205.0, 165.0, 30.0), np.float32) + shade[:, :, None] * 0.5
        out = np.where(lane[:, :, None], paint, out)
    return np.clip(out, 0, 255).astype(np.uint8)


def _draw_logo(img: np.ndarray, arena: ArenaSpec, scale: float) -> None:
    """Draw ``arena.logo_text`` centred in the south margin, about half the margin high."""
    e = floor_extent(arena)
    font = cv2.FONT_HERSHEY_SIMPLEX
    target_h = 0.45 * arena.margin_m * scale
    (_, th), _ = cv2.getTextSize(arena.logo_text, font, 1.0, 2)
    font_scale = target_h / max(th, 1)
    thickness = max(1, round(font_scale * 2))
    (tw, th), _ = cv2.getTextSize(arena.logo_text, font, font_scale, thickness)
    row_centre = (e + arena.side_m / 2.0 + arena.margin_m / 2.0) * scale
    org = (round(img.shape[1] / 2 - tw / 2), round(row_centre + th / 2))
    cv2.putText(img, arena.logo_text, org, font, font_scale, arena.logo_rgb, thickness,
                cv2.LINE_AA)
