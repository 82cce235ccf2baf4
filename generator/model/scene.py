"""The scene description: plain, typed, JSON-serialisable data (no rendering state).

World frame: metres, floor plane z = 0, z up, north +y, east +x, arena centred at the origin.
A scene fully determines its image and its ground truth; the renderer and the ground-truth code
are adapters over it.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from arenabench.aruco import aruco_dictionary, symmetric_turn
from arenabench.frame import COMPETITION_DICTIONARY
from arenabench.generator.assets import competition_arena as comp
from arenabench.generator.assets.texture_store import IMAGE_TEXTURE, is_ref
from arenabench.generator.parameters.params import PARAMETERS
from arenabench.limits import (
    MAX_IMAGE_SIDE_PX,
    MAX_SCENE_FILE_BYTES,
    MAX_SCENE_NUMBER,
    MAX_SCENE_OBJECTS,
    check_at_most,
    shown,
    text_problem,
)

Rgb = tuple[int, int, int]


#: Floor textures: procedural ones, the competition's own arena image, and an image file.
FLOOR_TEXTURES = ("plain", "speckle", "concrete", comp.TEXTURE_NAME, IMAGE_TEXTURE)
#: Arena fields of an image texture: left out of :meth:`Scene.to_dict` for other textures
#: (where they are empty), so those scenes' files are as they were before these fields.
IMAGE_TEXTURE_FIELDS = ("texture_file", "texture_size_m")


def _rgb(value: Any, name: str) -> Rgb:
    try:
        r, g, b = (round(float(c)) for c in value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be three numbers 0..255, got {value!r}") from exc
    if not all(0 <= c <= 255 for c in (r, g, b)):
        raise ValueError(f"{name} must be three numbers 0..255, got {value!r}")
    return (r, g, b)


def _within_bounds(value: float, name: str) -> None:
    """Refuse a value outside the bounds the parameter registry declares for ``name``."""
    bounds = PARAMETERS[name].bounds
    if not bounds.lo <= float(value) <= bounds.hi:
        raise ValueError(f"{name} must be in [{bounds.lo:g}, {bounds.hi:g}], got {value!r}")


#: A field's declared type -> what its value must be: "number", "int", "bool", "str", or a
#: tuple of those (that many items); a leading "?" lets it be ``None``; ("number", ...) any
#: number of items. Types not here (colours, nested specs) are checked by their own code.
_FIELD_SHAPES: dict[str, Any] = {
    "float": "number", "int": "int", "bool": "bool", "str": "str",
    "tuple[float, float]": ("number",) * 2, "tuple[float, float, float]": ("number",) * 3,
    "tuple[float, float, float, float, float]": ("number",) * 5,
    "tuple[int, int, int, int]": ("int",) * 4,
    "tuple[float, float, float] | None": ("?", ("number",) * 3),
    "tuple[tuple[float, float, float], ...] | None": ("?", (("number",) * 3, ...)),
}


def _shape_problem(value: Any, shape: Any) -> str | None:
    """Why ``value`` is not of ``shape`` (:data:`_FIELD_SHAPES`), or ``None``."""
    if isinstance(shape, tuple) and shape and shape[0] == "?":
        return None if value is None else _shape_problem(value, shape[1])
    if shape == "number":
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        return None if ok else "a number"
    if shape == "int":
        ok = (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer())
        return None if ok else "an integer"
    if shape == "bool":
        return None if isinstance(value, bool) else "true or false"
    if shape == "str":
        return None if isinstance(value, str) else "text"
    if not isinstance(value, (list, tuple)):
        return "a list"
    if len(shape) == 2 and shape[1] is ...:
        return next((p for v in value if (p := _shape_problem(v, shape[0]))), None)
    if len(value) != len(shape):
        return f"{len(shape)} items"
    return next((p for v, s in zip(value, shape, strict=True)
                 if (p := _shape_problem(v, s))), None)


def _finite_fields(spec: Any, section: str) -> None:
    """Refuse a value of the wrong kind (text where a number belongs, ``true`` for a length, a
    list of one for a point: :data:`_FIELD_SHAPES`), a non-finite number (``inf``, ``nan``;
    JSON's ``1e309`` reads as ``inf``) or one beyond
    :data:`~arenabench.limits.MAX_SCENE_NUMBER` in any field of ``spec``, nested tuples
    included, naming it ``section.field``."""
    def check(value: Any, name: str) -> None:
        if (isinstance(value, (int, float)) and not isinstance(value, bool)
                and not abs(value) <= MAX_SCENE_NUMBER):  # also NaN
            raise ValueError(f"{name} must be a finite number in "
                             f"[-{MAX_SCENE_NUMBER:.0f}, {MAX_SCENE_NUMBER:.0f}], "
                             f"got {value!r}")
        if isinstance(value, (tuple, list)):
            for item in value:
                check(item, name)

    for f in fields(spec):
        value = getattr(spec, f.name)
        shape = _FIELD_SHAPES.get(str(f.type))
        if shape is not None and (problem := _shape_problem(value, shape)):
            raise ValueError(f"{section}.{f.name} must be {problem}, got {shown(value)}")
        check(value, f"{section}.{f.name}")


def _positive(value: float, name: str) -> float:
    value = float(value)
    if not value > 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return value


@dataclass(frozen=True)
class ArenaSpec:
    """The arena floor.

    Parameters
    ----------
    side_m : float
        Side of the border-line square; the markers' outer corners sit at its corners.
    margin_m : float
        Width of floor beyond the border line on every side.
    floor_rgb : tuple of int
        Floor albedo (0..255).
    texture : {"plain", "speckle", "concrete", "competition", "image"}
        Plain colour, a faint procedural speckle, or warehouse concrete (mottling, stains and
        painted lane lines in the margin), seeded by ``texture_seed``; or the competition's
        own arena image (border line, markers 80/85/90/95 and logo printed on it, tinted by
        ``floor_rgb``), which fixes ``side_m`` and ``margin_m`` to its geometry
        (:mod:`arenabench.generator.assets.competition_arena`); or an image file (``texture_file``,
        tinted by ``floor_rgb``) covering ``texture_size_m``, which is then the floor: drawn
        as it is (no border line, grid or logo over it), sampled as the competition's
        texture is; its markers printed on it (``MarkerSpec.printed``) or drawn over it.
    texture_seed : int
        Seed of the procedural texture.
    border_width_m : float
        Width of the border line (0 = none).
    border_rgb : tuple of int
        Colour of the border line.
    grid_step_m : float
        Spacing of an optional floor grid (0 = none).
    grid_rgb : tuple of int
        Colour of the grid lines.
    logo_text : str
        Text distractor drawn centred just outside the south border ("" = none).
    logo_rgb : tuple of int
        Colour of the text distractor.
    texture_file : str
        ``texture="image"``: the image's reference, ``textures/<sha256>.png`` (or ``.jpg``),
        found in the texture cache (:mod:`arenabench.generator.assets.texture_store`).
    texture_size_m : tuple of float
        ``texture="image"``: width and height (m) the image covers, centred on the arena, its
        first row north.
    """

    side_m: float = 8.0
    margin_m: float = 0.45
    floor_rgb: Rgb = (253, 253, 253)
    texture: str = "plain"
    texture_seed: int = 0
    border_width_m: float = 0.015
    border_rgb: Rgb = (20, 20, 20)
    grid_step_m: float = 0.0
    grid_rgb: Rgb = (200, 200, 200)
    logo_text: str = ""
    logo_rgb: Rgb = (220, 50, 50)
    texture_file: str = ""
    texture_size_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        _finite_fields(self, "arena")
        self._check_image_texture()
        _positive(self.side_m, "arena.side_m")
        if self.margin_m < 0:
            raise ValueError(f"arena.margin_m must be >= 0, got {self.margin_m!r}")
        if self.texture not in FLOOR_TEXTURES:
            raise ValueError(
                f"arena.texture must be one of {', '.join(FLOOR_TEXTURES)}, got {self.texture!r}"
            )
        if self.texture == comp.TEXTURE_NAME and (
            abs(self.side_m - comp.ARENA_SIDE_M) > 1e-9
            or abs(self.margin_m - comp.ARENA_MARGIN_M) > 1e-9
        ):
            raise ValueError(
                f"arena.texture={comp.TEXTURE_NAME} needs arena.side_m={comp.ARENA_SIDE_M:g} and "
                f"arena.margin_m={comp.ARENA_MARGIN_M:g} (the texture's geometry), got "
                f"{self.side_m:g} and {self.margin_m:g}"
            )
        if self.border_width_m < 0:
            raise ValueError(f"arena.border_width_m must be >= 0, got {self.border_width_m!r}")
        if self.grid_step_m < 0:
            raise ValueError(f"arena.grid_step_m must be >= 0, got {self.grid_step_m!r}")
        if not isinstance(self.logo_text, str):
            raise ValueError(f"arena.logo_text must be text, got {shown(self.logo_text)}")
        if (problem := text_problem(self.logo_text)) is not None:
            raise ValueError(f"arena.logo_text {shown(self.logo_text)}: {problem}")
        for name in ("floor_rgb", "border_rgb", "grid_rgb", "logo_rgb"):
            object.__setattr__(self, name, _rgb(getattr(self, name), f"arena.{name}"))

    def _check_image_texture(self) -> None:
        """``texture="image"`` needs a texture reference and a size, and draws nothing over
        the image; other textures leave both fields empty."""
        try:
            size = tuple(float(s) for s in self.texture_size_m)
        except (TypeError, ValueError):
            size = ()
        if len(size) != 2:
            raise ValueError(f"arena.texture_size_m must be a width and a height (m), got "
                             f"{self.texture_size_m!r}")
        object.__setattr__(self, "texture_size_m", size)
        if self.texture != IMAGE_TEXTURE:
            if self.texture_file or any(size):
                raise ValueError(f"arena.texture_file and arena.texture_size_m need "
                                 f"arena.texture={IMAGE_TEXTURE}, got arena.texture="
                                 f"{self.texture}")
            return
        if not is_ref(self.texture_file):
            raise ValueError(f"arena.texture={IMAGE_TEXTURE} needs arena.texture_file (a PNG "
                             f"or JPEG file), got {self.texture_file!r}")
        if not all(s > 0 for s in size):
            raise ValueError(f"arena.texture={IMAGE_TEXTURE} needs arena.texture_size_m, its "
                             f"width and height on the floor (m) > 0, got {self.texture_size_m!r}")
        drawn = {name: value for name, value in (
            ("arena.border_width_m", self.border_width_m),
            ("arena.grid_step_m", self.grid_step_m),
            ("arena.logo_text", self.logo_text)) if value}
        if drawn:
            fix = ", ".join(f"{k}={'' if isinstance(v, str) else 0}" for k, v in drawn.items())
            got = ", ".join(f"{k}={v!r}" for k, v in drawn.items())
            raise ValueError(f"arena.texture={IMAGE_TEXTURE} draws the image as it is: set "
                             f"{fix} (got {got})")


@dataclass(frozen=True)
class MarkerSpec:
    """The four corner markers.

    Parameters
    ----------
    dictionary : str
        cv2.aruco predefined dictionary name, e.g. ``"DICT_4X4_100"``.
    ids : tuple of int
        Marker ids at the north-west, north-east, south-east and south-west corners.
    side_m : float
        Marker side (black border included, quiet zone excluded).
    rotation_deg : float
        Rotation of every printed marker counter-clockwise seen from above, relative to
        upright (the generated image's top towards north). 180 is the competition arena.
    quiet_zone_m : float
        Width of the white quiet zone drawn around each marker.
    printed : bool
        The markers are printed on an image arena (``arena.texture="image"``): none are
        drawn. Otherwise they are drawn as marker sheets over the floor (on the competition's
        texture: unless they are the ones printed on it). A scene file states it only when
        true.
    """

    dictionary: str = COMPETITION_DICTIONARY
    ids: tuple[int, int, int, int] = (80, 85, 90, 95)
    side_m: float = 0.48
    rotation_deg: float = 180.0
    quiet_zone_m: float = 0.04
    printed: bool = False

    def __post_init__(self) -> None:
        _finite_fields(self, "markers")
        if not isinstance(self.printed, bool):
            raise ValueError(f"markers.printed must be true or false, got {self.printed!r}")
        ids = tuple(int(i) for i in self.ids)
        if len(ids) != 4:
            raise ValueError(f"markers.ids must be 4 ids (nw, ne, se, sw), got {self.ids!r}")
        if len(set(ids)) != 4:
            raise ValueError(f"markers.ids must be 4 different ids (a pipeline tells the "
                             f"corners apart by them), got {self.ids!r}")
        object.__setattr__(self, "ids", ids)
        if not isinstance(self.dictionary, str):
            raise ValueError(f"markers.dictionary must be a name, got {self.dictionary!r}")
        size = aruco_dictionary(self.dictionary, field="markers.dictionary").bytesList.shape[0]
        for marker_id in ids:
            if not 0 <= marker_id < size:
                raise ValueError(f"markers.ids: id {marker_id} is not in {self.dictionary} "
                                 f"(ids 0..{size - 1})")
            if (turn := symmetric_turn(self.dictionary, marker_id)) is not None:
                raise ValueError(f"markers.ids: id {marker_id} of {self.dictionary} looks the "
                                 f"same turned {turn} deg, so no detector can tell its first "
                                 f"corner (choose another id)")
        _positive(self.side_m, "markers.side_m")
        if self.quiet_zone_m < 0:
            raise ValueError(f"markers.quiet_zone_m must be >= 0, got {self.quiet_zone_m!r}")
        if float(self.rotation_deg) % 90 != 0:
            raise ValueError(
                f"markers.rotation_deg must be a multiple of 90, got {self.rotation_deg!r}"
            )


@dataclass(frozen=True)
class Obstacle:
    """A box obstacle standing on the floor.

    Parameters
    ----------
    center_m : tuple of float
        Footprint centre (x, y) in metres.
    yaw_deg : float
        Rotation about z, counter-clockwise seen from above; the length runs along x at 0.
    length_m, width_m, height_m : float
        Box dimensions.
    color_rgb : tuple of int
        Albedo (0..255); faces are shaded from the scene's lights.
    """

    center_m: tuple[float, float]
    yaw_deg: float
    length_m: float
    width_m: float
    height_m: float
    color_rgb: Rgb = (124, 124, 124)

    def __post_init__(self) -> None:
        _finite_fields(self, "obstacle")
        object.__setattr__(self, "center_m", tuple(float(c) for c in self.center_m))
        for name in ("length_m", "width_m", "height_m"):
            _positive(getattr(self, name), f"obstacle.{name}")
        object.__setattr__(self, "color_rgb", _rgb(self.color_rgb, "obstacle.color_rgb"))


@dataclass(frozen=True)
class CameraSpec:
    """Pinhole camera: image size, intrinsics and pose.

    Intrinsics: ``K`` (3x3, OpenCV convention, pixel centres at integer coordinates) when
    given, else a vertical field of view ``fov_deg`` with the principal point at the image
    centre. Pose: ``eye_m`` + ``look_at_m`` when both are given (image up towards north,
    then ``roll_deg``), else the orbit form: the optical axis hits the floor at ``target_m``,
    the camera is ``altitude_m`` above the floor, tilted ``tilt_deg`` from the nadir, with
    heading ``yaw_deg`` (counter-clockwise seen from above; at 0 the image's top points north
    and the camera tilts towards north) and ``roll_deg`` about the optical axis.
    Lens distortion: ``dist`` = OpenCV's (k1, k2, p1, p2, k3), all zero for a pinhole image.
    """

    width: int = 1000
    height: int = 1000
    fov_deg: float = 60.0
    K: tuple[tuple[float, float, float], ...] | None = None
    altitude_m: float = 8.7
    tilt_deg: float = 0.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0
    target_m: tuple[float, float] = (0.0, 0.0)
    eye_m: tuple[float, float, float] | None = None
    look_at_m: tuple[float, float, float] | None = None
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        _finite_fields(self, "camera")
        dist = tuple(float(c) for c in self.dist)
        if len(dist) != 5:
            raise ValueError(f"camera.dist must be (k1, k2, p1, p2, k3), got {self.dist!r}")
        object.__setattr__(self, "dist", dist)
        for name in ("width", "height"):
            value = getattr(self, name)
            if int(value) != value or not 16 <= value <= MAX_IMAGE_SIDE_PX:
                raise ValueError(
                    f"camera.{name} must be an integer in [16, {MAX_IMAGE_SIDE_PX}] "
                    f"(the largest image side arenabench renders), got {value!r}"
                )
            object.__setattr__(self, name, int(value))
        _within_bounds(self.fov_deg, "camera.fov_deg")
        _positive(self.altitude_m, "camera.altitude_m")
        _within_bounds(self.tilt_deg, "camera.tilt_deg")
        object.__setattr__(self, "target_m", tuple(float(c) for c in self.target_m))
        if self.K is not None:
            k = tuple(tuple(float(v) for v in row) for row in self.K)
            if len(k) != 3 or any(len(row) != 3 for row in k):
                raise ValueError(f"camera.K must be 3x3, got {self.K!r}")
            object.__setattr__(self, "K", k)
        if (self.eye_m is None) != (self.look_at_m is None):
            raise ValueError("camera.eye_m and camera.look_at_m must be given together")
        if self.eye_m is not None:
            object.__setattr__(self, "eye_m", tuple(float(c) for c in self.eye_m))
            object.__setattr__(self, "look_at_m", tuple(float(c) for c in self.look_at_m))


#: The two ways of stating a camera's intrinsics: (the default form's fields, the explicit
#: form's fields). A scene file holds one form only; the explicit one (``K``) wins when given.
CAMERA_INTRINSIC_FIELDS: tuple[tuple[str, ...], tuple[str, ...]] = (("fov_deg",), ("K",))
#: The same for the pose: (orbit form, look-at form).
CAMERA_POSE_FIELDS: tuple[tuple[str, ...], tuple[str, ...]] = (
    ("altitude_m", "tilt_deg", "yaw_deg", "target_m"), ("eye_m", "look_at_m"))


@dataclass(frozen=True)
class DirectionalLight:
    """A directional light: ``direction`` is where the light travels (towards the scene)."""

    direction: tuple[float, float, float] = (0.3, -0.4, -1.0)
    intensity: float = 0.3

    def __post_init__(self) -> None:
        _finite_fields(self, "light")
        d = tuple(float(c) for c in self.direction)
        if len(d) != 3 or not any(d):
            raise ValueError(f"light.direction must be a non-zero 3-vector, got {self.direction!r}")
        object.__setattr__(self, "direction", d)
        if self.intensity < 0:
            raise ValueError(f"light.intensity must be >= 0, got {self.intensity!r}")


@dataclass(frozen=True)
class LightingSpec:
    """Ambient term plus up to four directional lights (Lambertian, baked into colours).

    ``shadow_strength`` (0..1) darkens the floor where the first directional light is blocked
    by a box (1 = only the ambient term is left there; 0 = no shadows). A spot light makes the
    floor uneven: brightness gain ``1 - spot_strength * (1 - exp(-d^2 / (2 spot_radius_m^2)))``
    at distance ``d`` from ``spot_xy_m`` (0 = even light).
    """

    ambient: float = 0.7
    directional: tuple[DirectionalLight, ...] = field(
        default_factory=lambda: (DirectionalLight(),)
    )
    shadow_strength: float = 0.0
    spot_strength: float = 0.0
    spot_xy_m: tuple[float, float] = (0.0, 0.0)
    spot_radius_m: float = 3.0

    def __post_init__(self) -> None:
        _finite_fields(self, "lighting")
        if self.ambient < 0:
            raise ValueError(f"lighting.ambient must be >= 0, got {self.ambient!r}")
        for name in ("shadow_strength", "spot_strength"):
            if not 0.0 <= float(getattr(self, name)) <= 1.0:
                raise ValueError(f"lighting.{name} must be in [0, 1], got "
                                 f"{getattr(self, name)!r}")
        _positive(self.spot_radius_m, "lighting.spot_radius_m")
        object.__setattr__(self, "spot_xy_m", tuple(float(c) for c in self.spot_xy_m))
        lights = tuple(
            d if isinstance(d, DirectionalLight) else DirectionalLight(**d)
            for d in self.directional
        )
        if len(lights) > 4:
            raise ValueError(f"lighting.directional: at most 4 lights, got {len(lights)}")
        object.__setattr__(self, "directional", lights)


def _choice(value: Any, name: str, *, kind: type) -> None:
    """Refuse a ``value`` that is not one of the choices (of type ``kind``) the parameter
    registry declares for ``name``."""
    choices = PARAMETERS[name].choices
    if isinstance(value, bool) or not isinstance(value, kind) or str(value) not in choices:
        raise ValueError(f"{name} must be one of {', '.join(choices)}, got {value!r}")


@dataclass(frozen=True)
class RenderSpec:
    """How the renderer draws the obstacles' edges (docs/rendering.md, "Edges").

    Parameters
    ----------
    edge_samples : {1, 2, 4}
        Coverage samples per pixel along the obstacles' edges: 1 = hard edges, 2 = the
        competition renderer's two-sample pattern, 4 = the standard 4x MSAA pattern
        (:data:`arenabench.generator.rendering.edges.EDGE_PATTERNS`).
    edge_resolve : {"linear", "srgb"}
        Where the samples of an edge pixel are averaged: in linear light (an sRGB framebuffer,
        as the competition's) or in sRGB values (a plain framebuffer).

    A scene file states this section only when it differs from the defaults (the neutral
    values of ``render.edge_samples`` and ``render.edge_resolve``), so scene files and GT
    written before it existed read and render the same.
    """

    edge_samples: int = PARAMETERS["render.edge_samples"].neutral
    edge_resolve: str = PARAMETERS["render.edge_resolve"].neutral

    def __post_init__(self) -> None:
        _choice(self.edge_samples, "render.edge_samples", kind=int)
        _choice(self.edge_resolve, "render.edge_resolve", kind=str)


@dataclass(frozen=True)
class FloorPatch:
    """A flat rectangle lying on the floor: not an obstacle (never counted, no area).

    Parameters
    ----------
    kind : {"tape", "paper", "occluder"}
        Tape lines and papers lie on the floor under the markers; an occluder lies over them
        (it hides part of a marker).
    center_m : tuple of float
        Centre (x, y) in metres.
    yaw_deg : float
        Rotation about z, counter-clockwise from above; the length runs along x at 0.
    length_m, width_m : float
        Size.
    color_rgb : tuple of int
        Colour (unlit albedo; the floor's lighting applies).
    """

    kind: str
    center_m: tuple[float, float]
    yaw_deg: float
    length_m: float
    width_m: float
    color_rgb: Rgb = (40, 40, 40)

    def __post_init__(self) -> None:
        _finite_fields(self, "patch")
        if self.kind not in ("tape", "paper", "occluder"):
            raise ValueError(f"patch.kind must be tape, paper or occluder, got {self.kind!r}")
        object.__setattr__(self, "center_m", tuple(float(c) for c in self.center_m))
        for name in ("length_m", "width_m"):
            _positive(getattr(self, name), f"patch.{name}")
        object.__setattr__(self, "color_rgb", _rgb(self.color_rgb, "patch.color_rgb"))


def _check_sizes(obstacles: Any, patches: Any) -> None:
    """At most :data:`~arenabench.limits.MAX_SCENE_OBJECTS` obstacles and patches."""
    check_at_most(len(obstacles), MAX_SCENE_OBJECTS, "number of obstacles")
    check_at_most(len(patches), MAX_SCENE_OBJECTS, "number of patches")


@dataclass(frozen=True)
class Scene:
    """Everything needed to render one image and compute its ground truth.

    ``patches`` are flat distractors (tape, paper) and marker occluders: drawn, never counted.
    ``render`` says how the obstacles' edges are drawn (:class:`RenderSpec`).
    """

    arena: ArenaSpec
    markers: MarkerSpec
    obstacles: tuple[Obstacle, ...]
    camera: CameraSpec
    lighting: LightingSpec = field(default_factory=LightingSpec)
    background_rgb: Rgb = (225, 225, 225)
    patches: tuple[FloorPatch, ...] = ()
    render: RenderSpec = field(default_factory=RenderSpec)

    def __post_init__(self) -> None:
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        _check_sizes(self.obstacles, self.patches)
        object.__setattr__(self, "patches", tuple(
            p if isinstance(p, FloorPatch) else FloorPatch(**_tuplify(p)) for p in self.patches
        ))
        object.__setattr__(self, "background_rgb", _rgb(self.background_rgb, "background_rgb"))
        if not isinstance(self.render, RenderSpec):
            raise ValueError(f"render must be a RenderSpec, got {self.render!r}")
        mk = self.markers
        if (self.arena.texture == comp.TEXTURE_NAME
                and not comp.markers_are_printed(mk.dictionary, mk.ids, mk.side_m,
                                                 mk.rotation_deg)
                and mk.side_m + mk.quiet_zone_m < comp.MARKER_SIDE_M - 1e-9):
            raise ValueError(
                f"markers.side_m + markers.quiet_zone_m must be >= {comp.MARKER_SIDE_M:g} on "
                f"arena.texture={comp.TEXTURE_NAME} (drawn markers must hide the printed ones), "
                f"got {mk.side_m:g} + {mk.quiet_zone_m:g}"
            )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready nested dict (tuples become lists).

        The camera is written one way only: ``K`` or ``fov_deg`` for the intrinsics, the
        look-at pose (``eye_m``, ``look_at_m``) or the orbit pose (``altitude_m``,
        ``tilt_deg``, ``yaw_deg``, ``target_m``), never both. ``render`` is written only when
        it is not the default (:class:`RenderSpec`), :data:`IMAGE_TEXTURE_FIELDS` only with an
        image texture, ``markers.printed`` only when true.
        """
        out = _listify(asdict(self))
        if self.render == RenderSpec():
            del out["render"]
        if out["arena"]["texture"] != IMAGE_TEXTURE:
            for name in IMAGE_TEXTURE_FIELDS:
                del out["arena"][name]
        if not out["markers"]["printed"]:
            del out["markers"]["printed"]
        camera = out["camera"]
        for name in CAMERA_INTRINSIC_FIELDS[camera["K"] is None]:
            del camera[name]
        for name in CAMERA_POSE_FIELDS[camera["eye_m"] is None]:
            del camera[name]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Scene:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        ValueError
            On a missing section or an invalid value.
        """
        try:
            cam = dict(data["camera"])
            for fields in (CAMERA_INTRINSIC_FIELDS, CAMERA_POSE_FIELDS):
                given = [n for n in fields[1] if cam.get(n) is not None]
                other = [n for n in fields[0] if n in cam]
                if given and other:
                    raise ValueError(
                        f"invalid scene description: camera gives both {', '.join(given)} and "
                        f"{', '.join(other)}; state it one way"
                    )
            if cam.get("K") is not None:
                cam["K"] = tuple(tuple(r) for r in cam["K"])
            _check_sizes(data["obstacles"], data.get("patches", ()))  # before building them
            lighting = _tuplify(dict(data.get("lighting", {})))
            if "directional" in lighting:
                lighting["directional"] = tuple(
                    DirectionalLight(**d) for d in lighting["directional"]
                )
            return cls(
                arena=ArenaSpec(**_tuplify(data["arena"])),
                markers=MarkerSpec(**_tuplify(data["markers"])),
                obstacles=tuple(Obstacle(**_tuplify(o)) for o in data["obstacles"]),
                camera=CameraSpec(**_tuplify(cam)),
                lighting=LightingSpec(**lighting),
                background_rgb=tuple(data.get("background_rgb", (225, 225, 225))),
                patches=tuple(FloorPatch(**_tuplify(p)) for p in data.get("patches", ())),
                render=RenderSpec(**data.get("render", {})),
            )
        except (KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"invalid scene description: {exc}") from exc


def _listify(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _listify(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_listify(v) for v in obj]
    return obj


def _tuplify(d: dict[str, Any]) -> dict[str, Any]:
    return {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}


#: Top-level keys of a scene file.
SCENE_KEYS = frozenset(
    {"arena", "markers", "obstacles", "camera", "lighting", "background_rgb", "patches",
     "render"}
)


def _texture_of_file(data: dict[str, Any], folder: Path) -> None:
    """A scene file's ``arena.texture_file`` as a texture reference: a path relative to the
    file's folder, or a reference whose copy lies there or in the texture cache
    (:mod:`arenabench.generator.assets.texture_store`)."""
    from arenabench.generator.assets import texture_store

    arena = data.get("arena")
    value = arena.get("texture_file") if isinstance(arena, dict) else None
    if not isinstance(value, str) or not value:
        return
    if texture_store.is_ref(value):
        ref = texture_store.import_ref(value, folder, where=str(folder / value))
    else:
        path = Path(value).expanduser()
        ref = texture_store.import_texture(path if path.is_absolute() else folder / path)
    data["arena"] = {**arena, "texture_file": ref}


def load_scene(path: str | Path) -> Scene:
    """Read a scene file (JSON of :meth:`Scene.to_dict`; an image texture's
    ``arena.texture_file`` is a path relative to the file, or a texture reference).

    Raises
    ------
    ValueError
        On a missing or unreadable file, invalid JSON, an unknown field or an invalid value.
    """
    p = Path(path)
    if p.exists() and not p.is_file():
        raise ValueError(f"scene file {str(p)!r} is not a regular file")
    try:
        size = p.stat().st_size
        if size > MAX_SCENE_FILE_BYTES:
            raise ValueError(f"scene file {str(p)!r} is {size} bytes: a scene file holds at "
                             f"most {MAX_SCENE_FILE_BYTES} (limits.MAX_SCENE_FILE_BYTES)")
        data = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"cannot read scene file {str(p)!r}: {exc.strerror or exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"scene file {str(p)!r} is not valid JSON: {exc}") from None
    except RecursionError:
        raise ValueError(f"scene file {str(p)!r} is nested too deeply to be a scene") from None
    if not isinstance(data, dict):
        raise ValueError(f"scene file {str(p)!r} must hold a JSON object")
    unknown = sorted(set(data) - SCENE_KEYS)
    if unknown:
        raise ValueError(f"scene file {str(p)!r}: unknown field(s) {', '.join(unknown)}")
    try:
        _texture_of_file(data, p.parent)
        return Scene.from_dict(data)
    except ValueError as exc:
        raise ValueError(f"scene file {str(p)!r}: {exc}") from None
