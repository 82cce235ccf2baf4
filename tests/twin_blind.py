"""Blind round trips of ``arenabench twin``: "real" images rendered by the generator with
hidden, randomly drawn parameters, and the comparison of a twin built from the image alone
with what was hidden.

:func:`hidden_case` draws a case (a scene and how its file is written) from a seed;
:func:`write_case` renders it and writes the image file (the only thing the twin is given);
:func:`compare` sets the twin (its folder, as ``arenabench twin`` writes it) against the hidden
case, with the tolerances of :data:`TOLERANCES`; :func:`round_trip` does all three, running
``arenabench twin`` as a user would, on the image file alone; :func:`reference_pass_rate`
scores the reference pipeline on scenes of the twin's preset. ``tools/twin_round_trips.py`` runs the
full set and prints the figures; ``tests/generator/fitting/test_twin_blind.py`` a few cases.

A picture floor's markers are, in about half the cases (:data:`PRINTED_SHARE`), printed on
the picture as an arena's author prints them (:func:`_print_markers`: sRGB means, not the
twin's painter), on a texture side the twin is not told; then the twin has to find the texel
grid they were printed on, and :func:`compare` checks it.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from arenabench.generator.assets.texture_store import import_texture
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import floor_extent
from arenabench.generator.model.scene import (
    IMAGE_TEXTURE,
    ArenaSpec,
    CameraSpec,
    DirectionalLight,
    LightingSpec,
    MarkerSpec,
    Obstacle,
    RenderSpec,
    Scene,
)
from arenabench.generator.model.shading import floor_factor, shade_factors
from arenabench.generator.parameters.preset_files import load_preset_file

#: Dictionaries drawn from (families of every size, AprilTag and the original ArUco).
DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_250", "DICT_5X5_100", "DICT_5X5_1000", "DICT_6X6_250",
                "DICT_7X7_50", "DICT_APRILTAG_36h11", "DICT_ARUCO_ORIGINAL")
#: Tolerances of the pinned parameters, and why (tools/twin_round_trips.py prints them).
TOLERANCES: dict[str, tuple[float, str]] = {
    "camera_px": (0.25, "RMS image distance (px) of floor points inside the arena, hidden "
                        "camera against the twin's (scaled to the hidden arena): a quarter "
                        "pixel moves a marker's or a box's outline by less than a pixel's "
                        "blend"),
    "fov_deg": (0.5, "pinned: within 0.5 deg; open (a near-nadir view trades the field of view "
                     "against the altitude): the hidden value inside the range kept, give or "
                     "take 0.5 deg"),
    "angle_deg": (0.1, "tilt, heading and roll, where the field of view is pinned (else they "
                       "follow it along the span that fits as well, and camera_px is the "
                       "check): 0.1 deg turns a 1000 px image by at most 0.9 px at its "
                       "corners"),
    "grey": (2.0, "floor, background, box top and the shades of the faces seen: JPEG rounding "
                  "and the modes of 8-bit images"),
    "marker_squares": (1.5, "the bound asked for: mean absolute grey difference of the fitted "
                            "scene's render in the squares 8 px around each marker"),
    "pass_rate": (0.95, "the reference pipeline on 100 scenes of the twin's preset"),
    "texel": (0.25, "markers printed on an image: the twin's texel grid against the hidden "
                    "one across a marker (texels, both grids with the markers' outer corners "
                    "on a texel boundary): the relative error of the texel's width over the "
                    "arena's side times the marker's side in hidden texels; a quarter texel "
                    "is the step of the twin's painter (4 samples a texel), and the texture's "
                    "own side is not pinned, only the texel (the floor beyond the markers may "
                    "lie outside the image)"),
}


@dataclass(frozen=True)
class HiddenCase:
    """A hidden scene and how its image file is written.

    Attributes
    ----------
    seed : int
        What it was drawn from.
    scene : Scene
        The scene (its texture file, for an image arena, in ``texture``).
    file_format : str
        ``"png"`` or ``"jpeg"``.
    jpeg_quality : int
        JPEG quality (``jpeg`` only).
    jpeg_subsampling : str
        ``"420"``, ``"422"`` or ``"444"``.
    texture : numpy.ndarray or None
        The image arena's texture (RGB), written beside the image when used.
    """

    seed: int
    scene: Scene
    file_format: str
    jpeg_quality: int = 95
    jpeg_subsampling: str = "420"
    texture: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def image_name(self) -> str:
        """The image file's name."""
        return f"hidden-{self.seed}.{'jpg' if self.file_format == 'jpeg' else 'png'}"


def _ids(rng: np.random.Generator, dictionary: str) -> tuple[int, ...]:
    from arenabench.aruco import aruco_dictionary, symmetric_turn

    size = aruco_dictionary(dictionary).bytesList.shape[0]
    ids: list[int] = []
    while len(ids) < 4:
        i = int(rng.integers(0, size))
        if i not in ids and symmetric_turn(dictionary, i) is None:
            ids.append(i)
    return tuple(ids)


def _floor_image(rng: np.random.Generator, texels: int = 1024) -> np.ndarray:
    """A floor picture for an image arena: mottled concrete-like grey with a few lines."""
    base = rng.normal(0, 1, (texels // 32, texels // 32)).astype(np.float32)
    img = 238 + 6 * cv2.resize(base, (texels, texels), interpolation=cv2.INTER_CUBIC)
    img += rng.normal(0, 1.5, (texels, texels)).astype(np.float32)
    out = np.clip(img, 0, 255).astype(np.uint8)
    out = np.repeat(out[:, :, None], 3, axis=2)
    for _ in range(int(rng.integers(1, 4))):
        y = int(rng.integers(0, texels))
        cv2.line(out, (0, y), (texels - 1, y), (150, 150, 150), int(rng.integers(2, 6)))
    return out


#: An image arena's markers are printed on its texture in this share of the cases that have one
#: (drawn apart from the other draws, so the other cases stay as they were).
PRINTED_SHARE = 0.5
#: The sides of a texture markers are printed on (texels; the twin's search covers
#: 2,048-4,096, :data:`arenabench.generator.fitting.rectify.GRID_SIDES`).
PRINTED_SIDES = (2100, 4000)
#: Samples a texel (a side) of the printer; its blends are sRGB means, as an image editor or an
#: SVG rasteriser makes them (the competition's texture: 230 where a marker's edge covers a
#: fifth of a texel), not the twin's painter's linear-light ones.
PRINTER_SAMPLES = 8


def _print_markers(texture: np.ndarray, arena: ArenaSpec, markers: MarkerSpec) -> np.ndarray:
    """``texture`` (RGB, covering ``arena``'s floor square) with the four markers printed on it
    by an arena's author: each marker's module image (``cv2.aruco.generateImageMarker``, one
    pixel a module) placed at its corners (:func:`~arenabench.generator.model.layout.
    marker_corners_world`, the generator's convention), every texel the sRGB mean of
    :data:`PRINTER_SAMPLES` squared samples."""
    from arenabench.frame import CORNER_ORDER
    from arenabench.generator.model.layout import marker_corners_world

    out = texture.copy()
    n = out.shape[0]
    e = floor_extent(arena)
    texel = 2.0 * e / n
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, markers.dictionary))
    cells = d.markerSize + 2
    offs = (np.arange(PRINTER_SAMPLES) + 0.5) / PRINTER_SAMPLES
    for corner, marker_id in zip(CORNER_ORDER, markers.ids, strict=True):
        modules = cv2.aruco.generateImageMarker(d, int(marker_id), cells, borderBits=1)
        c = marker_corners_world(arena, markers, corner)  # image TL, TR, BR, BL
        inv = np.linalg.inv(np.column_stack([c[1] - c[0], c[3] - c[0]]))
        j0, j1 = (int(np.floor((c[:, 0].min() + e) / texel)) - 1,
                  int(np.ceil((c[:, 0].max() + e) / texel)) + 1)
        i0, i1 = (int(np.floor((e - c[:, 1].max()) / texel)) - 1,
                  int(np.ceil((e - c[:, 1].min()) / texel)) + 1)
        block = out[i0:i1, j0:j1].astype(np.float64)
        total = np.zeros(block.shape)
        jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1))
        for dy in offs:
            for dx in offs:
                x, y = (jj + dx) * texel - e, e - (ii + dy) * texel
                uv = np.einsum("ij,jkl->ikl", inv, np.stack([x - c[0, 0], y - c[0, 1]]))
                ok = (uv[0] >= 0) & (uv[0] < 1) & (uv[1] >= 0) & (uv[1] < 1)
                cu = np.clip((uv[0] * cells).astype(int), 0, cells - 1)
                cv = np.clip((uv[1] * cells).astype(int), 0, cells - 1)
                total += np.where(ok[..., None], modules[cv, cu][..., None].astype(float), block)
        out[i0:i1, j0:j1] = np.rint(total / PRINTER_SAMPLES ** 2).astype(np.uint8)
    return out


def _printed(seed: int, arena: ArenaSpec, markers: MarkerSpec, floor: np.ndarray
             ) -> tuple[ArenaSpec, MarkerSpec, np.ndarray] | None:
    """For an image arena, whether its markers are printed on its texture (drawn from ``seed``
    apart from the case's other draws): if so the arena with the margin that puts the
    markers' outer corners a multiple of 4 texels in from the texture's edge on a side drawn
    in :data:`PRINTED_SIDES` (an author places them on the image's pixel grid), the markers
    printed, and the texture at that side with them printed on it; else None."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7717, 2]))
    if rng.random() >= PRINTED_SHARE:
        return None
    n = int(rng.integers(*PRINTED_SIDES))
    e = floor_extent(arena)
    k = 4 * max(1, round(arena.margin_m * n / (2.0 * e) / 4))  # texels in, as near as drawn
    arena = replace(arena, margin_m=round(k * arena.side_m / (n - 2 * k), 9))
    markers = replace(markers, printed=True, quiet_zone_m=0.0)
    big = cv2.resize(floor, (n, n), interpolation=cv2.INTER_LINEAR)
    return arena, markers, _print_markers(big, arena, markers)


def _boxes(rng: np.random.Generator, arena: ArenaSpec, markers: MarkerSpec,
           grey: int) -> tuple[Obstacle, ...]:
    from shapely.geometry import Polygon

    from arenabench.generator.model.layout import box_footprint

    side = arena.side_m
    inner = side / 2 - markers.side_m - 0.06 * side
    out: list[Obstacle] = []
    turned = rng.random() < 0.3
    for _ in range(int(rng.integers(1, 5))):
        for _ in range(200):
            w = float(rng.uniform(0.06, 0.11)) * side
            ob = Obstacle(center_m=tuple(float(v) for v in rng.uniform(-inner, inner, 2)),
                          yaw_deg=float(rng.uniform(-60, 60)) if turned
                          else float(rng.choice([0.0, 90.0])),
                          length_m=w * float(rng.uniform(1.5, 3.0)), width_m=w,
                          height_m=float(rng.uniform(0.04, 0.09)) * side,
                          color_rgb=(grey,) * 3)
            poly = Polygon(box_footprint(ob))
            if max(abs(c) for c in np.asarray(poly.exterior.coords).ravel()) > inner:
                continue
            if all(poly.distance(Polygon(box_footprint(o))) > 0.05 * side for o in out):
                out.append(ob)
                break
    return tuple(out)


def hidden_case(seed: int, *, image_px: int | None = None) -> HiddenCase:
    """Draw a hidden case from ``seed`` (see the module docstring); ``image_px``: a square
    image of that side instead of the drawn size (a quicker case)."""
    from arenabench.generator.model.sampler import markers_in_view

    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7717]))
    dictionary = str(rng.choice(DICTIONARIES))
    side = float(rng.uniform(3.0, 9.0))
    kind = str(rng.choice(["plain", "speckle", "concrete", "image"]))
    floor = int(rng.integers(228, 253))
    texture = _floor_image(rng) if kind == "image" else None
    arena = ArenaSpec(side_m=round(side, 3), margin_m=round(float(rng.uniform(0.04, 0.12))
                                                            * side, 3),
                      floor_rgb=(floor,) * 3, texture="plain" if kind == "image" else kind,
                      texture_seed=int(rng.integers(0, 100)),
                      border_width_m=round(float(rng.choice([0.0, 0.004, 0.01])) * side, 4),
                      logo_text=str(rng.choice(["", "arena", "lab 7"])))
    if kind == "image":  # an image floor is drawn as it is: no line or logo over it
        arena = replace(arena, border_width_m=0.0, logo_text="")
    msize = round(float(rng.uniform(0.06, 0.09)) * side, 4)
    cells = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)).markerSize + 2
    markers = MarkerSpec(dictionary=dictionary, ids=_ids(rng, dictionary), side_m=msize,
                         rotation_deg=float(rng.choice([0.0, 90.0, 180.0, 270.0])),
                         quiet_zone_m=round(msize / cells * float(rng.choice([0.5, 1.0, 1.5])),
                                            4))
    width, height = (1000, 1000) if rng.random() < 0.7 else (1280, 960)
    if image_px is not None:
        width = height = image_px
    for _ in range(500):
        fov = float(rng.uniform(45, 75))
        reach = floor_extent(arena) * float(rng.uniform(1.02, 1.25))
        camera = CameraSpec(width=width, height=height, fov_deg=round(fov, 4),
                            altitude_m=round(reach / math.tan(math.radians(fov / 2)), 4),
                            tilt_deg=round(float(rng.uniform(1.0, 8.0)), 4),
                            yaw_deg=round(float(rng.uniform(-15, 15)), 4),
                            roll_deg=round(float(rng.uniform(-2, 2)), 4),
                            target_m=tuple(round(float(v), 4)
                                           for v in rng.uniform(-0.03, 0.03, 2) * side))
        if markers_in_view(arena, markers, camera, margin_px=20):
            break
    else:  # pragma: no cover - the draws above always find one
        raise RuntimeError(f"case {seed}: no camera sees the markers")
    el, az = math.radians(float(rng.uniform(40, 80))), math.radians(float(rng.uniform(0, 360)))
    light = LightingSpec(ambient=round(float(rng.uniform(0.45, 0.7)), 4), directional=(
        DirectionalLight(direction=(-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az),
                                    -math.sin(el)), intensity=round(float(rng.uniform(0.25,
                                                                                       0.5)), 4)),))
    grey = int(rng.integers(80, min(160, floor - 70)))
    scene = Scene(arena=arena, markers=markers, obstacles=_boxes(rng, arena, markers, grey),
                  camera=camera, lighting=light,
                  background_rgb=(int(rng.integers(150, floor - 12)),) * 3,
                  render=RenderSpec(edge_samples=int(rng.choice([2, 4])),
                                    edge_resolve=str(rng.choice(["linear", "srgb"]))))
    png = rng.random() < 0.3
    printed = _printed(seed, arena, markers, texture) if texture is not None else None
    if printed is not None:
        arena, markers, texture = printed
        scene = replace(scene, arena=arena, markers=markers)
    return HiddenCase(seed=seed, scene=scene, file_format="png" if png else "jpeg",
                      jpeg_quality=int(rng.integers(80, 101)),
                      jpeg_subsampling=str(rng.choice(["420", "422", "444"])), texture=texture)


def hidden_scene(case: HiddenCase, folder: Path) -> Scene:
    """``case``'s scene as the renderer takes it: an image arena's texture written into a
    private subfolder of ``folder`` (``.hidden``, which the twin is not told about) and
    imported."""
    scene = case.scene
    if case.texture is None:
        return scene
    hidden = Path(folder) / ".hidden"
    hidden.mkdir(parents=True, exist_ok=True)
    path = hidden / f"floor-{case.seed}.png"
    cv2.imwrite(str(path), cv2.cvtColor(case.texture, cv2.COLOR_RGB2BGR))
    side = round(2.0 * floor_extent(scene.arena), 6)  # the image covers the floor square
    return replace(scene, arena=replace(scene.arena, texture=IMAGE_TEXTURE,
                                        texture_file=import_texture(path),
                                        texture_size_m=(side, side)))


def write_case(case: HiddenCase, folder: Path, renderer) -> Path:
    """Render ``case`` and write its image file into ``folder`` (its arena texture, for an
    image arena, into a private subfolder the twin is not told about). Returns the image."""
    from arenabench.imageio import encode_image

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    bgr = cv2.cvtColor(renderer.render(hidden_scene(case, folder)).rgb, cv2.COLOR_RGB2BGR)
    data = encode_image(bgr, image_format=case.file_format, jpeg_quality=case.jpeg_quality,
                        jpeg_subsampling=case.jpeg_subsampling)
    out = folder / case.image_name
    out.write_bytes(data)
    return out


def _grey(rgb) -> float:
    return float(np.mean(rgb))


def _preset_camera(p: dict[str, Any]) -> CameraSpec:
    """The camera of a preset's fixed camera parameters."""
    return CameraSpec(width=p["camera.width"], height=p["camera.height"],
                      fov_deg=p["camera.fov_deg"], altitude_m=p["camera.altitude_m"],
                      tilt_deg=p["camera.tilt_deg"], yaw_deg=p["camera.yaw_deg"],
                      roll_deg=p["camera.roll_deg"],
                      target_m=(p["camera.target_x_m"], p["camera.target_y_m"]))


def _camera_px(hidden: Scene, twin_camera: CameraSpec, twin_side: float,
               turn_deg: float = 0.0) -> float:
    """RMS image distance of floor points inside the arena (a 9 x 9 grid), the twin's camera
    scaled to the hidden arena: the floor's homography, which the image pins (the field of view
    and the altitude trade against each other along it, see the twin's open records).
    ``turn_deg``: the twin's world is the hidden one turned by that angle about the vertical
    (its first corner another marker's)."""
    k = hidden.arena.side_m / twin_side
    scaled = replace(twin_camera, altitude_m=twin_camera.altitude_m * k,
                     target_m=tuple(v * k for v in twin_camera.target_m))
    h = hidden.arena.side_m / 2
    grid = np.linspace(-h, h, 9)
    pts = np.array([(x, y, 0.0) for x in grid for y in grid])
    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    turned = pts @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    a = cam.project(pts, cam.intrinsics(hidden.camera), cam.world_from_camera(hidden.camera))
    b = cam.project(turned, cam.intrinsics(scaled), cam.world_from_camera(scaled))
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def _preset_light(p: dict[str, Any]):
    """The main light of a preset's fixed ``lighting.*`` parameters."""
    el, az = math.radians(p["lighting.elevation_deg"]), math.radians(p["lighting.azimuth_deg"])
    d = (-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), -math.sin(el))
    return LightingSpec(ambient=p["lighting.ambient"],
                        directional=(DirectionalLight(direction=d,
                                                      intensity=p["lighting.intensity"]),))


def _light_off(twin: Scene, faces: list[dict[str, Any]], own: dict[str, Any],
               other: dict[str, Any]) -> float:
    """The largest change (grey levels) of the floor's factor (times 255), a box top's and a
    seen face's shade when the light of ``own`` becomes that of ``other``."""
    from arenabench.generator.fitting.shades import COMPASS

    a, b = _preset_light(own), _preset_light(other)
    off = 255.0 * abs(floor_factor(a) - floor_factor(b))
    for face in faces:
        ob = twin.obstacles[face["box"]]
        want = COMPASS.index(face["direction"]) * 90.0
        angle = min((ob.yaw_deg + 90.0 * j for j in range(4)),
                    key=lambda x: abs((x - want + 180.0) % 360.0 - 180.0))
        n = np.array([[math.cos(math.radians(angle)), math.sin(math.radians(angle)), 0.0],
                      [0.0, 0.0, 1.0]])
        top = ob.color_rgb[0]
        fa, fb = shade_factors(n, a), shade_factors(n, b)
        off = max(off, *(abs(min(top * x, 255.0) - min(top * y, 255.0))
                         for x, y in zip(fa, fb, strict=True)))
    return float(off)


def _hidden_face(hidden: Scene, twin: Scene, box: int, direction: str) -> float:
    """The hidden shade of the face the twin's box ``box`` shows towards ``direction``: the
    hidden box nearest to it (centres scaled to the hidden arena), its side face whose normal
    is nearest to that compass direction (a turned box's faces are turned with it)."""
    from arenabench.generator.fitting.shades import COMPASS

    k = hidden.arena.side_m / twin.arena.side_m
    c = np.asarray(twin.obstacles[box].center_m) * k
    ob = min(hidden.obstacles, key=lambda o: float(np.linalg.norm(np.asarray(o.center_m) - c)))
    want = COMPASS.index(direction) * 90.0
    angle = min((ob.yaw_deg + 90.0 * j for j in range(4)),
                key=lambda a: abs((a - want + 180.0) % 360.0 - 180.0))
    a = math.radians(angle)
    factor = shade_factors(np.array([[math.cos(a), math.sin(a), 0.0]]), hidden.lighting)[0]
    return float(min(ob.color_rgb[0] * factor, 255.0))


def _printed_checks(case: HiddenCase, twin, params: dict, twin_dir: Path, check) -> None:
    """Markers drawn as sheets or printed, as hidden; printed ones on the texel grid found."""
    hidden = case.scene
    printed = params.get("markers.printed")
    if printed is not None and printed["status"] == "pinned":  # drawn sheets or printed
        check("markers.printed", hidden.markers.printed, printed["value"],
              hidden.markers.printed == printed["value"])
        if hidden.markers.printed and printed["value"]:  # on the texel grid found
            texels = cv2.imread(str(twin_dir / params["arena.texture_file"]["value"]),
                                cv2.IMREAD_UNCHANGED).shape[1]
            hidden_texel = 2.0 * floor_extent(hidden.arena) / case.texture.shape[1]
            want = hidden_texel / hidden.arena.side_m
            got = twin.arena.texture_size_m[0] / texels / twin.arena.side_m
            drift = abs(got / want - 1.0) * hidden.markers.side_m / hidden_texel
            check(f"printed markers' texel grid (texels of drift across a marker; texture "
                  f"sides {case.texture.shape[1]}, {texels})", 0.0, round(drift, 3),
                  drift <= TOLERANCES["texel"][0])


def same_family(hidden: str, found: str) -> bool:
    """Whether the twin's dictionary ``found`` is of the hidden one's family (the image shows
    the family, not which of its sizes the markers were drawn from), or the same one."""
    from arenabench.generator.fitting.markers import _family

    fam, got = _family(hidden), _family(found)
    return bool((fam and got and fam[0] == got[0]) or hidden.upper() == found.upper())


def compare(case: HiddenCase, twin_dir: Path) -> dict[str, Any]:
    """What the twin in ``twin_dir`` recovered of ``case``, each check with its outcome."""
    from arenabench.generator.model.scene import load_scene

    doc = json.loads((Path(twin_dir) / "twin.json").read_text())
    twin = load_scene(Path(twin_dir) / "scene.json")
    hidden = case.scene
    params = doc["parameters"]
    checks: dict[str, tuple[Any, Any, bool]] = {}

    def check(name: str, want: Any, got: Any, ok: bool) -> None:
        checks[name] = (want, got, bool(ok))

    check("markers.dictionary", hidden.markers.dictionary, doc["markers"]["dictionary"],
          same_family(hidden.markers.dictionary, doc["markers"]["dictionary"]))
    check("markers.ids", list(hidden.markers.ids), doc["markers"]["ids"],
          list(hidden.markers.ids) == doc["markers"]["ids"])
    check("markers.rotation_deg", hidden.markers.rotation_deg % 360,
          doc["markers"]["rotation_deg"], hidden.markers.rotation_deg % 360
          == doc["markers"]["rotation_deg"])
    ratio = twin.markers.side_m / twin.arena.side_m
    want_ratio = hidden.markers.side_m / hidden.arena.side_m
    check("markers.side / arena.side", round(want_ratio, 5), round(ratio, 5),
          abs(ratio - want_ratio) <= 0.004 * want_ratio + 1e-4)
    px = _camera_px(hidden, twin.camera, twin.arena.side_m)
    check("camera (image px)", 0.0, round(px, 3), px <= TOLERANCES["camera_px"][0])
    fov = params["camera.fov_deg"]
    tol = TOLERANCES["fov_deg"][0]
    if fov["status"] == "open":  # the hidden value inside the range kept
        lo, hi = fov["range"]
        check("camera.fov_deg (open: range)", hidden.camera.fov_deg, [lo, hi],
              lo - tol <= hidden.camera.fov_deg <= hi + tol)
    else:
        check("camera.fov_deg", hidden.camera.fov_deg, twin.camera.fov_deg,
              abs(hidden.camera.fov_deg - twin.camera.fov_deg) <= tol)
    preset = load_preset_file(Path(twin_dir) / "preset.toml")
    if fov["status"] == "open":  # its variants move the camera along the trade the image pins
        entry = preset.open["camera.fov_deg"]
        for end in (entry.range.lo, entry.range.hi):
            moved = _preset_camera({**preset.params, "camera.fov_deg": end, **entry.at(end)})
            px = _camera_px(hidden, moved, twin.arena.side_m)  # as the pinned camera's
            check(f"camera at fov {end:g} (image px)", 0.0, round(px, 3),
                  px <= TOLERANCES["camera_px"][0])
    # a length open only up to scale is not varied (alone it gives another image)
    gauge = sorted(k for k in params if params[k].get("gauge"))
    check("scale-only lengths not in [open]", [], sorted(set(gauge) & set(preset.open)),
          not set(gauge) & set(preset.open))
    if fov["status"] == "pinned":  # with an open field of view the tilt moves with it
        a, b = cam.world_from_camera(hidden.camera), cam.world_from_camera(twin.camera)
        turn = math.degrees(math.acos(float(np.clip(
            (np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1, 1))))
        check("camera rotation (deg)", 0.0, round(turn, 4), turn <= TOLERANCES["angle_deg"][0])
    f = min(floor_factor(hidden.lighting), 1.0)
    tol = TOLERANCES["grey"][0]
    floor = _grey(hidden.arena.floor_rgb) * f
    if case.texture is not None:  # a picture tinted by floor_rgb: its own commonest grey
        floor *= float(np.median(case.texture)) / 255.0
    # the floor's grey as the twin read it (a rectified texture's tint, arena.floor_rgb, is
    # the floor's lightest grey: its record says so)
    got_floor = _grey(doc["shades"]["floor_rgb"])
    check("floor grey", round(floor, 1), round(got_floor, 1), abs(floor - got_floor) <= tol)
    if params["background.gray"]["status"] == "pinned":
        check("background grey", _grey(hidden.background_rgb), _grey(twin.background_rgb),
              abs(_grey(hidden.background_rgb) - _grey(twin.background_rgb)) <= tol)
    if hidden.obstacles and twin.obstacles:  # (one grey for every box of a case)
        # as the renderer shades a box's top: a lit mesh, its factor not capped at 1 as the
        # floor's is (a light brighter than white lifts the boxes, not the floor)
        top = min(round(hidden.obstacles[0].color_rgb[0] * floor_factor(hidden.lighting)), 255)
        got = min(round(twin.obstacles[0].color_rgb[0] * floor_factor(twin.lighting)), 255)
        check("box top grey", round(top, 1), round(got, 1), abs(top - got) <= tol)
        for face in doc["shades"]["faces"]:
            d = face["direction"]
            want = _hidden_face(hidden, twin, face["box"], d)
            check(f"{d} face grey (seen, box {face['box']})", round(want, 1), face["gray"],
                  abs(want - face["gray"]) <= tol)
        if "lighting.azimuth_deg" in preset.open:
            # each light the phase check tries keeps the floor, the tops and the faces seen
            entry = preset.open["lighting.azimuth_deg"]
            off = max(_light_off(twin, doc["shades"]["faces"], preset.params,
                                 {**preset.params, "lighting.azimuth_deg": az, **entry.at(az)})
                      for az in entry.values or ())
            check(f"shades seen, {len(entry.values or ()) - 1} other lights (grey levels)", 0.0,
                  round(off, 2), off <= tol)
    _printed_checks(case, twin, params, Path(twin_dir), check)
    check("obstacles seen", len(hidden.obstacles), len(twin.obstacles),
          len(hidden.obstacles) == len(twin.obstacles))
    for name, want in (("render.edge_samples", hidden.render.edge_samples),
                       ("render.edge_resolve", hidden.render.edge_resolve)):
        rec = params[name]
        if rec["status"] == "pinned":
            check(name, want, rec["value"], want == rec["value"])
    image = doc["image"]
    check("output.format", case.file_format, image["format"], case.file_format == image["format"])
    if case.file_format == "jpeg":
        check("output.jpeg_quality", case.jpeg_quality, image["jpeg_quality"],
              case.jpeg_quality == image["jpeg_quality"])
        check("output.jpeg_subsampling", case.jpeg_subsampling, image["jpeg_subsampling"],
              case.jpeg_subsampling == image["jpeg_subsampling"])
    mad = doc["figures"]["mad"]["markers"]
    check("marker squares (grey levels)", TOLERANCES["marker_squares"][0], mad,
          mad <= TOLERANCES["marker_squares"][0])
    opened = sorted(k for k, v in params.items() if v["status"] == "open" and
                    (v.get("range") is not None or len(v.get("values", [])) > 1))
    reproduced = all(ok for _, _, ok in checks.values())
    verdict = doc["verdict"]["verdict"]
    # the verdict is right when a twin within every tolerance says good, and one that is not
    # says poor (never good)
    checks["verdict"] = ("good" if reproduced else "poor", verdict,
                         verdict == ("good" if reproduced else "poor"))
    return {"seed": case.seed, "checks": checks, "open": opened,
            "reproduced": reproduced, "verdict": verdict, "causes": doc["verdict"]["causes"],
            "ok": checks["verdict"][2],
            "figures": doc["figures"], "timings_s": doc.get("timings_s", {})}


def round_trip(case: HiddenCase, folder: Path, renderer, *, reuse: bool = False
               ) -> dict[str, Any]:
    """Render ``case`` into ``folder``, run ``arenabench twin`` on the image file alone (a
    subprocess, as a user runs it; its twin in ``folder/twin``) and :func:`compare`; with
    ``reuse``, a twin already there is compared again."""
    out = Path(folder) / "twin"
    if reuse and (out / "twin.json").exists():
        return compare(case, out)
    image = write_case(case, folder, renderer)
    proc = subprocess.run([sys.executable, "-m", "arenabench", "twin", str(image), "--out",
                           str(out), "--no-progress"], capture_output=True, text=True)
    if proc.returncode not in (0, 6):  # 6: written, its verdict poor (compare judges it)
        raise AssertionError(f"case {case.seed}: arenabench twin exited {proc.returncode}: "
                             f"{proc.stderr.strip()}")
    return compare(case, out)


def reference_pass_rate(twin_dir: Path, count: int, seed: int = 0) -> float:
    """The reference pipeline's pass rate (visible area reference) on scenes 0..count-1 of the
    twin's preset (``tests/pipelines/pass_rates.py``: each image written as the preset says)."""
    from pass_rates import score_preset

    preset = load_preset_file(Path(twin_dir) / "preset.toml")
    tally = score_preset(preset.params, count=count, seed=seed, pipelines=("reference",),
                         references=("visible",))["reference"]
    return tally.rate("visible")


def reference_on_image(case: HiddenCase, image: Path) -> tuple[bool, str]:
    """Whether the reference pipeline passes the "real" image itself (visible area reference,
    the hidden scene's ground truth), with a short account: where it fails the real arena
    (lines it counts as boxes, say), a twin's scenes that it fails too are the twin being
    faithful, and the pass-rate check does not apply."""
    from arenabench.competition import DEFAULT_TOLERANCE
    from arenabench.eval.datasets.reader import DatasetItem
    from arenabench.eval.pipelines import make_pipeline
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.generator.dataset.make import ground_truth_record
    from arenabench.imageio import load_image

    gt = ground_truth_record(case.scene, sid="hidden", preset="hidden")
    item = DatasetItem(id="hidden", image_path=Path(image), gt_path=Path("hidden.json"), gt=gt)
    truth = item.truth(area_reference="visible")
    pred = make_pipeline("reference").run_image(load_image(image))
    s = score_image(truth, pred, tolerance=DEFAULT_TOLERANCE)
    return bool(s.passed), (f"passed (answered {pred.count})" if s.passed else
                            f"{s.category}: answered {pred.count} obstacles, hidden "
                            f"{len(case.scene.obstacles)}")

