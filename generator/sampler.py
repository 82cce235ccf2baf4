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
from arenabench.generator.degrade import distort_points
from arenabench.generator.distractors import occluder_patch, sample_patches
from arenabench.generator.layout import box_footprint, marker_corners_world
from arenabench.generator.params import PARAMETERS, PARAMS, Range, Value, assemble
from arenabench.generator.presets import resolve
from arenabench.generator.scene import (
    ArenaSpec,
    CameraSpec,
    LightingSpec,
    MarkerSpec,
    Obstacle,
    Scene,
)


def _drawn_from(stream: str, *, draw: str = "scene") -> tuple[str, ...]:
    return tuple(p.name for p in PARAMS if p.stream == stream and p.draw == draw)


#: Scene-level scalar parameters drawn (in this order) for every scene.
SCALAR_KEYS: tuple[str, ...] = _drawn_from("scene")
#: Parameters drawn again with the camera when the markers are out of view.
_CAMERA_KEYS = tuple(p.name for p in PARAMS if p.redraw)
#: Degradation and scene-variation parameters, drawn in this order from their own
#: generator (:func:`variation_rng`) so that presets without them draw exactly as before.
VARIATION_KEYS: tuple[str, ...] = _drawn_from("variation")
#: Per-obstacle parameters, drawn (in this order) for each box.
_BOX_KEYS = _drawn_from("scene", draw="box")


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
    """Draw one value: a :class:`Range` is uniform (integers inclusive), else fixed.

    Always consumes exactly one uniform draw from ``rng``.
    """
    u = rng.random()
    if not isinstance(value, Range):
        return value
    lo, hi = value.lo, value.hi
    if integer:
        return int(lo + min(math.floor(u * (hi - lo + 1)), hi - lo))
    return float(lo + u * (hi - lo))


def _camera(values: dict[str, Any]) -> CameraSpec:
    return CameraSpec(**assemble(values)["camera"])


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
            draw(rng, p[k], integer=PARAMETERS[k].kind == "int") for k in _BOX_KEYS
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
    drawn = {k: draw(rng, p[k], integer=PARAMETERS[k].kind == "int") for k in SCALAR_KEYS}
    vrng = variation_rng(seed, index)
    drawn.update({k: draw(vrng, p[k], integer=PARAMETERS[k].kind == "int")
                  for k in VARIATION_KEYS})
    # Any other parameter given as a range (arena.side_m, markers.side_m, arena.texture_seed,
    # ...) is drawn from a stream of its own, in sorted key order, so that allowing ranges there
    # moved no draw of the streams above.
    erng = np.random.default_rng(np.random.SeedSequence([int(seed), int(index), 3]))
    drawn.update({
        key: draw(erng, p[key], integer=PARAMETERS[key].kind == "int")
        for key in sorted(p)
        if PARAMETERS[key].draw == "fixed" and isinstance(p[key], Range)
    })
    values = {**p, **drawn}
    sections = assemble(values)
    arena = ArenaSpec(**sections["arena"])
    markers = MarkerSpec(**sections["markers"])
    obstacles = _place_obstacles(rng, values, drawn["obstacles.count"], arena, markers)
    camera = CameraSpec(**sections["camera"])
    if p["camera.markers_in_view"]:
        for _ in range(p["camera.max_tries"]):
            if markers_in_view(arena, markers, camera):
                break
            drawn.update({k: draw(rng, p[k]) for k in _CAMERA_KEYS})
            values.update(drawn)
            camera = _camera(values)
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
    light = sections["lighting"]
    light["directional"][0]["direction"] = direction
    lighting = LightingSpec(**light)
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
