"""The parameter registry: one declaration per scene parameter.

Every parameter a preset, ``--set`` or ``--vary`` can name is one :class:`Param` in
:data:`PARAMS`. Everything else is derived from it: validation and the ``--set`` spellings
(:mod:`arenabench.generator.parameters.presets`), ``arenabench presets --params``, the neutral
values a
preset that lacks a parameter gets (:data:`NEUTRAL`), which parameters the sampler draws and from
which random stream (:mod:`arenabench.generator.model.sampler`), where each value lands in the scene
(:func:`assemble`) and which :class:`~arenabench.generator.rendering.degrade.Degradations` field it
sets.

A range is a :class:`Range` (``lo:hi`` on the command line, ``[lo, hi]`` in JSON), never a bare
2-tuple.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.assets.texture_store import IMAGE_TEXTURE
from arenabench.imageio import DEFAULT_JPEG_SUBSAMPLING, JPEG_SUBSAMPLINGS
from arenabench.limits import MAX_IMAGE_SIDE_PX

#: Value kinds of a parameter; only "float" and "int" accept ranges. "size" is a width and a
#: height (two numbers, each within the bounds); "file" an image file kept by its content
#: (:mod:`arenabench.generator.assets.texture_store`: the value becomes ``textures/<sha256>.png``).
KINDS = ("float", "int", "str", "rgb", "ids", "bool", "size", "file")
#: When a parameter is drawn: once per scene (and recorded in the GT's ``params``), once per
#: obstacle, or only when a preset or ``--set`` gives it as a range ("fixed").
DRAWS = ("scene", "box", "fixed")
#: Where the value goes: a section of the scene, or the image degradations.
SECTIONS = ("arena", "markers", "camera", "lighting", "render", "degrade")


@dataclass(frozen=True)
class Range:
    """A closed range ``[lo, hi]`` of a numeric parameter, drawn uniformly per scene.

    Real parameters draw uniformly over [lo, hi); integer ones over the integers lo..hi.

    Parameters
    ----------
    lo, hi : float or int
        The ends, finite numbers with ``lo <= hi``.

    Raises
    ------
    ValueError
        For a non-number, a non-finite end or ``lo > hi``.
    """

    lo: float
    hi: float

    def __post_init__(self) -> None:
        for end in (self.lo, self.hi):
            if isinstance(end, bool) or not isinstance(end, (int, float)):
                raise ValueError(f"range ends must be numbers, got {self.lo!r}:{self.hi!r}")
            if not math.isfinite(end):
                raise ValueError(f"range ends must be finite, got {self.lo!r}:{self.hi!r}")
        if self.lo > self.hi:
            raise ValueError(f"empty range {self.lo!r}:{self.hi!r} (lo > hi)")

    def __str__(self) -> str:
        return f"{self.lo:.10g}:{self.hi:.10g}"


#: A parameter value: a fixed value (number, text, bool, tuple of ints) or a :class:`Range`.
Value = Any


@dataclass(frozen=True)
class Param:
    """Declaration of one scene parameter.

    Attributes
    ----------
    name : str
        Dotted name (``camera.tilt_deg``) used by presets, ``--set``, ``--vary`` and the GT.
    kind : {"float", "int", "str", "rgb", "ids", "bool", "size", "file"}
        How values are parsed (:data:`KINDS`); only "float" and "int" accept ranges.
    help : str
        One line for ``arenabench presets --params``.
    bounds : Range or None
        Inclusive bounds of a number (``None``: any).
    choices : tuple of str
        Allowed values of a "str" or "int" parameter, spelt as on the command line (empty =
        any); a range of an "int" parameter with choices draws among the choices inside it.
    neutral : value or None
        The value a preset that lacks the parameter gets; it changes nothing in the image
        (``None``: every preset must give the parameter).
    lands : str
        Where the value goes: a dotted path in the scene (``camera.target_m.0``,
        ``lighting.directional.0.intensity``; numbers index sequences) or ``degrade.FIELD``
        (a :class:`~arenabench.generator.rendering.degrade.Degradations` field); empty when the
        sampler
        reads it itself (obstacle sizes and placement, light angles, distractors, tries).
    draw : {"scene", "box", "fixed"}
        When it is drawn (see :data:`DRAWS`).
    stream : str
        Name of the random stream its draws come from; empty = the parameter's own name.
        Every stream is seeded by (seed, index, stream name) (see
        :func:`arenabench.generator.model.sampler.stream_rng`), so adding, removing or reordering a
        parameter moves no other draw. A renamed parameter keeps drawing what it drew by
        naming its old stream here.
    redraw : bool
        Drawn again with the camera when the markers are not all in view.
    """

    name: str
    kind: str
    help: str
    bounds: Range | None = None
    choices: tuple[str, ...] = ()
    neutral: Value = None
    lands: str = ""
    draw: str = "fixed"
    stream: str = ""
    redraw: bool = False

    def __post_init__(self) -> None:
        if not self.stream:
            object.__setattr__(self, "stream", self.name)
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind must be one of {', '.join(KINDS)}, "
                             f"got {self.kind!r}")
        if self.draw not in DRAWS:
            raise ValueError(f"{self.name}: draw must be one of {', '.join(DRAWS)}, "
                             f"got {self.draw!r}")
        if self.choices and self.kind not in ("str", "int"):
            raise ValueError(f"{self.name}: only str and int parameters have choices")
        if self.lands and self.lands.split(".")[0] not in SECTIONS:
            raise ValueError(f"{self.name}: lands must start with one of "
                             f"{', '.join(SECTIONS)}, got {self.lands!r}")

    @property
    def post_render(self) -> bool:
        """Whether it acts on the rendered image only (a ``degrade.*`` degradation): scenes
        that differ only in such parameters render to the same pixels and ground truth."""
        return self.lands.split(".")[0] == "degrade"

    @property
    def numeric(self) -> bool:
        """Whether the parameter is a number (and so may be a :class:`Range`)."""
        return self.kind in ("float", "int")

    def values_in(self, lo: float, hi: float) -> tuple[int, ...]:
        """The choices of an "int" parameter with choices that lie in ``[lo, hi]``, in order."""
        return tuple(v for v in sorted(int(c) for c in self.choices) if lo <= v <= hi)


def _b(lo: float, hi: float) -> Range:
    return Range(lo, hi)


#: Every parameter, in declaration order (the order of ``arenabench presets --params``).
PARAMS: tuple[Param, ...] = (
    Param("arena.side_m", "float", "side of the border-line square (m)", _b(0.5, 1000),
          lands="arena.side_m"),
    Param("arena.margin_m", "float", "floor beyond the border line (m)", _b(0, 100),
          lands="arena.margin_m"),
    Param("arena.floor_rgb", "rgb", "floor albedo R,G,B", lands="arena.floor_rgb"),
    Param("arena.texture", "str", "floor texture (competition: the e-Yantra arena image; "
          "image: arena.texture_file)",
          choices=("plain", "speckle", "concrete", comp.TEXTURE_NAME, IMAGE_TEXTURE),
          lands="arena.texture"),
    Param("arena.texture_seed", "int", "seed of the procedural floor texture",
          _b(0, 1_000_000), lands="arena.texture_seed"),
    Param("arena.texture_file", "file", "arena.texture=image: PNG or JPEG of the floor (a "
          "path relative to the preset file; kept by its SHA-256)", neutral="",
          lands="arena.texture_file"),
    Param("arena.texture_size_m", "size", "arena.texture=image: the image's width, height on "
          "the floor (m), centred on the arena, row 0 north", _b(0, 1000), neutral=(0.0, 0.0),
          lands="arena.texture_size_m"),
    Param("arena.border_width_m", "float", "border line width (m), 0 = none", _b(0, 1),
          lands="arena.border_width_m"),
    Param("arena.border_rgb", "rgb", "border line colour R,G,B", lands="arena.border_rgb"),
    Param("arena.grid_step_m", "float", "floor grid spacing (m), 0 = none", _b(0, 100),
          lands="arena.grid_step_m"),
    Param("arena.grid_rgb", "rgb", "floor grid colour R,G,B", lands="arena.grid_rgb"),
    Param("arena.logo_text", "str", "text distractor in the south margin ('' = none)",
          lands="arena.logo_text"),
    Param("arena.logo_rgb", "rgb", "text distractor colour R,G,B", lands="arena.logo_rgb"),
    Param("markers.dictionary", "str", "cv2.aruco dictionary name", lands="markers.dictionary"),
    Param("markers.ids", "ids", "marker ids NW,NE,SE,SW", lands="markers.ids"),
    Param("markers.side_m", "float", "marker side (m)", _b(0.01, 100), lands="markers.side_m"),
    Param("markers.rotation_deg", "float", "printed marker rotation (multiple of 90)",
          _b(-360, 360), lands="markers.rotation_deg"),
    Param("markers.quiet_zone_m", "float", "white quiet zone around markers (m)", _b(0, 10),
          lands="markers.quiet_zone_m"),
    Param("markers.printed", "bool", "markers printed on the arena.texture=image file (none "
          "drawn)", neutral=False, lands="markers.printed"),
    Param("obstacles.count", "int", "number of boxes", _b(0, 50), draw="scene"),
    Param("obstacles.length_m", "float", "box length (m), per box", _b(0.01, 100), draw="box"),
    Param("obstacles.width_m", "float", "box width (m), per box", _b(0.01, 100), draw="box"),
    Param("obstacles.height_m", "float", "box height (m), per box", _b(0.001, 100), draw="box"),
    Param("obstacles.yaw_deg", "float", "box yaw (deg), per box", _b(-360, 360), draw="box"),
    Param("obstacles.yaw_step_deg", "float", "round each box yaw to a multiple of this "
          "(90 = axis-aligned; 0 = any yaw)", _b(0, 180), neutral=0.0),
    Param("obstacles.gray", "int", "box albedo grey level, per box", _b(0, 255), draw="box"),
    Param("obstacles.palette", "str", "box colours: grey boxes, or warehouse pallets and "
          "coloured crates", choices=("gray", "warehouse")),
    Param("obstacles.min_gap_m", "float", "minimum gap between footprints (m)", _b(0, 100)),
    Param("obstacles.edge_margin_m", "float", "minimum distance to the frame edge (m)",
          _b(0, 100)),
    Param("obstacles.max_tries", "int", "placement tries per box before failing",
          _b(1, 100000)),
    Param("camera.width", "int", "image width (px)", _b(16, MAX_IMAGE_SIDE_PX),
          lands="camera.width"),
    Param("camera.height", "int", "image height (px)", _b(16, MAX_IMAGE_SIDE_PX),
          lands="camera.height"),
    Param("camera.fov_deg", "float", "vertical field of view (deg)", _b(1, 170),
          lands="camera.fov_deg", draw="scene", redraw=True),
    Param("camera.altitude_m", "float", "camera height above the floor (m)", _b(0.01, 10000),
          lands="camera.altitude_m", draw="scene", redraw=True),
    Param("camera.tilt_deg", "float", "optical axis angle from the nadir (deg)", _b(0, 79),
          lands="camera.tilt_deg", draw="scene", redraw=True),
    Param("camera.yaw_deg", "float", "camera heading, CCW from north-up (deg)", _b(-360, 360),
          lands="camera.yaw_deg", draw="scene", redraw=True),
    Param("camera.roll_deg", "float", "rotation about the optical axis (deg)", _b(-180, 180),
          lands="camera.roll_deg", draw="scene", redraw=True),
    Param("camera.target_x_m", "float", "where the optical axis meets the floor, x (m)",
          _b(-1000, 1000), lands="camera.target_m.0", draw="scene",
          redraw=True),
    Param("camera.target_y_m", "float", "where the optical axis meets the floor, y (m)",
          _b(-1000, 1000), lands="camera.target_m.1", draw="scene",
          redraw=True),
    Param("camera.markers_in_view", "bool", "redraw the camera until all markers are in view"),
    Param("camera.max_tries", "int", "camera draws before failing", _b(1, 100000)),
    Param("lighting.ambient", "float", "ambient light", _b(0, 2), lands="lighting.ambient",
          draw="scene"),
    Param("lighting.intensity", "float", "directional light intensity", _b(0, 2),
          lands="lighting.directional.0.intensity", draw="scene"),
    Param("lighting.elevation_deg", "float", "directional light elevation (deg)", _b(0, 90),
          draw="scene"),
    Param("lighting.azimuth_deg", "float", "directional light azimuth, CCW from east (deg)",
          _b(-360, 360), draw="scene"),
    Param("background.gray", "int", "grey level around the arena", _b(0, 255), draw="scene"),
    # Degradations and scene-side variations: every one neutral by default.
    Param("camera.k1", "float", "lens radial distortion k1 (0 = pinhole; < 0 barrel)",
          _b(-1, 1), neutral=0.0, lands="camera.dist.0", draw="scene"),
    Param("camera.k2", "float", "lens radial distortion k2", _b(-1, 1), neutral=0.0,
          lands="camera.dist.1", draw="scene"),
    Param("camera.p1", "float", "lens tangential distortion p1", _b(-0.1, 0.1), neutral=0.0,
          lands="camera.dist.2", draw="scene"),
    Param("camera.p2", "float", "lens tangential distortion p2", _b(-0.1, 0.1), neutral=0.0,
          lands="camera.dist.3", draw="scene"),
    Param("camera.k3", "float", "lens radial distortion k3", _b(-1, 1), neutral=0.0,
          lands="camera.dist.4", draw="scene"),
    Param("degrade.vignetting", "float", "corner darkening 0..1 (0 = none)", _b(0, 1),
          neutral=0.0, lands="degrade.vignetting", draw="scene"),
    Param("degrade.exposure_ev", "float", "exposure change in stops (0 = none)", _b(-6, 6),
          neutral=0.0, lands="degrade.exposure_ev", draw="scene"),
    Param("degrade.motion_blur_px", "float", "motion blur length in px (0 = none)", _b(0, 200),
          neutral=0.0, lands="degrade.motion_blur_px", draw="scene"),
    Param("degrade.motion_angle_deg", "float", "motion blur direction, CCW from +x (deg)",
          _b(-360, 360), neutral=0.0, lands="degrade.motion_angle_deg", draw="scene"),
    Param("degrade.defocus_px", "float", "defocus (disc) blur radius in px (0 = none)",
          _b(0, 100), neutral=0.0, lands="degrade.defocus_px", draw="scene"),
    Param("degrade.noise_sigma", "float", "Gaussian noise std in grey levels (0 = none)",
          _b(0, 128), neutral=0.0, lands="degrade.noise_sigma", draw="scene"),
    Param("degrade.poisson_photons", "float", "shot noise: photons at full scale "
          "(0 = none; fewer = noisier)", _b(0, 1e7), neutral=0.0,
          lands="degrade.poisson_photons", draw="scene"),
    Param("degrade.gamma", "float", "display gamma, out = in^(1/gamma) (1 = none)",
          _b(0.1, 10), neutral=1.0, lands="degrade.gamma", draw="scene"),
    Param("degrade.jpeg_quality", "int", "JPEG round trip at this quality (0 = none)",
          _b(0, 100), neutral=0, lands="degrade.jpeg_quality", draw="scene"),
    Param("lighting.shadow_strength", "float", "box shadows from the directional light, "
          "0..1 (0 = none)", _b(0, 1), neutral=0.0, lands="lighting.shadow_strength",
          draw="scene"),
    Param("lighting.spot_strength", "float", "uneven light: darkening away from a spot, "
          "0..1 (0 = even)", _b(0, 1), neutral=0.0, lands="lighting.spot_strength",
          draw="scene"),
    Param("lighting.spot_x_m", "float", "spot light centre x (m)", _b(-1000, 1000),
          neutral=0.0, lands="lighting.spot_xy_m.0", draw="scene"),
    Param("lighting.spot_y_m", "float", "spot light centre y (m)", _b(-1000, 1000),
          neutral=0.0, lands="lighting.spot_xy_m.1", draw="scene"),
    Param("lighting.spot_radius_m", "float", "spot light radius (m)", _b(0.01, 1000),
          neutral=3.0, lands="lighting.spot_radius_m", draw="scene"),
    # Fill lights: horizontal directional lights along x, on the boxes' east or west faces only
    # (the floor, the markers and the top, north and south faces have no x component in their
    # normals); how a twin states the shade of faces its example does not show.
    Param("lighting.east_fill", "float", "extra light on the boxes' east (+x) faces only "
          "(0 = none)", _b(0, 2), neutral=0.0),
    Param("lighting.west_fill", "float", "extra light on the boxes' west (-x) faces only "
          "(0 = none)", _b(0, 2), neutral=0.0),
    Param("distractors.tapes", "int", "tape lines on the floor (not obstacles)", _b(0, 50),
          neutral=0, draw="scene"),
    Param("distractors.papers", "int", "papers on the floor (not obstacles)", _b(0, 50),
          neutral=0, draw="scene"),
    Param("markers.occlusion", "float", "fraction of one marker hidden by a flat "
          "occluder (0 = none)", _b(0, 1), neutral=0.0, draw="scene"),
    Param("markers.occluded", "int", "which marker is occluded: 0 NW, 1 NE, 2 SE, 3 SW",
          _b(0, 3), neutral=0, draw="scene"),
    # How box edges are drawn (docs/rendering.md, "Edges"): neutral = the competition's.
    Param("render.edge_samples", "int", "coverage samples per pixel along box edges: 1 hard, "
          "2 the competition's, 4 standard 4x MSAA", _b(1, 4), choices=("1", "2", "4"),
          neutral=2, lands="render.edge_samples"),
    Param("render.edge_resolve", "str", "edge samples averaged in linear light (an sRGB "
          "framebuffer) or in sRGB values (a plain one)", choices=("linear", "srgb"),
          neutral="linear", lands="render.edge_resolve"),
    # How the image files are written (not part of the scene: the GT changes only in its
    # image path).
    Param("output.format", "str", "image files: png (lossless), or jpeg as cv2.imwrite "
          "writes it (the competition's example)", choices=("png", "jpeg"),
          neutral="png"),
    Param("output.jpeg_quality", "int", "JPEG quality of output.format=jpeg", _b(1, 100),
          neutral=95),
    Param("output.jpeg_subsampling", "str", "JPEG chroma subsampling of output.format=jpeg "
          "(420: cv2.imwrite's default)", choices=tuple(JPEG_SUBSAMPLINGS),
          neutral=DEFAULT_JPEG_SUBSAMPLING),
)

#: Every parameter by name (declaration order).
PARAMETERS: dict[str, Param] = {p.name: p for p in PARAMS}
if len(PARAMETERS) != len(PARAMS):  # pragma: no cover - a declaration error
    raise ValueError("generator.params: a parameter is declared twice")

#: Defaults: a preset or mapping that lacks one of these parameters gets this value, which
#: changes nothing (in the image, or in scenes drawn before the parameter was added).
DEFAULTS: dict[str, Value] = {p.name: p.neutral for p in PARAMS if p.neutral is not None}
#: Neutral values of the degradation and scene-variation parameters (those with a neutral
#: value that are drawn for every scene).
NEUTRAL: dict[str, Value] = {k: v for k, v in DEFAULTS.items() if PARAMETERS[k].draw == "scene"}


def lands_in(section: str) -> dict[str, str]:
    """``{field: parameter name}`` of the parameters landing in ``section`` (one level deep).

    E.g. ``lands_in("degrade")`` maps each
    :class:`~arenabench.generator.rendering.degrade.Degradations` field to its parameter.
    """
    return {p.lands.split(".", 1)[1]: p.name for p in PARAMS
            if p.lands.split(".")[0] == section}


def assemble(values: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Put parameter values where they land in the scene (:attr:`Param.lands`).

    Parameters
    ----------
    values : dict
        Fixed (drawn) values by parameter name; names missing here are left out.

    Returns
    -------
    dict
        ``{section: {field: value}}`` for the scene sections (arena, markers, camera,
        lighting); indexed paths build lists (``camera.target_m.0`` -> ``target_m[0]``).
    """
    out: dict[str, Any] = {s: {} for s in SECTIONS if s != "degrade"}
    for p in PARAMS:
        if not p.lands or p.name not in values or p.lands.startswith("degrade."):
            continue
        parts = p.lands.split(".")
        node: Any = out
        for part, nxt in itertools.pairwise(parts):
            key: Any = int(part) if part.isdigit() else part
            fresh: Any = [] if nxt.isdigit() else {}
            if isinstance(node, list):
                node.extend([None] * (key + 1 - len(node)))
                if node[key] is None:
                    node[key] = fresh
            else:
                node.setdefault(key, fresh)
            node = node[key]
        last = parts[-1]
        if isinstance(node, list):
            node.extend([None] * (int(last) + 1 - len(node)))
            node[int(last)] = values[p.name]
        else:
            node[last] = values[p.name]
    return out
