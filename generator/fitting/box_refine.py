"""The boxes refined on the render: each box's centre, footprint and height moved until the
generator's render of the scene matches the image around it.

The silhouette fit (:func:`arenabench.generator.fitting.scene_fit.fit_boxes`) places a box to a
fraction of
a centimetre; whether an edge pixel is blended or hard depends on where the edge falls within
its pixel, so the render is compared with the image in the box's own region (its image grown
by :data:`REGION_GROW_PX`) and each value searched coordinate-wise, in steps from
:data:`STEPS` (shares of the arena's side: 4 mm down to 0.5 mm on the competition's arena).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import cv2
import numpy as np

from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices
from arenabench.generator.model.scene import Obstacle, Scene
from arenabench.interrupts import checkpoint

#: Pixels around a box's image compared.
REGION_GROW_PX = 3
#: Search steps, as shares of the arena's side, coarse to fine.
STEPS = (1.2e-3, 6e-4, 3e-4, 1.5e-4)
#: The moves searched: each side of the footprint on its own (``side+l`` moves the side at
#: the end of the length axis outwards, the opposite side held: the image shows each edge on
#: its own, so a centre and a size moved separately stall in a diagonal valley), the height,
#: and the height with the top face held where the camera sees it (the footprint follows).
FIELDS = ("side+l", "side-l", "side+w", "side-w", "height_m", "height_keep_top")
#: Passes over the values per step, at most.
MAX_PASSES = 6


def _keep_top(ob: Obstacle, scene: Scene, height: float) -> Obstacle:
    """``ob`` at ``height`` with its top face where the camera sees it now."""
    K, pose = cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera)
    top = cam.project(box_vertices(ob)[4:], K, pose)
    r_cw = pose[:3, :3].T
    t_cw = -r_cw @ pose[:3, 3]
    plane = K @ np.column_stack([r_cw[:, 0], r_cw[:, 1], r_cw[:, 2] * height + t_cw])
    w = cv2.perspectiveTransform(top.reshape(-1, 1, 2), np.linalg.inv(plane)).reshape(-1, 2)
    centre = w.mean(axis=0)
    a, b = np.linalg.norm(w[1] - w[0]), np.linalg.norm(w[2] - w[1])
    return replace(ob, center_m=tuple(round(float(c), 6) for c in centre),
                   length_m=round(float(a), 6), width_m=round(float(b), 6),
                   height_m=round(height, 6))


def _moved(ob: Obstacle, name: str, d: float, scene: Scene) -> Obstacle:
    if name == "height_keep_top":
        return _keep_top(ob, scene, max(ob.height_m + d, 1e-3))
    if name.startswith("side"):
        a = math.radians(ob.yaw_deg)
        axis = (np.array([math.cos(a), math.sin(a)]) if name.endswith("l")
                else np.array([-math.sin(a), math.cos(a)]))
        sign = 1.0 if name[4] == "+" else -1.0
        size = "length_m" if name.endswith("l") else "width_m"
        if getattr(ob, size) + d <= 1e-3:
            return ob
        centre = np.asarray(ob.center_m) + sign * axis * d / 2.0
        return replace(ob, center_m=tuple(round(float(c), 6) for c in centre),
                       **{size: round(getattr(ob, size) + d, 6)})
    return replace(ob, **{name: round(max(getattr(ob, name) + d, 1e-3), 6)})


def _region(ob: Obstacle, scene: Scene, shape: tuple[int, int]) -> np.ndarray:
    K, pose = cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera)
    hull = cv2.convexHull(cam.project(box_vertices(ob), K, pose).astype(np.float32))
    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [np.round(hull.reshape(-1, 2) * 16).astype(np.int32)], 1, shift=4)
    k = 2 * REGION_GROW_PX + 1
    return cv2.dilate(m, np.ones((k, k), np.uint8)).astype(bool)


def refine_boxes(scene: Scene, gray: np.ndarray, renderer, *,
                 progress: Callable[[str], None] | None = None) -> Scene:
    """``scene`` with each box moved to where its render best matches ``gray`` (mean
    absolute grey difference over the box's region, the region of its starting place and of
    each candidate together): its height scanned first (0.6 to 1.4 times the silhouette
    fit's, then within 3 %), the top face held where the camera sees it, then each move of
    :data:`FIELDS` in the steps of :data:`STEPS`."""
    target = gray.astype(np.float64)
    boxes = list(scene.obstacles)

    def render(s: Scene) -> np.ndarray:
        return cv2.cvtColor(renderer.render(s).rgb, cv2.COLOR_RGB2GRAY).astype(np.float64)

    for i, start in enumerate(scene.obstacles):
        checkpoint()
        base_region = _region(start, scene, gray.shape)

        def cost(ob: Obstacle, i=i, base_region=base_region) -> float:
            trial = list(boxes)
            trial[i] = ob
            s = replace(scene, obstacles=tuple(trial))
            region = base_region | _region(ob, scene, gray.shape)
            return float(np.abs(render(s)[region] - target[region]).mean())

        ob = boxes[i]
        best = cost(ob)
        first = best
        # the height first, scanned with the top face held (the silhouette fit can land a
        # centimetre or two off where a thin side face is all that shows it), then every move
        for lo, hi, count in ((0.6, 1.4, 41), (0.97, 1.03, 31)):
            h0 = ob.height_m
            for h in np.linspace(lo * h0, hi * h0, count):
                checkpoint()
                cand = _keep_top(ob, scene, float(h))
                c = cost(cand)
                if c < best - 1e-9:
                    best, ob = c, cand
        for share in STEPS:
            step = share * scene.arena.side_m
            for _ in range(MAX_PASSES):
                improved = False
                for name in FIELDS:
                    for d in (-step, step):
                        checkpoint()
                        cand = _moved(ob, name, d, scene)
                        c = cost(cand)
                        if c < best - 1e-9:
                            best, ob, improved = c, cand, True
                if not improved:
                    break
        boxes[i] = ob
        if progress:
            progress(f"box {i + 1}: region difference {first:.2f} -> {best:.2f} grey levels")
    return replace(scene, obstacles=tuple(boxes))
