"""The camera, fitted freely to the four markers, then snapped to round values where those fit
as well.

1. **Corners.** The markers' sub-pixel corners give a homography from the arena's floor to the
   image (the marker side searched when it is not known); the homography gives the focal
   length (square pixels, centred principal point: its two rotation columns must be
   orthogonal and of equal length) and ``cv2.solvePnP`` the pose.
2. **Marker pixels.** Pose, field of view, the marker side (when not known) and a blur are
   refined by Levenberg-Marquardt on the pixels inside the four markers
   (:mod:`arenabench.generator.fitting.marker_model`): a corner detector is biased where a
   marker touches a printed line, the modules are not.
3. **The renderer** (with a known arena texture): the same, on the squares around the markers
   of the generator's own render (:class:`RenderObjective`), which samples the texture as the
   target renderer does; this is what the fitted scene's render is judged on.
4. **Round values.** Roll, field of view, the axis' angle from the nadir (as a pitch below the
   horizon, which a simulator states) and heading are tried at round values, in radians and
   in degrees, coarsest first (:data:`SNAP_STEPS`), the other free parameters refitted; a value
   is kept when the residual grows by at most :data:`SNAP_TOLERANCE` and the arena's floor
   moves by at most :data:`SNAP_MOVE_PX` in the image (the competition's camera: roll 0,
   1.2 rad field of view, 1.5 rad pitch).

All fitting runs on the orbit-form parameters (:data:`ORBIT`), so an angle can be held.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from arenabench.frame import CORNER_ORDER
from arenabench.generator.fitting import marker_model as mm
from arenabench.generator.fitting.markers import MarkerFinding
from arenabench.generator.model import camera as cam
from arenabench.generator.model.camera import camera_from_pose
from arenabench.generator.model.layout import MARKER_Z, marker_corners_world
from arenabench.generator.model.scene import ArenaSpec, CameraSpec, MarkerSpec, Scene
from arenabench.interrupts import checkpoint

#: Round values tried for each angle, coarsest first: (unit, step). Radians first: a
#: simulator's camera is usually stated in radians (Gazebo's SDF).
#: No finer step: an angle known to a few hundredths of a degree lies within the tolerance of
#: some value on a finer grid whatever it is, so a snap there would say nothing.
SNAP_STEPS: tuple[tuple[str, float], ...] = (
    ("rad", 0.1), ("deg", 5.0), ("rad", 0.05), ("deg", 1.0))
#: A round value is kept when the RMS residual grows by at most this share of the free fit's
SNAP_TOLERANCE = 0.01
#: ... and the camera moves the arena's floor by at most this (px, RMS over a 5 x 5 grid)
#: from the free fit's: a residual far from zero (a model unlike the image) grows by less than
#: 1 % under moves of a third of a pixel (an ``eyrc-oblique`` scene's field of view, 58.10
#: deg, fitted 58.18, was snapped to 58 there, 0.32 px off its hidden camera).
SNAP_MOVE_PX = 0.1
#: The orbit-form parameters fitted (``CameraSpec`` fields; ``target_x``/``target_y`` are
#: ``target_m``'s two coordinates).
ORBIT = ("target_x", "target_y", "altitude_m", "tilt_deg", "yaw_deg", "roll_deg", "fov_deg")
#: The angles that may snap, in the order tried (roll first: most cameras have none).
SNAPPABLE = ("roll_deg", "fov_deg", "tilt_deg", "yaw_deg")
#: Finite-difference steps of the orbit parameters (m, deg) for the marker model.
MODEL_STEPS = np.array([1e-4, 1e-4, 2e-4, 2e-3, 2e-3, 2e-3, 2e-3])
#: The same for the renderer (its 8-bit output needs larger moves, about 0.05 px).
RENDER_STEPS = np.array([2e-4, 2e-4, 5e-4, 5e-3, 5e-3, 5e-3, 5e-3])
#: Starting blur (px) of the marker model.
START_SIGMA_PX = 0.5
#: Moves (orbit units: m, deg) for the pinned-residual figures: 1 mm and 0.01 deg.
SENSITIVITY_STEPS = {"target_x": 0.001, "target_y": 0.001, "altitude_m": 0.001,
                     "tilt_deg": 0.01, "yaw_deg": 0.01, "roll_deg": 0.01, "fov_deg": 0.01}


@dataclass(frozen=True)
class CameraFit:
    """A fitted camera and its evidence.

    Attributes
    ----------
    camera : CameraSpec
        The camera (orbit form), snapped where round values fit as well.
    free : CameraSpec
        The freely fitted camera (before snapping).
    marker_side_m : float
        The marker side (fitted, or the given one).
    sigma_px : float
        The marker model's blur.
    rms_free, rms : float
        RMS residual of the last stage (grey levels), free and snapped.
    stage : str
        Which residual the last stage used: ``"markers"`` (the marker model, linear light) or
        ``"render"`` (the renderer, sRGB grey).
    corner_rms_px : float
        RMS distance of the detected sub-pixel corners from the camera's projection.
    snapped : dict
        Angle name -> (unit, value in that unit) of each snapped angle.
    sensitivity : dict
        Parameter -> how much the RMS residual grows when that parameter moves by its step
        in :data:`SENSITIVITY_STEPS` (grey levels): the residual of a pinned value.
    fov_range : tuple of float or None
        The fields of view (deg, lowest and highest) at which the markers fit as well, the
        other parameters refitted (:func:`fov_range`); ``None`` where not scanned.
    fov_ends : tuple of dict or None
        The two fits at those fields of view: each :data:`ORBIT` parameter's value (lengths in
        the fit's units), at the lowest, then at the highest.
    nadir : bool
        The camera looks within :data:`NADIR_TILT_DEG` of straight down: its heading was held
        at 0 and the image's turn is its roll (the two turn such an image alike).
    """

    camera: CameraSpec
    free: CameraSpec
    marker_side_m: float
    sigma_px: float
    rms_free: float
    rms: float
    stage: str
    corner_rms_px: float
    snapped: dict[str, tuple[str, float]] = field(default_factory=dict)
    sensitivity: dict[str, float] = field(default_factory=dict)
    fov_range: tuple[float, float] | None = None
    fov_ends: tuple[dict[str, float], dict[str, float]] | None = None
    nadir: bool = False


#: Tilt (deg) below which the axis' heading and the roll turn the image alike (one rotation
#: about the vertical): the heading is held at 0 and the turn fitted as roll, so neither
#: drifts along the other nor snaps to a value the other makes fit.
NADIR_TILT_DEG = 0.5


def _heading_into_roll(v: np.ndarray, width: int, height: int) -> np.ndarray:
    """``v`` with its heading 0 and the same rotation about the vertical in its roll."""
    camera = orbit_camera(v, width, height)
    pose = cam.world_from_camera(camera)
    level = cam.world_from_camera(replace(camera, yaw_deg=0.0, roll_deg=0.0))
    m = level[:3, :3].T @ pose[:3, :3]
    out = v.copy()
    out[ORBIT.index("yaw_deg")] = 0.0
    out[ORBIT.index("roll_deg")] = math.degrees(math.atan2(m[1, 0], m[0, 0]))
    return out


#: Field-of-view offsets (deg) scanned by :func:`fov_range`, nearest first, each way, until
#: the markers no longer fit as well. Out to 32 deg: seen 2 deg from the nadir, markers can fit
#: as well more than 6 deg from the fitted field of view (docs/measurements.md, the blind
#: round trips).
FOV_SCAN_DEG = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
#: The fields of view :func:`fov_range` keeps to (deg): a pinhole camera's sensible span.
FOV_SCAN_BOUNDS = (10.0, 150.0)


def fov_range(objective: Objective, v: np.ndarray, extra: np.ndarray, rms_ref: float, *,
              iterations: int = 8, held: tuple[str, ...] = ()
              ) -> tuple[tuple[float, float], tuple[dict[str, float], dict[str, float]]]:
    """The fields of view at which the markers fit as well as at ``v`` (the residual within
    :data:`SNAP_TOLERANCE` of ``rms_ref``), every other parameter refitted, scanned out to
    :data:`FOV_SCAN_DEG` each way: a near-nadir view of a flat arena trades the field of view
    against the altitude (every floor point keeps its pixel), so only the perspective of a
    tilted view, weak at a few degrees, tells them apart. Returns ((lowest, highest) field of
    view, (the fit there, the fit there)), each fit as {:data:`ORBIT` name: value}."""
    k, a = ORBIT.index("fov_deg"), ORBIT.index("altitude_m")
    limit = rms_ref * (1.0 + SNAP_TOLERANCE)
    free = tuple(i for i, name in enumerate(ORBIT) if i != k and name not in held)
    ends = []
    for sign in (-1.0, 1.0):
        best = v
        for offset in FOV_SCAN_DEG:
            fov = v[k] + sign * offset
            if not FOV_SCAN_BOUNDS[0] <= fov <= FOV_SCAN_BOUNDS[1]:
                break
            trial = best.copy()
            trial[k] = fov
            trial[a] = best[a] * math.tan(math.radians(best[k] / 2)) / math.tan(
                math.radians(trial[k] / 2))  # the floor's image about the same
            tv, _, trms = levenberg_marquardt(objective, trial, extra, free=free,
                                              iterations=iterations)
            if trms > limit:
                break
            best = tv
        ends.append(best)
    lo, hi = ends
    fits = tuple({name: round(float(e[i]), 6) for i, name in enumerate(ORBIT)} for e in ends)
    return (round(float(lo[k]), 4), round(float(hi[k]), 4)), (fits[0], fits[1])


def world_corners(arena: ArenaSpec, markers: MarkerSpec) -> np.ndarray:
    """World (x, y, z) of the 16 marker corners, NW to SW, cv2.aruco order each: (16, 3)."""
    xy = np.vstack([marker_corners_world(arena, markers, c) for c in CORNER_ORDER])
    return np.column_stack([xy, np.full(len(xy), MARKER_Z)])


def image_corners(finding: MarkerFinding) -> np.ndarray:
    """The 16 detected sub-pixel corners, in :func:`world_corners`' order: (16, 2)."""
    return np.vstack([finding.corners[c] for c in CORNER_ORDER])


def focal_from_homography(h: np.ndarray, cx: float, cy: float) -> float | None:
    """The focal length (px) that makes a plane-to-image homography's two rotation columns
    orthogonal and of equal length (principal point ``cx, cy``, square pixels); ``None`` when
    the plane is seen too squarely for the homography to fix it."""
    t = np.array([[1.0, 0.0, -cx], [0.0, 1.0, -cy], [0.0, 0.0, 1.0]])
    g = t @ h
    a, b = g[:, 0], g[:, 1]
    # orthogonal: (a0 b0 + a1 b1) w + a2 b2 = 0; equal length: (|a01|^2 - |b01|^2) w +
    # a2^2 - b2^2 = 0, with w = 1 / f^2: least squares over both
    rows = np.array([[a[0] * b[0] + a[1] * b[1], a[2] * b[2]],
                     [a[0] ** 2 + a[1] ** 2 - b[0] ** 2 - b[1] ** 2, a[2] ** 2 - b[2] ** 2]])
    num = -float(rows[:, 0] @ rows[:, 1])
    den = float(rows[:, 0] @ rows[:, 0])
    if den <= 0 or num <= 0:
        return None
    return 1.0 / math.sqrt(num / den)


def _marker_side_by_homography(finding: MarkerFinding, arena: ArenaSpec,
                               markers: MarkerSpec) -> float:
    """The marker side whose 16 corners a homography fits best (golden section)."""
    image = image_corners(finding)

    def err(side: float) -> float:
        world = world_corners(arena, replace(markers, side_m=side))[:, :2]
        h, _ = cv2.findHomography(world, image, 0)
        proj = cv2.perspectiveTransform(world.reshape(-1, 1, 2), h).reshape(-1, 2)
        return float(np.mean(np.sum((proj - image) ** 2, axis=1)))

    grid = np.linspace(0.02 * arena.side_m, 0.45 * arena.side_m, 60)
    i = int(np.argmin([err(s) for s in grid]))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    gr = (math.sqrt(5) - 1) / 2
    for _ in range(40):
        c, d = b - gr * (b - a), a + gr * (b - a)
        if err(c) < err(d):
            b = d
        else:
            a = c
    return float((a + b) / 2)


def _k(f: float, width: int, height: int) -> np.ndarray:
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0, 0, 1.0]])


def _pose_matrix(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    r_cw, _ = cv2.Rodrigues(np.asarray(rvec, np.float64))
    pose = np.eye(4)
    pose[:3, :3] = r_cw.T
    pose[:3, 3] = -r_cw.T @ np.asarray(tvec, np.float64).ravel()
    return pose


def corner_camera(finding: MarkerFinding, arena: ArenaSpec, markers: MarkerSpec,
                  width: int, height: int, *, fov_deg: float | None = None) -> CameraSpec:
    """Step 1: the camera from the corners alone (field of view from the homography, or
    ``fov_deg`` when it is known; pose from ``cv2.solvePnP``; 60 deg when the view is too
    square to give one)."""
    world, image = world_corners(arena, markers), image_corners(finding)
    if fov_deg is not None:
        f = height / 2.0 / math.tan(math.radians(fov_deg / 2.0))
    else:
        h, _ = cv2.findHomography(world[:, :2], image, 0)
        f = focal_from_homography(h, (width - 1) / 2.0, (height - 1) / 2.0)
    if f is None or not 0.2 * width < f < 50.0 * width:
        f = height / 2.0 / math.tan(math.radians(30.0))
    K = _k(f, width, height)
    ok, rvec, tvec = cv2.solvePnP(world, image, K, None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:  # pragma: no cover - four or more coplanar points always give a pose
        raise ValueError("image: no camera pose fits the markers")
    rvec, tvec = cv2.solvePnPRefineLM(world, image, K, None, rvec, tvec)
    fov = math.degrees(2.0 * math.atan(height / 2.0 / f)) if fov_deg is None else fov_deg
    return camera_from_pose(_pose_matrix(rvec, tvec), fov_deg=fov, width=width, height=height)


def orbit_vector(camera: CameraSpec) -> np.ndarray:
    """The camera's :data:`ORBIT` parameters as a vector."""
    return np.array([camera.target_m[0], camera.target_m[1], camera.altitude_m,
                     camera.tilt_deg, camera.yaw_deg, camera.roll_deg, camera.fov_deg])


def orbit_camera(v: np.ndarray, width: int, height: int) -> CameraSpec:
    """The orbit-form camera of a :data:`ORBIT` vector (angles kept in their bounds)."""
    return CameraSpec(width=width, height=height, target_m=(float(v[0]), float(v[1])),
                      altitude_m=float(max(v[2], 1e-3)),
                      tilt_deg=float(min(max(v[3], 0.0), 79.0)), yaw_deg=float(v[4]),
                      roll_deg=float(v[5]), fov_deg=float(min(max(v[6], 1.0), 170.0)))


class Objective:
    """Residuals of a camera (an :data:`ORBIT` vector) and of extra parameters.

    Attributes
    ----------
    steps : numpy.ndarray
        Finite-difference steps of the orbit parameters.
    extra_steps : numpy.ndarray
        The same for the extra parameters.
    """

    steps: np.ndarray = MODEL_STEPS
    extra_steps: np.ndarray = np.zeros(0)
    arena: ArenaSpec
    width: int
    height: int

    def residuals(self, v: np.ndarray, extra: np.ndarray) -> np.ndarray:  # pragma: no cover
        """Residual vector."""
        raise NotImplementedError

    def floor_move_px(self, a: np.ndarray, b: np.ndarray) -> float:
        """RMS image distance (px) of a 5 x 5 grid over the arena's square between the
        cameras of the orbit vectors ``a`` and ``b``."""
        h = self.arena.side_m / 2.0
        grid = np.linspace(-h, h, 5)
        pts = np.array([(x, y, 0.0) for x in grid for y in grid])
        pa, pb = (cam.project(pts, cam.intrinsics(c), cam.world_from_camera(c))
                  for c in (orbit_camera(v, self.width, self.height) for v in (a, b)))
        return float(np.sqrt(np.mean(np.sum((pa - pb) ** 2, axis=1))))


class MarkerObjective(Objective):
    """The marker model's residuals (step 2); extras: the marker side when fitted, the blur."""

    steps = MODEL_STEPS

    def __init__(self, gray: np.ndarray, finding: MarkerFinding, arena: ArenaSpec,
                 markers: MarkerSpec, *, fit_side: bool) -> None:
        self.arena, self.markers, self.fit_side = arena, markers, fit_side
        self.height, self.width = gray.shape
        modules = {c: mm.module_pattern(finding.dictionary, i)
                   for c, i in zip(CORNER_ORDER, finding.ids, strict=True)}
        self.patches = mm.marker_patches(gray, finding.corners, modules)
        self.extra_steps = np.array(([markers.side_m * 2e-4] if fit_side else []) + [0.01])

    def split(self, extra: np.ndarray) -> tuple[float, float]:
        """(marker side, blur) of an extra vector."""
        return (float(extra[0]) if self.fit_side else self.markers.side_m), float(extra[-1])

    def residuals(self, v: np.ndarray, extra: np.ndarray) -> np.ndarray:
        camera = orbit_camera(v, self.width, self.height)
        side, sigma = self.split(extra)
        return mm.residuals(self.patches, cam.intrinsics(camera), cam.world_from_camera(camera),
                            self.arena, replace(self.markers, side_m=side), max(sigma, 0.0))


class RenderObjective(Objective):
    """The generator's render against the image in the squares around the markers (step 3):
    sRGB grey, after a gain and an offset solved in closed form (the light is fitted later).

    Parameters
    ----------
    scene : Scene
        The scene to render (its camera is replaced); no obstacles are drawn.
    gray : numpy.ndarray
        The image, (H, W) uint8.
    mask : numpy.ndarray
        (H, W) bool: the pixels compared.
    renderer : object
        A :class:`~arenabench.generator.rendering.render.Renderer`.
    """

    steps = RENDER_STEPS

    def __init__(self, scene: Scene, gray: np.ndarray, mask: np.ndarray, renderer, *,
                 fit_side: bool = False) -> None:
        self.scene = replace(scene, obstacles=())
        self.arena = scene.arena
        self.mask = mask
        self.target = gray[mask].astype(np.float64)
        self.renderer = renderer
        self.height, self.width = gray.shape
        self.fit_side = fit_side
        self.extra_steps = np.array([scene.markers.side_m * 5e-4] if fit_side else [])

    def render(self, camera: CameraSpec, side: float | None = None) -> np.ndarray:
        """The grey render of the scene through ``camera`` (markers of ``side``, when given:
        drawn markers only)."""
        scene = replace(self.scene, camera=camera)
        if side is not None:
            scene = replace(scene, markers=replace(scene.markers, side_m=float(side)))
        rgb = self.renderer.render(scene).rgb
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)

    def residuals(self, v: np.ndarray, extra: np.ndarray) -> np.ndarray:
        checkpoint()
        side = float(extra[0]) if self.fit_side else None
        got = self.render(orbit_camera(v, self.width, self.height), side)[self.mask].astype(
            np.float64)
        a = np.column_stack([got, np.ones_like(got)])
        coef, *_ = np.linalg.lstsq(a, self.target, rcond=None)
        return a @ coef - self.target


def levenberg_marquardt(objective: Objective, v: np.ndarray, extra: np.ndarray, *,
                        free: tuple[int, ...], iterations: int = 30
                        ) -> tuple[np.ndarray, np.ndarray, float]:
    """Minimise the objective's squared residuals over the orbit parameters ``free``
    (indices into :data:`ORBIT`) and every extra parameter, by Levenberg-Marquardt with
    central differences. Returns (orbit vector, extras, RMS residual)."""
    free = tuple(free)
    n_free = len(free)

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        vv = v.copy()
        vv[list(free)] = x[:n_free]
        return vv, x[n_free:]

    x = np.concatenate([v[list(free)], extra]).astype(np.float64)
    steps = np.concatenate([objective.steps[list(free)], objective.extra_steps])
    r = objective.residuals(*unpack(x))
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(iterations):
        checkpoint()
        jac = np.empty((len(r), len(x)))
        for j in range(len(x)):
            d = np.zeros_like(x)
            d[j] = steps[j]
            jac[:, j] = (objective.residuals(*unpack(x + d))
                         - objective.residuals(*unpack(x - d))) / (2.0 * steps[j])
        g = jac.T @ r
        a = jac.T @ jac
        improved = False
        delta = np.zeros_like(x)
        for _ in range(8):
            delta = -np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-12), g)
            cand = x + delta
            rc = objective.residuals(*unpack(cand))
            c = float(rc @ rc)
            if c < cost:
                x, r, cost, improved = cand, rc, c, True
                lam = max(lam / 3.0, 1e-7)
                break
            lam *= 4.0
        if not improved or np.all(np.abs(delta) < steps * 0.02):
            break
    vv, ex = unpack(x)
    return vv, ex, math.sqrt(cost / max(len(r), 1))


def round_angle(value_deg: float, unit: str, step: float) -> float:
    """``value_deg`` rounded to a multiple of ``step`` in ``unit`` (``rad`` or ``deg``),
    in degrees."""
    if unit == "rad":
        return math.degrees(round(math.radians(value_deg) / step) * step)
    return round(value_deg / step) * step


def snap_angles(objective: Objective, v: np.ndarray, extra: np.ndarray, rms_free: float, *,
                held: tuple[str, ...] = (), iterations: int = 12,
                progress: Callable[[str], None] | None = None
                ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[str, float]], float]:
    """Step 4: hold each angle at the roundest value that fits as well (see the module
    docstring). ``held``: orbit parameters not to refit (already fixed). Returns (orbit
    vector, extras, snapped angles, RMS residual)."""
    limit = rms_free * (1.0 + SNAP_TOLERANCE)
    free_v = v.copy()
    snapped: dict[str, tuple[str, float]] = {}
    rms = rms_free
    for name in SNAPPABLE:
        if name in held:  # a known value stays as it is
            continue
        k = ORBIT.index(name)
        tried: set[float] = set()
        for unit, step in SNAP_STEPS:
            if name == "tilt_deg":  # a pitch below the horizon, as a simulator states it
                value = 90.0 - round_angle(90.0 - v[k], unit, step)
            else:
                value = round_angle(v[k], unit, step)
            key = round(value, 9)
            if key in tried or abs(value - v[k]) > 2.0 or (name == "tilt_deg" and value < 0):
                continue
            tried.add(key)
            trial = v.copy()
            trial[k] = value
            free = tuple(i for i, n in enumerate(ORBIT)
                         if n not in snapped and n not in held and i != k)
            tv, te, trms = levenberg_marquardt(objective, trial, extra, free=free,
                                               iterations=iterations)
            if trms <= limit and objective.floor_move_px(free_v, tv) <= SNAP_MOVE_PX:
                v, extra, rms = tv, te, trms
                shown = 90.0 - value if name == "tilt_deg" else value
                snapped[name] = (unit, round(math.radians(shown) if unit == "rad" else shown, 9))
                if progress:  # the parameter's own degrees; the world file's value beside
                    world = f"{'pitch ' if name == 'tilt_deg' else ''}{snapped[name][1]:g} {unit}"
                    said = (f"{value:g} deg" if unit == "deg" and name != "tilt_deg"
                            else f"{value:g} deg ({world})")
                    progress(f"{name} snapped to {said}")
                break
    return v, extra, snapped, rms


def sensitivity(objective: Objective, v: np.ndarray, extra: np.ndarray) -> dict[str, float]:
    """Per orbit parameter, how much the RMS residual grows when it moves by its step in
    :data:`SENSITIVITY_STEPS` (the others held)."""
    def rms(vv):
        r = objective.residuals(vv, extra)
        return math.sqrt(float(r @ r) / max(len(r), 1))

    base = rms(v)
    out = {}
    for k, name in enumerate(ORBIT):
        moved = v.copy()
        moved[k] += SENSITIVITY_STEPS[name]
        out[name] = round(rms(moved) - base, 4)
    return out


def rounded_camera(v: np.ndarray, width: int, height: int) -> CameraSpec:
    """The orbit camera of ``v`` with its values rounded as scene files hold them."""
    return orbit_camera(np.round(v, 6), width, height)


def metres_up(camera: CameraSpec) -> str:
    """How the log says a camera's height by default: ``"3.1630 m up"``."""
    return f"{camera.altitude_m:.4f} m up"


def fit_camera(gray: np.ndarray, finding: MarkerFinding, *, arena: ArenaSpec,
               markers: MarkerSpec, fit_marker_side: bool, snap: bool = True,
               fov_deg: float | None = None,
               progress: Callable[[str], None] | None = None,
               up: Callable[[CameraSpec], str] = metres_up) -> CameraFit:
    """Steps 1, 2 and 4: fit the camera (and the marker side when ``fit_marker_side``) to the
    four markers' pixels.

    Parameters
    ----------
    gray : numpy.ndarray
        (H, W) uint8 image.
    finding : MarkerFinding
        The markers (:func:`arenabench.generator.fitting.markers.find_markers`).
    arena, markers : ArenaSpec, MarkerSpec, keyword-only
        The arena's geometry (its side fixes the scale) and the markers (dictionary, ids,
        rotation; their side is the starting value when ``fit_marker_side``).
    fit_marker_side : bool, keyword-only
        Fit the marker side too.
    snap : bool, keyword-only
        Try round values of the angles.
    fov_deg : float or None, keyword-only
        A known field of view, held (``None``: fitted, and the span of those that fit as
        well scanned).
    progress : callable, keyword-only
        Called with a line on each step.
    up : callable, keyword-only
        How those lines say the camera's height (default :func:`metres_up`; the twin says it
        in arena sides until the arena's size is known).

    Returns
    -------
    CameraFit
    """
    height, width = gray.shape
    side = (_marker_side_by_homography(finding, arena, markers) if fit_marker_side
            else markers.side_m)
    mk = replace(markers, side_m=side)
    start = corner_camera(finding, arena, mk, width, height, fov_deg=fov_deg)
    objective = MarkerObjective(gray, finding, arena, mk, fit_side=fit_marker_side)
    extra0 = np.array(([side] if fit_marker_side else []) + [START_SIGMA_PX])
    held = () if fov_deg is None else ("fov_deg",)
    v, extra, rms_free = levenberg_marquardt(
        objective, orbit_vector(start), extra0,
        free=tuple(i for i, name in enumerate(ORBIT) if name not in held))
    nadir = v[ORBIT.index("tilt_deg")] < NADIR_TILT_DEG
    if nadir:  # heading and roll are one turn here: held as roll
        held = (*held, "yaw_deg")
        v, extra, rms_free = levenberg_marquardt(
            objective, _heading_into_roll(v, width, height), extra,
            free=tuple(i for i, name in enumerate(ORBIT) if name not in held))
    free_camera = rounded_camera(v, width, height)
    if progress:
        progress(f"camera fitted freely to the marker pixels: fov {free_camera.fov_deg:.3f} "
                 f"deg, {up(free_camera)}, tilt {free_camera.tilt_deg:.3f} "
                 f"deg (RMS {rms_free:.2f})")
    fovs = fov_ends = None
    if fov_deg is None:
        fovs, fov_ends = fov_range(objective, v, extra, rms_free, held=held)
        if progress:
            progress(f"the markers fit as well from {fovs[0]:.2f} to {fovs[1]:.2f} deg of "
                     "field of view")
    snapped: dict[str, tuple[str, float]] = {}
    rms = rms_free
    if snap:
        v, extra, snapped, rms = snap_angles(objective, v, extra, rms_free, held=held,
                                             progress=progress)
    side, sigma = objective.split(extra)
    camera = rounded_camera(v, width, height)
    proj = cam.project(world_corners(arena, replace(markers, side_m=side)),
                       cam.intrinsics(camera), cam.world_from_camera(camera))
    corner_rms = float(np.sqrt(np.mean(np.sum((proj - image_corners(finding)) ** 2, axis=1))))
    return CameraFit(camera=camera, free=free_camera, marker_side_m=round(side, 6),
                     sigma_px=round(sigma, 4), rms_free=round(rms_free, 4), rms=round(rms, 4),
                     stage="markers", corner_rms_px=round(corner_rms, 4), snapped=snapped,
                     sensitivity=sensitivity(objective, orbit_vector(camera), extra),
                     fov_range=fovs, fov_ends=fov_ends, nadir=bool(nadir))


def refine_with_renderer(fit: CameraFit, scene: Scene, gray: np.ndarray, mask: np.ndarray,
                         renderer, *, snap: bool = True, fit_side: bool = False,
                         progress: Callable[[str], None] | None = None,
                         up: Callable[[CameraSpec], str] = metres_up) -> CameraFit:
    """Step 3 (and 4 again): refine ``fit``'s camera on the generator's render of ``scene``
    (a known arena texture, or drawn markers) in ``mask``, every angle free again, then snap;
    with ``fit_side`` (drawn markers) the marker side too."""
    height, width = gray.shape
    objective = RenderObjective(scene, gray, mask, renderer, fit_side=fit_side)
    none = np.array([scene.markers.side_m] if fit_side else [])
    starts = [orbit_vector(fit.camera), orbit_vector(fit.free)]
    held = ("yaw_deg",) if fit.nadir else ()  # at the nadir the turn stays in the roll
    free = tuple(i for i, name in enumerate(ORBIT) if name not in held)
    best = None
    for start in starts:  # the snapped camera, then the free one: the better fit wins
        v, ex, rms_free = levenberg_marquardt(objective, start, none, free=free,
                                              iterations=8)
        if best is None or rms_free < best[1]:
            best = (v, rms_free, ex)
    v, rms_free, none = best
    free_camera = rounded_camera(v, width, height)
    if progress:
        progress(f"camera refined on the render: fov {free_camera.fov_deg:.3f} deg, "
                 f"{up(free_camera)} (RMS {rms_free:.2f} grey levels)")
    snapped: dict[str, tuple[str, float]] = {}
    rms = rms_free
    if snap:
        v, none, snapped, rms = snap_angles(objective, v, none, rms_free, held=held,
                                            iterations=5, progress=progress)
    camera = rounded_camera(v, width, height)
    side = round(float(none[0]), 6) if fit_side else fit.marker_side_m
    return replace(fit, camera=camera, free=free_camera, rms_free=round(rms_free, 4),
                   rms=round(rms, 4), stage="render", snapped=snapped, marker_side_m=side,
                   sensitivity=sensitivity(objective, orbit_vector(camera), none))
