"""Scene-side light variations computed analytically: box shadows, an uneven (spot) light and
fill lights on the boxes' east and west faces.

- Shadows: the first directional light's shadow of each box on the floor is the convex hull of
  its footprint and its top face projected along the light onto z = 0. The union is drawn as
  one translucent black overlay (FLAT rendering stays fast; no shadow maps). Shadows are
  appearance only: they never change the ground-truth count or areas.
- Spot light: a smooth multiplicative gain over the floor, applied to the rendered pinhole
  image through the floor homography (a box takes the gain of the floor point behind it).
- Fill lights (``lighting.east_fill``, ``lighting.west_fill``): horizontal directional lights
  along x, after the main light in ``LightingSpec.directional``. A normal without an x
  component (the floor, the markers, the boxes' top, north and south faces) gets nothing from
  them, so only the east and west faces change; they cast no shadow (only the first light
  does) and leave the floor's shade, hence the shadows' darkness, as it was.
"""

from __future__ import annotations

import cv2
import numpy as np
import shapely
from shapely.geometry import MultiPoint, Polygon

from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices
from arenabench.generator.model.scene import DirectionalLight, LightingSpec, Scene
from arenabench.generator.model.shading import floor_factor

#: Height (m) of the shadow overlay: above the floor, the distractors and the markers.
SHADOW_Z = 0.0014


#: Where each fill light travels: the east fill towards -x (it lights faces whose normal
#: points east, +x), the west fill towards +x.
FILL_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "east": (-1.0, 0.0, 0.0), "west": (1.0, 0.0, 0.0)}


def fill_lights(*, east: float, west: float) -> tuple[DirectionalLight, ...]:
    """The fill lights of intensities ``east`` and ``west`` (none for 0), to follow the main
    light in ``LightingSpec.directional`` (only the first directional light casts shadows)."""
    return tuple(DirectionalLight(direction=FILL_DIRECTIONS[side], intensity=float(value))
                 for side, value in (("east", east), ("west", west)) if value > 0)


def shadow_alpha(lighting: LightingSpec) -> float:
    """Fraction of floor brightness removed in the shadow of the first directional light."""
    if lighting.shadow_strength <= 0 or not lighting.directional:
        return 0.0
    lit = min(floor_factor(lighting), 1.0)
    if lit <= 0:
        return 0.0
    unlit = LightingSpec(ambient=lighting.ambient, directional=lighting.directional[1:])
    return float(lighting.shadow_strength * (1.0 - min(floor_factor(unlit), 1.0) / lit))


def shadow_region_world(scene: Scene):
    """Union (shapely geometry, metres) of the boxes' shadows on the floor; empty when none.

    Only the first directional light casts shadows, and only when ``shadow_strength > 0``.
    """
    lighting = scene.lighting
    if lighting.shadow_strength <= 0 or not lighting.directional or not scene.obstacles:
        return Polygon()
    d = np.asarray(lighting.directional[0].direction, dtype=np.float64)
    if d[2] >= 0:  # light from below the horizon: no shadow on the floor
        return Polygon()
    shapes = []
    for ob in scene.obstacles:
        v = box_vertices(ob)
        flat = v[:, :2] - d[None, :2] * (v[:, 2:3] / d[2])
        shapes.append(MultiPoint(flat).convex_hull)
    return shapely.union_all(shapes)


def shadow_mesh_arrays(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Positions (N, 3), RGBA colours (N, 4) and triangles (M, 3) of the shadow overlay.

    None when the scene casts no shadow. The overlay is black with alpha :func:`shadow_alpha`:
    blended over the floor it multiplies the floor's brightness by ``1 - alpha``.
    """
    alpha = shadow_alpha(scene.lighting)
    region = shadow_region_world(scene)
    if alpha <= 0 or region.is_empty:
        return None
    tris = shapely.constrained_delaunay_triangles(region)
    coords = [np.asarray(t.exterior.coords)[:3] for t in tris.geoms]
    if not coords:
        return None
    xy = np.concatenate(coords)
    positions = np.column_stack([xy, np.full(len(xy), SHADOW_Z)]).astype(np.float32)
    rgba = np.tile(np.array([0.0, 0.0, 0.0, alpha], np.float32), (len(xy), 1))
    faces = np.arange(len(xy)).reshape(-1, 3)
    return positions, rgba, faces


def spot_gain(lighting: LightingSpec, xy: np.ndarray) -> np.ndarray:
    """Brightness gain of the spot light at floor points ``xy`` (..., 2)."""
    if lighting.spot_strength <= 0:
        return np.ones(np.shape(xy)[:-1])
    d2 = ((np.asarray(xy) - np.asarray(lighting.spot_xy_m)) ** 2).sum(axis=-1)
    falloff = np.exp(-d2 / (2.0 * lighting.spot_radius_m ** 2))
    return 1.0 - lighting.spot_strength * (1.0 - falloff)


def apply_spot_light(rgb: np.ndarray, scene: Scene) -> np.ndarray:
    """Multiply a pinhole render of ``scene`` by the spot light's gain on the floor.

    Returns ``rgb`` itself when the light is even. Pixels that see no floor (above the
    horizon) keep gain 1.
    """
    if scene.lighting.spot_strength <= 0:
        return rgb
    h, w = rgb.shape[:2]
    K = cam.intrinsics(scene.camera)
    pose = cam.world_from_camera(scene.camera)
    image_to_floor = np.linalg.inv(cam.floor_homography(K, pose))
    # The gain is smooth: solve it on a coarse grid and resize (bilinear).
    step = 8
    gx = np.arange(0, w + step, step, dtype=np.float64)
    gy = np.arange(0, h + step, step, dtype=np.float64)
    u, v = np.meshgrid(gx, gy)
    p = np.stack([u, v, np.ones_like(u)], axis=-1) @ image_to_floor.T
    ok = p[..., 2] > 1e-12
    xy = p[..., :2] / np.where(ok, p[..., 2], 1.0)[..., None]
    gain = np.where(ok, spot_gain(scene.lighting, xy), 1.0).astype(np.float32)
    xs = (np.arange(w, dtype=np.float32) / step)[None, :].repeat(h, 0)
    ys = (np.arange(h, dtype=np.float32) / step)[:, None].repeat(w, 1)
    full = cv2.remap(gain, xs, ys, cv2.INTER_LINEAR)
    out = rgb.astype(np.float32) * full[:, :, None]
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
