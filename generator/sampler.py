"""Preset + seed + index -> Scene.

Every random draw of scene ``index`` in a run with seed ``seed`` comes from one generator,
``numpy.random.default_rng(SeedSequence([seed, index]))``, so a scene never depends on the
number of workers or on which scenes came before. Scalar parameters are drawn first in a
fixed order, one uniform draw each whether or not the parameter is a range, so overriding one
parameter leaves the others' values unchanged; obstacle placement and camera redraws follow.
The degradation and scene-variation parameters (:data:`VARIATION_KEYS`: lens, ``degrade.*``,
shadows, spot light, distractors, occlusion) come from a second generator,
:func:`variation_rng`, so adding them left every earlier scene's draws as they were.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from shapely.geometry import Polygon, box

from arenabench.fileio import rounded
from arenabench.generator import camera as cam
from arenabench.generator.degrade import LENS_PARAMS, PARAM_NAMES, distort_points
from arenabench.generator.distractors import occluder_patch, sample_patches
from arenabench.generator.layout import box_footprint, marker_corners_world
from arenabench.generator.presets import PARAMETERS, Value, resolve
from arenabench.generator.scene import (
    ArenaSpec,
    CameraSpec,
    DirectionalLight,
    LightingSpec,
    MarkerSpec,
    Obstacle,
    Scene,
)

#: Scene-level scalar parameters drawn (in this order) for every scene.
SCALAR_KEYS: tuple[str, ...] = (
    "obstacles.count",
    "camera.altitude_m",
    "camera.tilt_deg",
    "camera.yaw_deg",
    "camera.roll_deg",
    "camera.target_x_m",
    "camera.target_y_m",
    "camera.fov_deg",
    "lighting.ambient",
    "lighting.intensity",
    "lighting.elevation_deg",
    "lighting.azimuth_deg",
    "background.gray",
)
_CAMERA_KEYS = tuple(k for k in SCALAR_KEYS if k.startswith("camera."))
#: Degradation and scene-variation parameters, drawn in this order from their own
#: generator (:func:`variation_rng`) so that presets without them draw exactly as before.
VARIATION_KEYS: tuple[str, ...] = (
    *LENS_PARAMS,
    *PARAM_NAMES.values(),
    "lighting.shadow_strength",
    "lighting.spot_strength",
    "lighting.spot_x_m",
    "lighting.spot_y_m",
    "lighting.spot_radius_m",
    "distractors.tapes",
    "distractors.papers",
    "markers.occlusion",
    "markers.occluded",
)
_INT_VARIATION_KEYS = ("degrade.jpeg_quality", "distractors.tapes", "distractors.papers",
                       "markers.occluded")
_BOX_KEYS = ("obstacles.length_m", "obstacles.width_m", "obstacles.height_m",
             "obstacles.yaw_deg", "obstacles.gray")


class SamplingError(ValueError):
    """A preset asks for something that cannot be placed; the message names the parameters."""


@dataclass(frozen=True)
class SampledScene:
    """A scene and the scalar parameters drawn for it (keyed by ``--set`` names)."""

    scene: Scene
    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    index: int = 0


def scene_rng(seed: int, index: int) -> np.random.Generator:
    """The one random generator of scene ``index`` in a run with ``seed``."""
    if seed < 0 or index < 0:
        raise ValueError(f"seed and index must be >= 0, got seed={seed!r} index={index!r}")
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(index)]))


def variation_rng(seed: int, index: int) -> np.random.Generator:
    """Generator of scene ``index``'s degradation and variation draws (independent stream)."""
    if seed < 0 or index < 0:
        raise ValueError(f"seed and index must be >= 0, got seed={seed!r} index={index!r}")
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(index), 2]))


def draw(rng: np.random.Generator, value: Value, *, integer: bool = False) -> Any:
    """Draw one value: a ``(lo, hi)`` range is uniform (integers inclusive), else fixed.

    Always consumes exactly one uniform draw from ``rng``.
    """
    u = rng.random()
    if not isinstance(value, tuple) or len(value) != 2:
        return value
    lo, hi = value
    if integer:
        return int(lo + min(math.floor(u * (hi - lo + 1)), hi - lo))
    return float(lo + u * (hi - lo))


def _camera(p: dict[str, Any], drawn: dict[str, Any]) -> CameraSpec:
    return CameraSpec(
        width=p["camera.width"], height=p["camera.height"], fov_deg=drawn["camera.fov_deg"],
        altitude_m=drawn["camera.altitude_m"], tilt_deg=drawn["camera.tilt_deg"],
        yaw_deg=drawn["camera.yaw_deg"], roll_deg=drawn["camera.roll_deg"],
        target_m=(drawn["camera.target_x_m"], drawn["camera.target_y_m"]),
        dist=tuple(drawn.get(k, 0.0) for k in LENS_PARAMS),
    )


def markers_in_view(arena: ArenaSpec, markers: MarkerSpec, camera: CameraSpec,
                    *, margin_px: float = 2.0) -> bool:
    """Whether all four markers (quiet zone included) project inside the (distorted) image."""
    K = cam.intrinsics(camera)
    pose = cam.world_from_camera(camera)
    for corner in ("nw", "ne", "se", "sw"):
        xy = marker_corners_world(arena, markers, corner, pad_m=markers.quiet_zone_m)
        pts = np.column_stack([xy, np.zeros(4)])
        if np.any((pts - pose[:3, 3]) @ pose[:3, 2] <= 0):
            return False
        px = distort_points(cam.project(pts, K, pose), K, camera.dist)
        if (px.min() < margin_px - 0.5 or px[:, 0].max() > camera.width - 0.5 - margin_px
                or px[:, 1].max() > camera.height - 0.5 - margin_px):
            return False
    return True


#: Crate colours of the warehouse palette (RGB): blue, red, green, yellow, grey plastic.
_CRATE_RGB = ((45, 85, 160), (165, 45, 40), (55, 120, 65), (205, 170, 45), (90, 95, 100))
#: Wooden pallet colour (RGB).
_PALLET_RGB = (160, 120, 75)


def _warehouse_load(rng: np.random.Generator, length: float, width: float,
                    height: float) -> tuple[float, float, float, tuple[int, int, int]]:
    """A warehouse obstacle: a low wooden pallet (40 %) or a coloured crate of the drawn size."""
    if rng.random() < 0.4:
        size = (float(rng.uniform(1.0, 1.25)), float(rng.uniform(0.8, 1.0)),
                float(rng.uniform(0.12, 0.2)))
        base = _PALLET_RGB
    else:
        size = (length, width, height)
        base = _CRATE_RGB[int(rng.integers(len(_CRATE_RGB)))]
    jitter = rng.integers(-12, 13, size=3)
    color = tuple(int(np.clip(c + j, 0, 255)) for c, j in zip(base, jitter, strict=True))
    return size[0], size[1], size[2], color


def _place_obstacles(rng: np.random.Generator, p: dict[str, Any], count: int,
                     arena: ArenaSpec, markers: MarkerSpec) -> tuple[Obstacle, ...]:
    inner = arena.side_m / 2.0 - markers.side_m - p["obstacles.edge_margin_m"]
    if inner <= 0:
        raise SamplingError(
            f"no room for obstacles: arena.side_m={arena.side_m} with markers.side_m="
            f"{markers.side_m} and obstacles.edge_margin_m={p['obstacles.edge_margin_m']}"
        )
    region = box(-inner, -inner, inner, inner)
    gap = p["obstacles.min_gap_m"]
    placed: list[Obstacle] = []
    shapes: list[Polygon] = []
    for i in range(count):
        length, width, height, yaw, gray = (
            draw(rng, p[k], integer=(k == "obstacles.gray")) for k in _BOX_KEYS
        )
        color = (gray, gray, gray)
        step = p["obstacles.yaw_step_deg"]
        if step > 0:  # e.g. 90: boxes axis-aligned, as the competition's world files place them
            yaw = float(round(yaw / step) * step) % 180.0
        if p["obstacles.palette"] == "warehouse":  # extra draws only here: eyrc is unchanged
            length, width, height, color = _warehouse_load(rng, length, width, height)
        for _ in range(p["obstacles.max_tries"]):
            centre = (float(rng.uniform(-inner, inner)), float(rng.uniform(-inner, inner)))
            ob = Obstacle(center_m=centre, yaw_deg=yaw, length_m=length, width_m=width,
                          height_m=height, color_rgb=color)
            shape = Polygon(box_footprint(ob))
            if region.contains(shape) and all(shape.distance(s) >= gap for s in shapes):
                placed.append(ob)
                shapes.append(shape)
                break
        else:
            raise SamplingError(
                f"could not place obstacle {i + 1} of obstacles.count={count} after "
                f"obstacles.max_tries={p['obstacles.max_tries']} tries: obstacles.min_gap_m="
                f"{gap}, obstacles.edge_margin_m={p['obstacles.edge_margin_m']}, "
                f"obstacles.length_m={p['obstacles.length_m']}, obstacles.width_m="
                f"{p['obstacles.width_m']}, arena.side_m={arena.side_m}"
            )
    return tuple(placed)


def sample_scene(preset: str | dict[str, Value], *, seed: int, index: int,
                 overrides: dict[str, Value] | None = None) -> SampledScene:
    """Draw scene ``index`` of a run with ``seed`` from a preset.

    Parameters
    ----------
    preset : str or dict
        Preset name or resolved parameter mapping.
    seed, index : int, keyword-only
        Run seed and scene index (both >= 0).
    overrides : dict, keyword-only
        Parsed ``--set`` values (see :func:`arenabench.generator.presets.parse_overrides`).

    Returns
    -------
    SampledScene

    Raises
    ------
    SamplingError
        When obstacles or the camera cannot be placed within the bounded number of tries.
    """
    p = resolve(preset, overrides)
    rng = scene_rng(seed, index)
    drawn = {k: draw(rng, p[k], integer=k in ("obstacles.count", "background.gray"))
             for k in SCALAR_KEYS}
    vrng = variation_rng(seed, index)
    varied = {k: draw(vrng, p[k], integer=k in _INT_VARIATION_KEYS) for k in VARIATION_KEYS}
    drawn.update(varied)
    # Any other parameter given as a range (arena.side_m, markers.side_m, arena.texture_seed,
    # ...) is drawn from a stream of its own, in sorted key order, so that allowing ranges there
    # moved no draw of the streams above.
    erng = np.random.default_rng(np.random.SeedSequence([int(seed), int(index), 3]))
    extra = {
        key: draw(erng, p[key], integer=PARAMETERS[key].kind == "int")
        for key in sorted(p)
        if key not in drawn and key not in _BOX_KEYS and isinstance(p[key], tuple)
        and PARAMETERS[key].kind in ("float", "int")
    }
    drawn.update(extra)
    p = {**p, **extra}
    arena = ArenaSpec(
        side_m=p["arena.side_m"], margin_m=p["arena.margin_m"], floor_rgb=p["arena.floor_rgb"],
        texture=p["arena.texture"], texture_seed=p["arena.texture_seed"],
        border_width_m=p["arena.border_width_m"],
        border_rgb=p["arena.border_rgb"], grid_step_m=p["arena.grid_step_m"],
        grid_rgb=p["arena.grid_rgb"], logo_text=p["arena.logo_text"],
        logo_rgb=p["arena.logo_rgb"],
    )
    markers = MarkerSpec(
        dictionary=p["markers.dictionary"], ids=p["markers.ids"], side_m=p["markers.side_m"],
        rotation_deg=p["markers.rotation_deg"], quiet_zone_m=p["markers.quiet_zone_m"],
    )
    obstacles = _place_obstacles(rng, p, drawn["obstacles.count"], arena, markers)
    camera = _camera(p, drawn)
    if p["camera.markers_in_view"]:
        for _ in range(p["camera.max_tries"]):
            if markers_in_view(arena, markers, camera):
                break
            drawn.update({k: draw(rng, p[k]) for k in _CAMERA_KEYS})
            camera = _camera(p, drawn)
        else:
            raise SamplingError(
                "markers not in view after camera.max_tries="
                f"{p['camera.max_tries']} camera draws: camera.altitude_m="
                f"{p['camera.altitude_m']}, camera.tilt_deg={p['camera.tilt_deg']}, "
                f"camera.fov_deg={p['camera.fov_deg']}, arena.side_m={arena.side_m}"
            )
    el, az = math.radians(drawn["lighting.elevation_deg"]), math.radians(
        drawn["lighting.azimuth_deg"])
    direction = (-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), -math.sin(el))
    lighting = LightingSpec(
        ambient=drawn["lighting.ambient"],
        directional=(DirectionalLight(direction=direction, intensity=drawn["lighting.intensity"]),),
        shadow_strength=drawn["lighting.shadow_strength"],
        spot_strength=drawn["lighting.spot_strength"],
        spot_xy_m=(drawn["lighting.spot_x_m"], drawn["lighting.spot_y_m"]),
        spot_radius_m=drawn["lighting.spot_radius_m"],
    )
    patches = sample_patches(vrng, tapes=drawn["distractors.tapes"],
                             papers=drawn["distractors.papers"], arena=arena, markers=markers)
    occluder = occluder_patch(arena, markers, marker=drawn["markers.occluded"],
                              fraction=drawn["markers.occlusion"])
    if occluder is not None:
        patches = (*patches, occluder)
    g = drawn["background.gray"]
    scene = Scene(arena=arena, markers=markers, obstacles=obstacles, camera=camera,
                  lighting=lighting, background_rgb=(g, g, g), patches=patches)
    # Canonical form: the scene rendered is exactly the one written to the GT file (floats
    # rounded like the GT file), so Scene.from_dict(gt["scene"]) re-renders the same image.
    scene = Scene.from_dict(rounded(scene.to_dict()))
    return SampledScene(scene=scene, params=rounded(drawn), seed=int(seed), index=int(index))
