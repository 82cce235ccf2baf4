"""Build a twin from one real render of an arena: the fitted scene, the preset, and what the
image pins or leaves open.

Steps (each one a module of this package):

1. the file (:mod:`~arenabench.generator.fitting.image_file`) and the markers
   (:mod:`~arenabench.generator.fitting.markers`);
2. the arena's geometry and scale (:mod:`~arenabench.generator.fitting.arena_geometry`);
3. the camera (:mod:`~arenabench.generator.fitting.camera_fit`), refined on the render when the
   arena texture is given;
4. the greys, boxes, faces and light (:mod:`~arenabench.generator.fitting.shades`), the boxes
   refined on the render (:mod:`~arenabench.generator.fitting.box_refine`);
5. without a texture, the arena's texture rectified from the image
   (:mod:`~arenabench.generator.fitting.rectify`);
6. the edges (:mod:`~arenabench.generator.fitting.edge_evidence`), chosen among the renders of
   every edge model the way the image's statistics are;
7. what varies (:mod:`~arenabench.generator.fitting.variation`) and the records
   (:mod:`~arenabench.generator.fitting.records`);
8. the figures: the fitted scene's render, written as the image was, against the image,
   region by region (:mod:`~arenabench.generator.fitting.regions`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.assets import texture_store
from arenabench.generator.fitting import arena_geometry as ag
from arenabench.generator.fitting import camera_fit as cf
from arenabench.generator.fitting import records as rec
from arenabench.generator.fitting.edge_evidence import EdgeEvidence, outline_band, read_edges
from arenabench.generator.fitting.image_file import FileFacts, as_written, read_file_facts
from arenabench.generator.fitting.markers import (
    MarkerFinding,
    detector_offset_text,
    find_markers,
)
from arenabench.generator.fitting.regions import (
    RegionFigures,
    marker_squares,
    region_figures,
    region_masks,
)
from arenabench.generator.fitting.shades import Shades, read_shades
from arenabench.generator.fitting.similarity import ssim
from arenabench.generator.fitting.variation import Varied, vary_boxes
from arenabench.generator.fitting.verdict import GOOD, UNRENDERED, FitVerdict, judge
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import floor_extent
from arenabench.generator.model.scene import (
    IMAGE_TEXTURE,
    ArenaSpec,
    LightingSpec,
    MarkerSpec,
    RenderSpec,
    Scene,
)
from arenabench.generator.parameters.params import PARAMETERS, Range, Value
from arenabench.generator.parameters.presets import resolve
from arenabench.generator.rendering.textures import MODULE_TEXELS
from arenabench.imageio import decode_image
from arenabench.interrupts import checkpoint

#: The edge models tried (samples, resolve).
EDGE_MODELS = ((1, "linear"), (2, "linear"), (2, "srgb"), (4, "linear"), (4, "srgb"))


@dataclass(frozen=True)
class TwinOptions:
    """What ``arenabench twin`` is given besides the image.

    Attributes
    ----------
    texture : Path or None
        The arena's texture image.
    arena_size_m : tuple of float or None
        The arena floor's size (W, H metres): the area the texture covers, or without a
        texture the floor the image shows out to its edge.
    name : str
        The preset's name.
    snap : bool
        Try round values of the camera's angles.
    """

    texture: Path | None = None
    arena_size_m: tuple[float, float] | None = None
    name: str = "twin"
    snap: bool = True


@dataclass
class Twin:
    """A built twin: everything the writers need.

    Attributes
    ----------
    scene : Scene
        The fitted scene of the image (its texture, when rectified, in ``texture_rgb``).
    params : dict
        The preset's parameters.
    records : list of Record
        Every parameter, pinned or open.
    figures : RegionFigures
        The fitted scene's render (as written) against the image.
    real, render : numpy.ndarray
        The image and that render (BGR).
    texture_rgb : numpy.ndarray or None
        The rectified texture (RGB; the scene's ``arena.texture_file`` names it).
    facts : dict
        What was found, for ``twin.json`` and the report.
    timings : dict
        Seconds per step.
    verdict : FitVerdict
        Whether the render holds the bounds the blind round trips hold, and if not what is
        off and why (:mod:`arenabench.generator.fitting.verdict`).
    """

    scene: Scene
    params: dict[str, Value]
    records: list[rec.Record]
    figures: RegionFigures
    real: np.ndarray
    render: np.ndarray
    texture_rgb: np.ndarray | None
    varied: list[Varied]
    facts: dict[str, Any] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    verdict: FitVerdict = field(default_factory=lambda: FitVerdict(GOOD, (), ()))

    @property
    def open_params(self) -> dict:
        """The preset file's ``[open]`` table: parameter -> OpenParam."""
        out = {}
        for r in self.records:
            entry = r.open_param()
            if entry is not None:
                out[r.name] = entry
        return out


def _sides_up(side_m: float):
    """The log's height of a camera in arena sides (the arena's size not known yet)."""
    def up(camera) -> str:
        return f"{camera.altitude_m / side_m:.4f} arena sides up"
    return up


def records_text(records) -> str:
    """``"30 pinned, 41 open (9 in the preset's [open] table: a, b, ...)"``: of the open ones,
    those the phase check varies are named (the others have no say in the image)."""
    named = sorted(r.name for r in records if r.open_param() is not None)
    n_open = sum(r.status == "open" for r in records)
    listed = (f" ({len(named)} in the preset's [open] table: {', '.join(named)}; the others "
              f"in twin.json)" if named else " (none in the preset's [open] table)")
    return (f"{sum(r.status == 'pinned' for r in records)} pinned, {n_open} open"
            + (listed if n_open else ""))


def _grey(rgb) -> int:
    return round(float(np.mean(rgb)))


def _scale_scene(scene: Scene, factor: float) -> Scene:
    """``scene`` with every length times ``factor`` (the image does not change)."""
    c = scene.camera
    camera = replace(c, altitude_m=round(c.altitude_m * factor, 6),
                     target_m=tuple(round(v * factor, 6) for v in c.target_m))
    arena = replace(scene.arena, side_m=round(scene.arena.side_m * factor, 6),
                    margin_m=round(scene.arena.margin_m * factor, 6),
                    texture_size_m=tuple(round(v * factor, 6)
                                         for v in scene.arena.texture_size_m))
    markers = replace(scene.markers, side_m=round(scene.markers.side_m * factor, 6),
                      quiet_zone_m=round(scene.markers.quiet_zone_m * factor, 6))
    obstacles = tuple(replace(o, center_m=tuple(round(v * factor, 6) for v in o.center_m),
                              length_m=round(o.length_m * factor, 6),
                              width_m=round(o.width_m * factor, 6),
                              height_m=round(o.height_m * factor, 6)) for o in scene.obstacles)
    return replace(scene, camera=camera, arena=arena, markers=markers, obstacles=obstacles)


class _Steps:
    """Progress and timing of the steps."""

    def __init__(self, progress: Callable[[str], None] | None) -> None:
        self.progress = progress
        self.timings: dict[str, float] = {}
        self._t = time.monotonic()

    def done(self, name: str, line: str = "") -> None:
        now = time.monotonic()
        self.timings[name] = round(now - self._t, 2)
        self._t = now
        if self.progress:
            self.progress(f"{name}: {line}" if line else name)

    def say(self, line: str) -> None:
        if self.progress:
            self.progress(line)


def build_twin(image_path: Path, options: TwinOptions | None = None, *,
               progress: Callable[[str], None] | None = None, renderer=None) -> Twin:
    """Build the twin of one image (see the module docstring).

    Parameters
    ----------
    image_path : Path
        The real render.
    options : TwinOptions
        Texture, size, name.
    progress : callable, keyword-only
        Called with one line per step.
    renderer : Renderer, keyword-only
        A renderer to reuse (one is made and closed otherwise).

    Raises
    ------
    ValueError
        An image without four markers (``MarkersNotFoundError``), a texture or size that
        does not fit it (``ArenaError``).
    """
    options = options or TwinOptions()
    own = renderer is None
    if own:
        from arenabench.generator.rendering.render import Renderer

        renderer = Renderer()
    try:
        twin = _build(Path(image_path), options, _Steps(progress), renderer)
        if twin.scene.arena.texture == IMAGE_TEXTURE:  # the twin's texture, into the cache
            texture_store.keep_held(twin.scene.arena.texture_file)
        return twin
    finally:
        texture_store.release_held()  # the trial textures
        if own:
            renderer.close()


def _build(image_path: Path, options: TwinOptions, steps: _Steps, renderer) -> Twin:
    data = image_path.read_bytes()
    real = decode_image(data, name=str(image_path))
    gray = cv2.cvtColor(real, cv2.COLOR_BGR2GRAY)
    height, width = gray.shape
    facts_file = read_file_facts(data, name=str(image_path))
    finding = find_markers(gray)
    steps.done("markers", f"{finding.dictionary} ids {list(finding.ids)}, printed "
                          f"{finding.rotation_deg:g} deg")
    # 2. geometry: the texture's, or the generator's default arena until the scale is known
    geometry = (ag.texture_geometry(options.texture, options.arena_size_m, finding)
                if options.texture is not None else
                ag.ArenaGeometry(ag.DEFAULT_SIDE_M, None, None, "default"))
    provisional = ArenaSpec(side_m=geometry.side_m, margin_m=geometry.margin_m or 0.0,
                            border_width_m=0.0, logo_text="")
    markers = MarkerSpec(dictionary=finding.dictionary, ids=finding.ids,
                         side_m=geometry.marker_side_m or 0.07 * geometry.side_m,
                         rotation_deg=finding.rotation_deg, quiet_zone_m=0.0,
                         printed=geometry.texture == "file")
    checkpoint()
    # the log says heights in the preset's metres, or in arena sides until the size is known
    up = _sides_up(geometry.side_m) if geometry.scale_source == "default" else cf.metres_up
    fit = cf.fit_camera(gray, finding, arena=provisional, markers=markers,
                        fit_marker_side=geometry.marker_side_m is None, snap=options.snap,
                        progress=steps.say, up=up)
    markers = replace(markers, side_m=fit.marker_side_m)

    steps.done("camera", f"fov {fit.camera.fov_deg:.3f} deg, {up(fit.camera)}, snapped "
                         f"{sorted(fit.snapped)}")
    if geometry.texture:
        arena = _texture_arena(geometry, (248, 248, 248))
        squares = np.zeros(gray.shape, bool)
        for m in marker_squares(finding, gray.shape).values():
            squares |= m
        probe = Scene(arena=arena, markers=markers, obstacles=(), camera=fit.camera,
                      lighting=LightingSpec(ambient=1.0, directional=()))
        fit = cf.refine_with_renderer(fit, probe, gray, squares, renderer, snap=options.snap,
                                      progress=steps.say, up=up)
        steps.done("camera on the render", f"fov {fit.camera.fov_deg:.3f} deg, "
                   f"{up(fit.camera)}, snapped {sorted(fit.snapped)}")
    else:
        arena = provisional
    checkpoint()
    shades = read_shades(real, fit.camera, arena, markers)
    steps.done("shades", f"floor {_grey(shades.floor_rgb)}, background "
               f"{'-' if shades.background_rgb is None else _grey(shades.background_rgb)}, "
               f"{len(shades.boxes)} boxes, faces seen: {', '.join(shades.directions_seen)}")
    camera = fit.camera
    scale = 1.0
    scale_source = geometry.scale_source
    margin = geometry.margin_m
    if not geometry.texture:
        floor_half = None
        if shades.background_rgb is not None:
            floor_half = ag.floor_edge_half(gray, camera, geometry.side_m / 2.0,
                                            floor=_grey(shades.floor_rgb),
                                            background=_grey(shades.background_rgb))
        if options.arena_size_m is not None:
            if floor_half is None:
                raise ag.ArenaError(
                    f"--arena-size {options.arena_size_m[0]:g},{options.arena_size_m[1]:g}: "
                    "the image does not show the floor's edge against the background, so the "
                    "size cannot be placed")
            scale = options.arena_size_m[0] / (2.0 * floor_half)
            scale_source = "floor edge"
        half = geometry.side_m / 2.0
        # no edge seen: the floor reaches past every image corner
        margin = (floor_half - half) if floor_half is not None else (
            1.05 * _view_reach(camera) - half)
    obstacles = tuple(replace(b.obstacle, color_rgb=rgb)
                      for b, rgb in zip(shades.boxes, shades.box_rgb, strict=True))
    background = shades.background_rgb or shades.floor_rgb
    if geometry.texture:
        arena = _texture_arena(geometry, shades.floor_rgb)
    else:
        arena = replace(provisional, margin_m=round(max(margin, 0.0), 6),
                        floor_rgb=shades.floor_rgb)
    scene = Scene(arena=arena, markers=markers, obstacles=obstacles, camera=camera,
                  lighting=shades.lighting, background_rgb=(_grey(background),) * 3)
    texture_rgb = None
    if not geometry.texture:
        scene = replace(scene, arena=replace(scene.arena, floor_rgb=_floor_tint(
            real, scene, shades, finding)))
        scene = _sheet_white(scene, gray, finding, steps, floor=_grey(shades.floor_rgb))
        checkpoint()
        margin = scene.arena.margin_m
        texture_rgb, scene, fit = _own_texture(real, gray, scene, fit, shades, finding,
                                               renderer, options, steps)
        if scale_source == "floor edge" and scene.arena.margin_m != margin:
            # the printed markers' texel grid placed the floor's edge: that edge is the size
            scale = options.arena_size_m[0] / (2.0 * floor_extent(scene.arena))
        steps.done("texture", f"rectified from the image, {texture_rgb.shape[1]} texels a "
                              f"side; camera {scale * fit.camera.altitude_m:.4f} m up, marker "
                              f"side {scale * scene.markers.side_m:.4f} m")
    # 4b. the boxes on the render
    from arenabench.generator.fitting.box_refine import refine_boxes

    checkpoint()
    scene = refine_boxes(scene, gray, renderer, progress=steps.say)
    steps.done("boxes", ", ".join(f"{scale * o.length_m:.3f} x {scale * o.width_m:.3f} x "
                                  f"{scale * o.height_m:.3f} m" for o in scene.obstacles)
               or "none")
    # 6. edges
    checkpoint()
    edges, edge_table = _choose_edges(scene, real, facts_file, renderer)
    if edges.samples is not None:
        scene = replace(scene, render=RenderSpec(edge_samples=edges.samples,
                                                 edge_resolve=edges.resolve or "linear"))
    steps.done("edges", f"{edges.samples or 'open'} samples, "
                        f"{edges.resolve or 'open'} resolve")
    # scale to metres
    if scale != 1.0:
        scene = _scale_scene(scene, scale)
    varied = vary_boxes(scene.obstacles, scene.arena, scene.markers)
    render_bgr = as_written(cv2.cvtColor(renderer.render(scene).rgb, cv2.COLOR_RGB2BGR),
                            facts_file)
    render_gray = cv2.cvtColor(render_bgr, cv2.COLOR_BGR2GRAY)
    masks = region_masks(scene, finding, gray.shape)
    figures = region_figures(render_gray, gray, masks, finding)
    steps.done("figures", f"marker squares {figures.mad['markers']:.2f} grey levels, whole "
                          f"image {figures.whole:.2f}; the default detector's corners "
                          f"{detector_offset_text(figures.detector_px)}")
    verdict = judge(figures, gray, render_gray, masks, corner_rms_px=fit.corner_rms_px)
    steps.done("verdict", verdict.line())
    params = _preset_params(scene, varied, facts_file)
    facts = {
        "image": {"file": image_path.name, "width": width, "height": height,
                  "format": facts_file.format, "jpeg_quality": facts_file.jpeg_quality,
                  "jpeg_subsampling": facts_file.jpeg_subsampling,
                  "jpeg_tables_exact": facts_file.exact},
        "verdict": verdict.to_dict(),
        "markers": {"dictionary": finding.dictionary, "family": list(finding.family),
                    "smallest_holding_the_corner_ids": finding.smallest or finding.dictionary,
                    "ids": list(finding.ids), "others": list(finding.others),
                    "rotation_deg": finding.rotation_deg,
                    "bit_errors": finding.bit_errors, "dictionaries_tried": len(finding.tried)},
        "camera": {"free": _camera_dict(_scale_camera(fit.free, scale)),
                   "snapped": {k: {"unit": u, "value": v} for k, (u, v) in fit.snapped.items()},
                   "stage": fit.stage, "rms_free": fit.rms_free, "rms": fit.rms,
                   "corner_rms_px": fit.corner_rms_px, "sensitivity": fit.sensitivity,
                   "fov_range": None if fit.fov_range is None else list(fit.fov_range)},
        "scale": {"source": scale_source, "factor": round(scale, 9)},
        "shades": {"floor_rgb": list(shades.floor_rgb),
                   "background_rgb": None if shades.background_rgb is None
                   else list(shades.background_rgb),
                   "faces": [{"box": f.box, "direction": f.direction, "gray": f.gray,
                              "pixels": f.pixels} for f in shades.faces],
                   "face_residual": round(shades.face_residual, 4)},
        "edges": {"samples": edges.samples, "resolve": edges.resolve,
                  "edge_pixels": edges.edge_pixels, "blended": edges.blended,
                  "shares": edges.shares, "reason": edges.reason, "models": edge_table},
        "figures": {"mad": figures.mad, "pixels": figures.pixels,
                    "per_marker": {str(k): v for k, v in figures.per_marker.items()},
                    "whole": figures.whole,
                    "ssim": round(ssim(render_gray, gray), 5),
                    "detector_corners_px": {str(k): v for k, v in figures.detector_px.items()}},
    }
    records = _records(scene, params, fit, shades, edges, edge_table, facts_file, finding,
                       varied, scale_source, figures, renderer, gray, verdict)
    steps.done("records", records_text(records))
    return Twin(scene=scene, params=params, records=records, figures=figures, real=real,
                render=render_bgr, texture_rgb=texture_rgb, varied=varied, facts=facts,
                timings=steps.timings, verdict=verdict)


#: Drawn marker sheets this close to the image's marker squares (mean absolute grey
#: difference) are taken without trying painted markers.
DRAWN_MATCH = 1.5
#: Quiet zones tried around drawn marker sheets (modules): every whole texel of the sheet's
#: texture out to two modules. The sheet's side in texels sets its mip chain, and so how its
#: modules' edges blend at the level a view samples: an ``eyrc-jitter`` sheet's quiet zone of
#: 14 texels (0.44 modules) rendered at 16 (0.5, the nearest of the quarter modules tried
#: before) differs by 4.7 grey levels over the marker squares, at 14 by none.
QUIET_ZONES = tuple(t / MODULE_TEXELS for t in range(0, 2 * MODULE_TEXELS + 1))


def _own_texture(real, gray, scene: Scene, fit: cf.CameraFit, shades: Shades,
                 finding: MarkerFinding, renderer, options: TwinOptions,
                 steps: _Steps) -> tuple[np.ndarray, Scene, cf.CameraFit]:
    """Without a texture: the markers either drawn as the generator draws marker sheets, or
    painted into a texture rectified from the image; for each, the camera (and the marker
    side, the quiet zone of drawn ones, the texel grid of painted ones) refined on its render,
    and the one whose marker squares match the image better kept; then the texture rectified
    through that camera and corrected by back-projection."""
    from arenabench.generator.fitting.rectify import (
        Rectification,
        marker_side_search,
        painted_cost,
        rectified_arena,
        texel_grid_search,
        with_extent,
        with_texture,
    )

    squares = np.zeros(gray.shape, bool)
    for m in marker_squares(finding, gray.shape).values():
        squares |= m
    rect = Rectification(real, scene, shades.box_mask)

    def mad(s: Scene) -> float:
        got = cv2.cvtColor(renderer.render(replace(s, obstacles=())).rgb, cv2.COLOR_RGB2GRAY)
        return float(np.abs(got[squares].astype(float) - gray[squares]).mean())

    # drawn sheets: the quiet zone, the camera and side on the render, the quiet zone again
    module = scene.markers.side_m / finding.module_count

    def quiet_zone(s: Scene) -> tuple[Scene, tuple[float, float]]:
        m = s.markers.side_m / finding.module_count
        best = min((mad(replace(s, markers=replace(s.markers, quiet_zone_m=q * m))), q)
                   for q in QUIET_ZONES)
        return replace(s, markers=replace(s.markers, quiet_zone_m=round(best[1] * m, 6))), best

    drawn = with_texture(replace(scene, markers=replace(scene.markers, printed=False,
                                                        quiet_zone_m=module)),
                         rect.texture)
    drawn, _ = quiet_zone(drawn)
    fit_d = cf.refine_with_renderer(fit, drawn, gray, squares, renderer, snap=options.snap,
                                    fit_side=True, progress=steps.say,
                                    up=_sides_up(scene.arena.side_m))
    drawn = replace(drawn, camera=fit_d.camera,
                    markers=replace(drawn.markers, side_m=fit_d.marker_side_m))
    drawn, best_q = quiet_zone(drawn)
    steps.say(f"markers drawn as sheets: {best_q[0]:.2f} grey levels over the marker squares "
              f"(quiet zone {best_q[1]:g} modules)")
    # painted into the texture: how a printed marker's pixels look depends on the texel grid
    # of the texture it was printed on, which a render at another grid cannot match (a camera
    # refined there follows the aliasing, not the geometry); so the grid is searched first,
    # and only on the grid found is the camera refined on the render of the painted markers
    # (on the default grid the marker model's camera is kept)
    painted = replace(scene, markers=replace(scene.markers, printed=True, quiet_zone_m=0.0))
    fit_p = fit
    cost_p = math.inf
    texels = None
    if best_q[0] > DRAWN_MATCH:
        try:
            grid = texel_grid_search(real, gray, painted, shades.box_mask, squares, renderer,
                                     progress=steps.say)
        except ValueError as exc:  # no floor outside the markers: no boundary to align to
            steps.say(f"texel grid: the default one ({exc})")
        else:
            texels = grid.side
            steps.say(f"texel grid: {texels} texels a side over "
                      f"{grid.extent_m / floor_extent(scene.arena):.5f} of the floor's extent "
                      f"as its edge gave it, the markers' outer corners on texel boundaries "
                      f"({grid.cost:.2f} grey levels over the marker squares)")
            painted = with_extent(painted, grid.extent_m)
            rect = Rectification(real, painted, shades.box_mask, texels=texels)
        side, cost_p = marker_side_search(gray, painted, rect, squares, renderer)
        painted = replace(painted, markers=replace(painted.markers, side_m=side))
        fit_p = replace(fit_p, marker_side_m=side)
        if texels is not None:
            shown = with_texture(painted, rect.painted(painted)[0])
            fit_p = cf.refine_with_renderer(fit_p, shown, gray, squares, renderer,
                                            snap=options.snap, progress=steps.say,
                                            up=_sides_up(scene.arena.side_m))
            painted = replace(painted, camera=fit_p.camera)
            rect = Rectification(real, painted, shades.box_mask, texels=texels,
                                 fill_hidden=False)
            cost_p = painted_cost(gray, painted, rect, squares, renderer)
        steps.say(f"markers painted into the texture: {cost_p:.2f} grey levels over the marker "
                  "squares")
    if best_q[0] <= cost_p:
        chosen, fit, texels = replace(drawn, arena=scene.arena), fit_d, None
    else:  # the floor's extent the texel grid gives
        chosen, fit = replace(painted, arena=replace(scene.arena,
                                                     margin_m=painted.arena.margin_m)), fit_p
    chosen = replace(chosen, obstacles=scene.obstacles)
    texture_rgb, chosen = rectified_arena(real, chosen, shades.box_mask, renderer,
                                          texels=texels, progress=steps.say)
    return texture_rgb, chosen, fit


#: The field of view is open when the markers fit as well over a wider span than this (deg).
FOV_PINNED_SPAN_DEG = 0.5


def _fov_open(fit: cf.CameraFit) -> bool:
    return fit.fov_range is not None and fit.fov_range[1] - fit.fov_range[0] > FOV_PINNED_SPAN_DEG


def _trade_ends(fit: cf.CameraFit, key: str, own: float, metres: float) -> tuple[float, float]:
    """Orbit parameter ``key`` (:data:`~.camera_fit.ORBIT`) at the two ends of the
    field-of-view trade, for a camera whose value is ``own``: ``own`` moved as the fits at
    the ends (:attr:`CameraFit.fov_ends`) moved from the free fit, lengths times ``metres``
    (the fit's units to metres). The preset's camera is the free fit snapped and refined; it
    moves along the same trade."""
    assert fit.fov_ends is not None
    free = dict(zip(cf.ORBIT, cf.orbit_vector(fit.free), strict=True))
    unit = metres if key in ("target_x", "target_y", "altitude_m") else 1.0
    # within the parameter's bounds: seen from the nadir the trade would tilt the camera
    # below 0 deg, which no camera of the generator is (the trade ends there)
    bounds = PARAMETERS[_CAMERA_NAMES[key]].bounds
    lo, hi = (round(min(max(own + (end[key] - free[key]) * unit, bounds.lo), bounds.hi), 6)
              for end in fit.fov_ends)
    return lo, hi


def _fov_companions(fit: cf.CameraFit, params: dict[str, Value], names: dict[str, str]
                    ) -> tuple[tuple[str, tuple[float, float]], ...]:
    """The camera parameters that move with the field of view along its open range
    (:func:`_trade_ends`), at its low and high end. The altitude always moves; another
    parameter when it moves by at least its pinned-residual step (1 mm, 0.01 deg)."""
    metres = params["camera.altitude_m"] / fit.camera.altitude_m
    out = []
    for key, name in names.items():
        if key == "fov_deg":
            continue
        own = float(params[name])
        ends = _trade_ends(fit, key, own, metres)
        if key == "altitude_m" or max(abs(e - own) for e in ends) >= cf.SENSITIVITY_STEPS[key]:
            out.append((name, ends))
    return tuple(sorted(out))


def _fov_trade(fit: cf.CameraFit, key: str, value: float) -> Range:
    """The range of the field of view (``key`` ``fov_deg``) or of the altitude (``value``:
    the preset's, in metres) along the trade that fits as well (:func:`_trade_ends`)."""
    lo, hi = sorted(_trade_ends(fit, key, value, value / fit.camera.altitude_m))
    return Range(round(min(lo, value), 6), round(max(hi, value), 6))


def _open_light(params: dict[str, Value], shades: Shades, unseen: list[str],
                evidence: str) -> dict[str, rec.Record]:
    """The light's records where fewer than two side-face directions are seen: many lights
    give the faces seen (:mod:`~arenabench.generator.fitting.light_span`). The azimuth is open
    with one value per light that makes an unseen direction's faces darkest or lightest, and
    the ambient, intensity and elevation move with it (their ranges span those lights)."""
    from arenabench.generator.fitting.light_span import FACE_TOLERANCE, Light, light_extremes

    own = Light(ambient=float(params["lighting.ambient"]),
                intensity=float(params["lighting.intensity"]),
                elevation_deg=float(params["lighting.elevation_deg"]),
                azimuth_deg=float(params["lighting.azimuth_deg"]))
    lights = [own]
    floor = own.ambient + own.intensity * math.sin(math.radians(own.elevation_deg))
    for extreme in light_extremes(shades.boxes, unseen, floor=floor):
        if extreme.light not in lights:
            lights.append(extreme.light)
    azimuths: list[float] = []
    for light in lights:  # the azimuth names the variant: two lights never share one
        az = light.azimuth_deg
        while az in azimuths:
            az = round(az + 0.001, 6)
        azimuths.append(az)
    keys = ("lighting.ambient", "lighting.elevation_deg", "lighting.intensity")
    moves = tuple((k, tuple(float(light.params()[k]) for light in lights)) for k in keys)
    seen = ", ".join(shades.directions_seen) or "none"
    why = (f"side faces seen: {seen}: many lights give them (each within "
           f"{FACE_TOLERANCE:g} grey level of the best); the variants are the lights that make "
           f"the {', '.join(unseen)} faces darkest and lightest")
    out = {"lighting.azimuth_deg": rec.open_values(
        "lighting.azimuth_deg", params["lighting.azimuth_deg"], tuple(azimuths), why,
        evidence=evidence, moves_with=moves)}
    for k, values in moves:
        lo, hi = min(values), max(values)
        out[k] = (rec.open_range(k, params[k], Range(lo, hi), f"moves with the light's "
                                 f"azimuth: {why}", evidence=evidence) if hi > lo else
                  rec.open_values(k, params[k], (params[k],), f"the same in every light that "
                                  f"gives the faces seen: {why}", evidence=evidence))
    return out


#: The marker sheets' white is clipped (paper under a light brighter than it: nothing to dim)
#: when at least this share of the white pixels is 255: on the blind round trips' images the
#: share is 0.70-1.00 where the light saturates white and 0.00 everywhere else, whites of 250
#: included (docs/measurements.md).
CLIPPED_SHARE = 0.5


#: The share of the floor's pixels at most as light as the rectified texture's tint (the rest
#: clip at the texture's white).
TINT_PERCENTILE = 99.5


def _floor_tint(real: np.ndarray, scene: Scene, shades: Shades, finding: MarkerFinding
                ) -> tuple[int, int, int]:
    """The tint of a texture rectified from the image: the floor's lightest grey
    (:data:`TINT_PERCENTILE`, per channel; boxes and markers left out), so that the texture,
    stored relative to it, keeps the floor's lighter pixels below its white (stored relative
    to the commonest grey they would clip, and the floor come out darker where it is lighter)."""
    from arenabench.generator.fitting.shades import floor_square_mask

    shape = real.shape[:2]
    floor = floor_square_mask(scene.camera, shape, scene.arena.side_m / 2.0)
    floor &= ~cv2.dilate(shades.box_mask.astype(np.uint8), np.ones((9, 9), np.uint8)
                         ).astype(bool)
    for m in marker_squares(finding, shape).values():
        floor &= ~m
    if floor.sum() < 1000:
        return shades.floor_rgb
    rgb = cv2.cvtColor(real, cv2.COLOR_BGR2RGB)
    return tuple(max(min(math.ceil(float(np.percentile(rgb[..., c][floor], TINT_PERCENTILE))),
                         255), shades.floor_rgb[c]) for c in range(3))


def _sheet_white(scene: Scene, gray: np.ndarray, finding: MarkerFinding, steps: _Steps, *,
                 floor: float) -> Scene:
    """``scene`` lit so that white paper shows the image's marker white: drawn marker sheets
    are white (255) lit like the floor, so a white below 255 that is not clipped (fewer than
    :data:`CLIPPED_SHARE` of its pixels at 255) means a dimmer light over lighter albedos
    (floor and box greys divided by the same factor, every face's shade kept).
    The white is the median of the marker squares' pixels above the middle between the floor
    and their 99th percentile (the white modules and quiet zones; the percentile alone would
    take JPEG ringing's overshoot)."""
    from arenabench.generator.model.shading import floor_factor

    squares = np.zeros(gray.shape, bool)
    for m in marker_squares(finding, gray.shape).values():
        squares |= m
    values = gray[squares].astype(np.float64)
    top = float(np.percentile(values, 99))
    bright = values[values >= (floor + top) / 2.0]
    white = float(np.median(bright)) if bright.size else top
    k = white / 255.0
    clipped = bright.size == 0 or float(np.mean(bright >= 254.5)) >= CLIPPED_SHARE
    if clipped or k * 255.0 < floor or floor / k > 255.0:
        return scene
    lit = scene.lighting
    lighting = replace(lit, ambient=round(lit.ambient * k / floor_factor(lit), 6),
                       directional=tuple(replace(d, intensity=round(d.intensity * k
                                                                    / floor_factor(lit), 6))
                                         for d in lit.directional))

    def albedo(rgb) -> tuple[int, ...]:
        return tuple(min(round(v / k), 255) for v in rgb)

    steps.say(f"marker white {white:.0f}: the light dimmed to {k:.3f} of white")
    return replace(scene, lighting=lighting,
                   arena=replace(scene.arena, floor_rgb=albedo(scene.arena.floor_rgb)),
                   obstacles=tuple(replace(o, color_rgb=albedo(o.color_rgb))
                                   for o in scene.obstacles))


def _scale_range(name: str, value: float) -> Range:
    """What a length allows when the scale is open: a tenth to ten times itself (within the
    parameter's bounds)."""
    from arenabench.generator.parameters.params import PARAMETERS

    lo, hi = sorted((round(value * 0.1, 6), round(value * 10.0, 6)))
    b = PARAMETERS[name].bounds
    return Range(max(lo, b.lo), min(hi, b.hi))


def _view_reach(camera) -> float:
    """The largest |x| or |y| (m) on the floor seen at the image's corners."""
    h = cam.floor_homography(cam.intrinsics(camera), cam.world_from_camera(camera))
    corners = np.array([[0, 0], [camera.width - 1, 0], [camera.width - 1, camera.height - 1],
                        [0, camera.height - 1]], np.float64)
    world = cv2.perspectiveTransform(corners.reshape(-1, 1, 2), np.linalg.inv(h)).reshape(-1, 2)
    return float(np.abs(world).max())


def _texture_arena(geometry: ag.ArenaGeometry, floor_rgb) -> ArenaSpec:
    if geometry.texture == comp.TEXTURE_NAME:
        return ArenaSpec(side_m=comp.ARENA_SIDE_M, margin_m=comp.ARENA_MARGIN_M,
                         texture=comp.TEXTURE_NAME, border_width_m=0.0, logo_text="",
                         floor_rgb=tuple(floor_rgb))
    side = round(geometry.side_m + 2.0 * geometry.margin_m, 6)  # the floor square it covers
    return ArenaSpec(side_m=geometry.side_m, margin_m=geometry.margin_m,
                     texture=IMAGE_TEXTURE,
                     texture_file=texture_store.import_texture(
                         geometry.texture_path, where=f"--texture {geometry.texture_path}"),
                     texture_size_m=(side, side), border_width_m=0.0, logo_text="",
                     grid_step_m=0.0, floor_rgb=tuple(floor_rgb))


def _scale_camera(camera, factor: float):
    return replace(camera, altitude_m=round(camera.altitude_m * factor, 6),
                   target_m=tuple(round(v * factor, 6) for v in camera.target_m))


def _camera_dict(camera) -> dict[str, Any]:
    return {"fov_deg": camera.fov_deg, "altitude_m": camera.altitude_m,
            "tilt_deg": camera.tilt_deg, "yaw_deg": camera.yaw_deg,
            "roll_deg": camera.roll_deg, "target_m": list(camera.target_m)}


def _choose_edges(scene: Scene, real: np.ndarray, facts: FileFacts, renderer
                  ) -> tuple[EdgeEvidence, dict[str, dict[str, Any]]]:
    """The edge model whose render, written as the image was, shows the image's edge
    statistics (:func:`read_edges`' shares) most closely; open when two models are about as
    close or no box shows an edge."""
    gray = cv2.cvtColor(real, cv2.COLOR_BGR2GRAY)
    band = outline_band(scene.obstacles, scene.camera, gray.shape)
    want = read_edges(gray, band)
    if not scene.obstacles or want.edge_pixels == 0:
        return replace(want, samples=None, resolve=None,
                       reason="no box edge in the image"), {}
    keys = sorted(want.shares)

    def vector(e: EdgeEvidence) -> np.ndarray:
        return np.array([e.blended / max(e.edge_pixels, 1)] + [e.shares[k] for k in keys])

    table = {}
    distances = {}
    for samples, resolve_ in EDGE_MODELS:
        checkpoint()
        s = replace(scene, render=RenderSpec(edge_samples=samples, edge_resolve=resolve_))
        bgr = as_written(cv2.cvtColor(renderer.render(s).rgb, cv2.COLOR_RGB2BGR), facts)
        g = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
        got = read_edges(g, band)
        d = float(np.linalg.norm(vector(got) - vector(want)))
        band_mad = float(np.abs(g.astype(float) - gray)[band].mean())
        key = f"{samples}/{resolve_}"
        distances[key] = d
        table[key] = {"distance": round(d, 4), "band_mad": round(band_mad, 4),
                      "blended": got.blended}
    order = sorted(distances, key=distances.get)
    best, second = order[0], order[1]
    samples, resolve_ = int(best.split("/")[0]), best.split("/")[1]
    reason = ""
    if samples == 1:
        resolve_out: str | None = None
        reason = "hard edges: where samples would be averaged is not seen"
    else:
        resolve_out = resolve_
    if distances[second] < 1.5 * distances[best] and second.split("/")[0] != best.split("/")[0]:
        return replace(want, samples=None, resolve=None, shares=want.shares,
                       reason=f"the image's edges fit {best} and {second} about as well"), table
    if (samples > 1 and second.split("/")[0] == str(samples)
            and distances[second] < 1.5 * distances[best]):
        resolve_out = None
        reason = f"the image's edges fit both resolves of {samples} samples about as well"
    return replace(want, samples=samples, resolve=resolve_out, reason=reason), table


def _preset_params(scene: Scene, varied: list[Varied], facts: FileFacts) -> dict[str, Value]:
    """The twin's preset: the fitted scene's camera, light, greys, arena and edges held, the
    boxes varied."""
    c, light, a, m = scene.camera, scene.lighting, scene.arena, scene.markers
    d = light.directional[0].direction if light.directional else (0.0, 0.0, -1.0)
    norm = math.sqrt(sum(v * v for v in d))
    grays = sorted({o.color_rgb[0] for o in scene.obstacles}) or [120]
    params: dict[str, Value] = {
        "arena.side_m": a.side_m, "arena.margin_m": a.margin_m, "arena.floor_rgb": a.floor_rgb,
        "arena.texture": a.texture, "arena.texture_seed": 0, "arena.texture_file":
            a.texture_file, "arena.texture_size_m": a.texture_size_m,
        "arena.border_width_m": 0.0, "arena.border_rgb": (20, 20, 20),
        "arena.grid_step_m": 0.0, "arena.grid_rgb": (200, 200, 200), "arena.logo_text": "",
        "arena.logo_rgb": (220, 50, 50),
        "markers.dictionary": m.dictionary, "markers.ids": m.ids, "markers.side_m": m.side_m,
        "markers.rotation_deg": m.rotation_deg, "markers.quiet_zone_m": m.quiet_zone_m,
        "markers.printed": m.printed,
        "obstacles.palette": "gray", "obstacles.max_tries": 500,
        "obstacles.gray": grays[0] if len(grays) == 1 else Range(grays[0], grays[-1]),
        "camera.width": c.width, "camera.height": c.height, "camera.fov_deg": c.fov_deg,
        "camera.altitude_m": c.altitude_m, "camera.tilt_deg": c.tilt_deg,
        "camera.yaw_deg": c.yaw_deg, "camera.roll_deg": c.roll_deg,
        "camera.target_x_m": c.target_m[0], "camera.target_y_m": c.target_m[1],
        "camera.markers_in_view": True, "camera.max_tries": 100,
        "lighting.ambient": light.ambient,
        "lighting.intensity": light.directional[0].intensity if light.directional else 0.0,
        "lighting.elevation_deg": round(math.degrees(math.asin(min(-d[2] / norm, 1.0))), 6),
        "lighting.azimuth_deg": round(math.degrees(math.atan2(-d[1], -d[0])), 6),
        "background.gray": scene.background_rgb[0],
        "render.edge_samples": scene.render.edge_samples,
        "render.edge_resolve": scene.render.edge_resolve,
        "output.format": facts.output_format,
    }
    if facts.format == "jpeg":
        params["output.jpeg_quality"] = facts.jpeg_quality
        params["output.jpeg_subsampling"] = facts.jpeg_subsampling
    for v in varied:
        params[v.name] = v.value
    if a.texture == comp.TEXTURE_NAME:
        # the competition texture fixes its own geometry
        params["arena.side_m"], params["arena.margin_m"] = comp.ARENA_SIDE_M, comp.ARENA_MARGIN_M
    return resolve(params)


@dataclass(frozen=True)
class _Found:
    """What the twin found, for the records: the scene and its parameters, the camera fit,
    the shades, the edges, the file's facts, the markers, the varied parameters, where the
    scale came from and the figures of the fitted render."""

    scene: Scene
    params: dict[str, Value]
    fit: Any
    shades: Shades
    edges: EdgeEvidence
    edge_table: dict
    file: FileFacts
    finding: MarkerFinding
    varied: list[Varied]
    scale_source: str
    figures: RegionFigures
    verdict: FitVerdict

    @property
    def own_texture(self) -> bool:
        """The arena's texture is rectified from the image (not given, not built in)."""
        return self.scene.arena.texture == IMAGE_TEXTURE and self.scale_source != "texture"


def _records(scene, params, fit, shades: Shades, edges: EdgeEvidence, edge_table,
             facts_file: FileFacts, finding: MarkerFinding, varied: list[Varied],
             scale_source: str, figures: RegionFigures, renderer, gray,
             verdict: FitVerdict) -> list[rec.Record]:
    """Every parameter pinned (with its residual) or open (with its range and why)."""
    from arenabench.generator.fitting.residuals import pinned_residuals

    found = _Found(scene, params, fit, shades, edges, edge_table, facts_file, finding, varied,
                   scale_source, figures, verdict)
    res = pinned_residuals(scene, gray, renderer, finding)
    r: dict[str, rec.Record] = {}
    for group in (_camera_records, _marker_records, _arena_records, _light_records,
                  _edge_records, _output_records, _varied_records):
        r.update(group(found, res))
    return rec.complete(r, params)


#: the camera's fitted values -> their parameters
_CAMERA_NAMES = {"target_x": "camera.target_x_m", "target_y": "camera.target_y_m",
                 "altitude_m": "camera.altitude_m", "tilt_deg": "camera.tilt_deg",
                 "yaw_deg": "camera.yaw_deg", "roll_deg": "camera.roll_deg",
                 "fov_deg": "camera.fov_deg"}


def _camera_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """The camera: fitted to the markers (snapped to round values that fit), open up to scale
    without a size, the field of view and the altitude open together where they trade."""
    fit, params, r = f.fit, f.params, {}
    sens_unit = ("grey levels RMS over the marker squares per 1 mm / 0.01 deg"
                 if fit.stage == "render" else
                 "linear grey levels RMS over the marker modules per 1 mm / 0.01 deg")
    for key, name in _CAMERA_NAMES.items():
        snapped = fit.snapped.get(key)
        how = (f"fitted freely to the markers, then held at the round {snapped[1]:g} {snapped[0]}"
               + (" of pitch" if key == "tilt_deg" else "") if snapped
               else "fitted to the markers' pixels")
        if key == "yaw_deg" and fit.nadir:
            how = (f"held at 0: within {cf.NADIR_TILT_DEG:g} deg of the nadir the heading and "
                   "the roll turn the image alike, and the turn is fitted as the roll")
        if f.scale_source == "default" and key in ("target_x", "target_y", "altitude_m"):
            r[name] = rec.open_range(name, params[name], _scale_range(name, params[name]),
                                     "the image fixes the camera only up to scale (no "
                                     "--arena-size): every length scales with its distance",
                                     evidence=how, gauge=True)
        elif key in ("fov_deg", "altitude_m") and _fov_open(fit):
            r[name] = rec.open_range(name, params[name], _fov_trade(fit, key, params[name]),
                                     f"the markers fit as well from {fit.fov_range[0]:.2f} to "
                                     f"{fit.fov_range[1]:.2f} deg of field of view: a near-nadir "
                                     "view of a flat arena trades the field of view against the "
                                     "altitude, only the weak perspective of the tilt tells "
                                     "them apart" + ("; the camera moves with it" if key ==
                                                     "fov_deg" else "; moves with the field of"
                                                     " view"), evidence=how,
                                     moves_with=(_fov_companions(fit, params, _CAMERA_NAMES)
                                                 if key == "fov_deg" else ()))
        else:
            if key in ("tilt_deg", "yaw_deg", "roll_deg") and _fov_open(fit):
                how += (" (for the field of view held: along the span of fields of view that "
                        "fit as well the tilt moves with it)")
            r[name] = rec.pinned(name, params[name], how, fit.sensitivity.get(key), sens_unit)
    for name in ("camera.width", "camera.height"):
        r[name] = rec.pinned(name, params[name], "the image's size")
    return r


def _marker_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """The markers: dictionary and ids decoded, rotations, side, drawn or printed."""
    scene, params, finding, r = f.scene, f.params, f.finding, {}
    r["markers.dictionary"] = rec.pinned(
        "markers.dictionary", params["markers.dictionary"],
        f"every one of {len(finding.tried)} dictionaries tried; the family "
        f"{', '.join(finding.family)} prints the same markers, the smallest holding the ids "
        "is named", finding.bit_errors, "bit errors")
    r["markers.ids"] = rec.pinned("markers.ids", params["markers.ids"],
                                  "decoded, named by corner", finding.bit_errors, "bit errors")
    r["markers.rotation_deg"] = rec.pinned("markers.rotation_deg", params["markers.rotation_deg"],
                                           "where each marker's corner 0 lies")
    r["markers.side_m"] = (rec.pinned("markers.side_m", params["markers.side_m"],
                                      "located in the texture") if scene.arena.texture
                           in (comp.TEXTURE_NAME,) or f.fit.stage == "render"
                           else rec.pinned("markers.side_m", params["markers.side_m"],
                                           "fitted to the markers' pixels with the camera"))
    if f.own_texture:
        how = ("painted into the rectified texture, on the texel grid that puts their outer "
               "corners on texel boundaries and matches them best (their pixels fit better so "
               "than drawn as marker sheets)" if scene.markers.printed else
               "drawn as marker sheets over the rectified texture (their pixels match the "
               "image's better than painted ones, or within 1.5 grey levels)")
        r["markers.printed"] = rec.pinned("markers.printed", params["markers.printed"], how)
        if not scene.markers.printed:
            r["markers.quiet_zone_m"] = rec.pinned(
                "markers.quiet_zone_m", params["markers.quiet_zone_m"],
                "the white around the markers, searched in quarter modules on the render")
    elif scene.arena.texture == IMAGE_TEXTURE:
        r["markers.printed"] = rec.pinned("markers.printed", True,
                                          "the given texture's markers are the image's")
    return r


def _arena_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """The arena: its texture, its size (open up to scale without one), the floor and the
    background greys."""
    scene, params, scale_source, r = f.scene, f.params, f.scale_source, {}
    if scene.arena.texture in (comp.TEXTURE_NAME, IMAGE_TEXTURE):
        source = ("the given texture" if scale_source == "texture"
                  else "rectified from the image")
        r["arena.texture"] = rec.pinned("arena.texture", params["arena.texture"], source)
        if scene.arena.texture == IMAGE_TEXTURE:
            r["arena.texture_file"] = rec.pinned("arena.texture_file",
                                                 params["arena.texture_file"], source)
            r["arena.texture_size_m"] = rec.pinned(
                "arena.texture_size_m", params["arena.texture_size_m"],
                "the floor square it covers (arena.side_m + 2 arena.margin_m)")
    for name in ("arena.side_m", "arena.margin_m"):
        if scale_source == "default":
            r[name] = rec.open_range(name, params[name], _scale_range(name, params[name]),
                                     "the image fixes the arena only up to scale (no "
                                     "--arena-size or texture): any size, every length "
                                     "scaled alike", gauge=True)
        elif (scale_source == "floor edge" and scene.markers.printed
              and scene.arena.texture == IMAGE_TEXTURE):
            r[name] = rec.pinned(name, params[name], "from the floor edge, placed to within "
                                 "a texel by the texel grid of the printed markers")
        else:
            r[name] = rec.pinned(name, params[name], f"from the {scale_source}")
    r["arena.floor_rgb"] = rec.pinned("arena.floor_rgb", params["arena.floor_rgb"],
                                      "the floor's commonest grey inside the markers' square"
                                      if scene.arena.texture != IMAGE_TEXTURE or scale_source
                                      == "texture" else "the rectified texture's tint: the "
                                      f"floor's lightest grey ({TINT_PERCENTILE:g}th percentile;"
                                      f" its commonest as seen is {list(f.shades.floor_rgb)})",
                                      res.get("arena.floor_rgb"),
                                      "grey levels MAD over the floor per grey level")
    if f.shades.background_rgb is None:
        r["background.gray"] = rec.open_range("background.gray", params["background.gray"],
                                              Range(0, 255), "the image shows no background")
    else:
        r["background.gray"] = rec.pinned("background.gray", params["background.gray"],
                                          "the commonest grey around the floor",
                                          res.get("background.gray"),
                                          "grey levels MAD over the background per grey level")
    return r


def _light_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """The light: pinned by two or more faces seen, open otherwise; fills of unseen sides
    open; the boxes' palette."""
    shades, params, r = f.shades, f.params, {}
    light_evidence = (f"faces seen: top and {', '.join(shades.directions_seen) or 'no side'}; "
                      f"their shades within {shades.face_residual:.2f} grey levels RMS")
    unseen = [d for d in ("east", "west", "north", "south") if d not in shades.directions_seen]
    if len(shades.directions_seen) >= 2:
        for name in ("lighting.ambient", "lighting.intensity", "lighting.elevation_deg",
                     "lighting.azimuth_deg"):
            r[name] = rec.pinned(name, params[name], light_evidence + "; the weakest light that "
                                 "gives them (an unseen face keeps about the ambient shade)",
                                 res.get("lighting"), "grey levels MAD over the faces seen "
                                 "per 1 % of light")
    else:
        r.update(_open_light(params, shades, unseen, light_evidence))
    for side in ("east", "west"):
        name = f"lighting.{side}_fill"
        if side in unseen:
            r[name] = rec.open_range(name, 0.0, Range(0.0, 1.0),
                                     f"{side} faces not visible: any shade from the main light's "
                                     "(fill 0) to the top face's", evidence=light_evidence)
        else:
            r[name] = rec.pinned(name, 0.0, f"{side} faces seen and given by the main light")
    r["obstacles.palette"] = rec.pinned("obstacles.palette", "gray", "grey boxes")
    return r


def _edge_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """The edge model: the one whose renders match the image's box outlines best, or open
    where the image cannot tell."""
    edges, edge_table, params, r = f.edges, f.edge_table, f.params, {}
    if edges.samples is None:
        r["render.edge_samples"] = rec.open_values("render.edge_samples",
                                                   params["render.edge_samples"], (1, 2, 4),
                                                   edges.reason)
        r["render.edge_resolve"] = rec.open_values("render.edge_resolve",
                                                   params["render.edge_resolve"],
                                                   ("linear", "srgb"), edges.reason)
        return r
    best = f"{edges.samples}/{edges.resolve or 'linear'}"
    others = {k: v["band_mad"] for k, v in edge_table.items() if k != best}
    near = min(others.values()) if others else None
    base = edge_table.get(best, {}).get("band_mad")
    r["render.edge_samples"] = rec.pinned(
        "render.edge_samples", params["render.edge_samples"],
        f"{edges.blended} of {edges.edge_pixels} edge pixels blended; the renders of every "
        "edge model compared", None if near is None or base is None else near - base,
        "grey levels MAD in the 2 px band around the boxes, next model minus this one")
    if edges.resolve is None:
        r["render.edge_resolve"] = rec.open_values("render.edge_resolve",
                                                   params["render.edge_resolve"],
                                                   ("linear", "srgb"), edges.reason)
    else:
        r["render.edge_resolve"] = rec.pinned("render.edge_resolve",
                                              params["render.edge_resolve"],
                                              "the blends' shares in each space")
    return r


def _output_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """The file's format and JPEG settings, and the degradations the render does without."""
    params, facts_file, r = f.params, f.file, {}
    r["output.format"] = rec.pinned("output.format", params["output.format"],
                                    "the file's signature")
    if facts_file.format == "jpeg":
        r["output.jpeg_quality"] = rec.pinned(
            "output.jpeg_quality", params["output.jpeg_quality"],
            "the file's quantisation tables" + ("" if facts_file.exact else
                                                " (not libjpeg's exactly: the nearest quality)"))
        r["output.jpeg_subsampling"] = rec.pinned("output.jpeg_subsampling",
                                                  params["output.jpeg_subsampling"],
                                                  "the file's frame header")
    for name, what, kind in UNRENDERED:
        seen = [c for c in f.verdict.causes if c.kind == kind]
        if seen:  # the image has it and the twin renders none: said, not fitted
            r[name] = rec.open_values(name, params[name], (params[name],),
                                      f"not fitted: the image shows {seen[0].text}")
        else:
            r[name] = rec.pinned(name, params[name], f"the render without {what} matches the "
                                 f"image (whole image within {f.figures.whole:.2f} grey "
                                 "levels)")
    return r


def _varied_records(f: _Found, res: dict) -> dict[str, rec.Record]:
    """What one image shows one draw of (the boxes): open, with the rule of their variation."""
    r = {}
    for v in f.varied:
        value = f.params[v.name]
        if isinstance(value, Range):
            r[v.name] = rec.open_range(v.name, value, value, f"one image shows one draw: "
                                       f"{v.rule}", evidence=v.seen, varies=True)
        else:
            r[v.name] = rec.open_values(v.name, value, (value,), f"one image shows one draw: "
                                        f"{v.rule}", evidence=v.seen, varies=True)
    return r
