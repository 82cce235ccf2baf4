"""Preset + seed + index -> Scene.

Every random draw of scene ``index`` in a run with seed ``seed`` comes from a **named stream**:
stream ``name`` is ``numpy.random.default_rng(SeedSequence([seed, index, crc32(name)]))``
(:func:`stream_rng`). Each parameter drawn has a stream of its own, named after it
(:attr:`arenabench.generator.parameters.params.Param.stream`), so a scene never depends on the
number of
workers or on which scenes came before, and adding, removing, reordering or overriding a
parameter moves no other parameter's draw. A range is drawn once per scene (a per-box
parameter once per box, from the same stream); the camera parameters are drawn again, from
their streams, while the markers are out of view. Draws that are not parameters have named
streams too: obstacle placement (:data:`PLACEMENT_STREAM`), the warehouse loads (the
``obstacles.palette`` stream), the floor distractors (:data:`PATCH_STREAM`) and the image noise
(``degrade``, :func:`arenabench.generator.dataset.make.degrade_rng`).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from shapely.geometry import Polygon, box

from arenabench.fileio import rounded
from arenabench.generator.model import camera as cam
from arenabench.generator.model.distractors import occluder_patch, sample_patches
from arenabench.generator.model.layout import (
    IN_VIEW_MARGIN_PX,
    box_footprint,
    marker_corners_world,
)
from arenabench.generator.model.lens import distort_points
from arenabench.generator.model.lights import fill_lights
from arenabench.generator.model.scene import (
    ArenaSpec,
    CameraSpec,
    LightingSpec,
    MarkerSpec,
    Obstacle,
    RenderSpec,
    Scene,
)
from arenabench.generator.parameters.params import PARAMETERS, PARAMS, Range, Value, assemble
from arenabench.generator.parameters.presets import resolve

#: Per-obstacle parameters (each box draws each of them once, from the parameter's stream).
_BOX_KEYS = tuple(p.name for p in PARAMS if p.draw == "box")
#: Parameters drawn again with the camera when the markers are out of view.
_CAMERA_KEYS = tuple(p.name for p in PARAMS if p.redraw)
#: Stream of the obstacle centres (placement tries).
PLACEMENT_STREAM = "obstacles.placement"
#: Stream of the tape and paper patches on the floor.
PATCH_STREAM = "distractors.patches"


class SamplingError(ValueError):
    """A preset asks for something that cannot be placed; the message names the parameters."""


@dataclass(frozen=True)
class SampledScene:
    """A scene and the scalar parameters drawn for it (keyed by ``--set`` names)."""

    scene: Scene
    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    index: int = 0


def _check_seed(seed: int, index: int) -> None:
    if seed < 0 or index < 0:
        raise ValueError(f"seed and index must be >= 0, got seed={seed!r} index={index!r}")


def stream_rng(seed: int, index: int, name: str) -> np.random.Generator:
    """The random stream ``name`` of scene ``index`` in a run with ``seed``.

    Seeded by ``(seed, index, crc32(name))``: streams of different names are independent, and
    a stream's draws depend on nothing but its name, the seed and the index.

    Raises
    ------
    ValueError
        For a negative seed or index, or an empty name.
    """
    _check_seed(seed, index)
    if not name:
        raise ValueError("stream name must not be empty")
    key = zlib.crc32(name.encode("utf-8"))
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(index), key]))


class Streams:
    """The named random streams of one scene, each created on first use (:func:`stream_rng`)."""

    def __init__(self, seed: int, index: int) -> None:
        self.seed, self.index = int(seed), int(index)
        self._rngs: dict[str, np.random.Generator] = {}
        _check_seed(self.seed, self.index)

    def __call__(self, name: str) -> np.random.Generator:
        """Stream ``name`` (the same generator, continuing, on every call)."""
        if name not in self._rngs:
            self._rngs[name] = stream_rng(self.seed, self.index, name)
        return self._rngs[name]

    def draw(self, key: str, value: Value) -> Any:
        """Parameter ``key``'s next value: a :class:`Range` drawn from its stream, else
        ``value`` itself (no draw)."""
        if not isinstance(value, Range):
            return value
        spec = PARAMETERS[key]
        return draw(self(spec.stream), value, integer=spec.kind == "int",
                    choices=spec.values_in(value.lo, value.hi) if spec.choices else ())


def draw(rng: np.random.Generator, value: Value, *, integer: bool = False,
         choices: tuple[int, ...] = ()) -> Any:
    """Draw one value: a :class:`Range` is uniform (integers inclusive; one of ``choices``,
    each as likely, when given), else fixed.

    Always consumes exactly one uniform draw from ``rng``.
    """
    u = rng.random()
    if not isinstance(value, Range):
        return value
    lo, hi = value.lo, value.hi
    if choices:
        return int(choices[min(math.floor(u * len(choices)), len(choices) - 1)])
    if integer:
        return int(lo + min(math.floor(u * (hi - lo + 1)), hi - lo))
    return float(lo + u * (hi - lo))


def _camera(values: dict[str, Any]) -> CameraSpec:
    return CameraSpec(**assemble(values)["camera"])


def markers_in_view(arena: ArenaSpec, markers: MarkerSpec, camera: CameraSpec,
                    *, margin_px: float = IN_VIEW_MARGIN_PX) -> bool:
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


def _place_obstacles(streams: Streams, p: dict[str, Any], count: int,
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
        box_ = {k: streams.draw(k, p[k]) for k in _BOX_KEYS}
        length, width, height = (box_[f"obstacles.{k}"] for k in ("length_m", "width_m",
                                                                   "height_m"))
        yaw, gray = box_["obstacles.yaw_deg"], box_["obstacles.gray"]
        color = (gray, gray, gray)
        step = p["obstacles.yaw_step_deg"]
        if step > 0:  # e.g. 90: boxes axis-aligned, as the competition's world files place them
            yaw = float(round(yaw / step) * step) % 180.0
        if p["obstacles.palette"] == "warehouse":  # pallet or crate, from its own stream
            length, width, height, color = _warehouse_load(
                streams(PARAMETERS["obstacles.palette"].stream), length, width, height)
        rng = streams(PLACEMENT_STREAM)
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


def sample_scene(preset: Any, *, seed: int, index: int,
                 overrides: dict[str, Value] | None = None) -> SampledScene:
    """Draw scene ``index`` of a run with ``seed`` from a preset.

    Parameters
    ----------
    preset : str, dict or ResolvedPreset
        Preset name, parameter mapping or a preset file's
        :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`.
    seed, index : int, keyword-only
        Run seed and scene index (both >= 0).
    overrides : dict, keyword-only
        Parsed ``--set`` values (see
        :func:`arenabench.generator.parameters.param_values.parse_overrides`).

    Returns
    -------
    SampledScene

    Raises
    ------
    SamplingError
        When obstacles or the camera cannot be placed within the bounded number of tries.
    """
    p = resolve(preset, overrides)
    streams = Streams(seed, index)
    # Drawn for every scene (and recorded in the GT): draw="scene" parameters, and any other
    # parameter a preset or --set gives as a range (arena.side_m, markers.side_m, ...).
    drawn = {
        spec.name: streams.draw(spec.name, p[spec.name]) for spec in PARAMS
        if spec.draw == "scene" or (spec.draw == "fixed" and isinstance(p[spec.name], Range))
    }
    values = {**p, **drawn}
    sections = assemble(values)
    arena = ArenaSpec(**sections["arena"])
    markers = MarkerSpec(**sections["markers"])
    obstacles = _place_obstacles(streams, values, drawn["obstacles.count"], arena, markers)
    camera = CameraSpec(**sections["camera"])
    if p["camera.markers_in_view"]:
        for _ in range(p["camera.max_tries"]):
            if markers_in_view(arena, markers, camera):
                break
            drawn.update({k: streams.draw(k, p[k]) for k in _CAMERA_KEYS})
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
    light["directional"] += fill_lights(east=values["lighting.east_fill"],
                                        west=values["lighting.west_fill"])
    lighting = LightingSpec(**light)
    patches = sample_patches(streams(PATCH_STREAM), tapes=drawn["distractors.tapes"],
                             papers=drawn["distractors.papers"], arena=arena, markers=markers)
    occluder = occluder_patch(arena, markers, marker=drawn["markers.occluded"],
                              fraction=drawn["markers.occlusion"])
    if occluder is not None:
        patches = (*patches, occluder)
    g = drawn["background.gray"]
    scene = Scene(arena=arena, markers=markers, obstacles=obstacles, camera=camera,
                  lighting=lighting, background_rgb=(g, g, g), patches=patches,
                  render=RenderSpec(**sections["render"]))
    # Canonical form: the scene rendered is exactly the one written to the GT file (floats
    # rounded like the GT file), so Scene.from_dict(gt["scene"]) re-renders the same image.
    scene = Scene.from_dict(rounded(scene.to_dict()))
    return SampledScene(scene=scene, params=rounded(drawn), seed=int(seed), index=int(index))
