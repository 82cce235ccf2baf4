"""How the no-texture twin's painted markers fit the image over the texel grid they are painted
on: the cost of each (texture side, texel size) pair (docs/measurements.md, "The no-texture
twin's texel grid").

The cost is the mean absolute grey difference over the four marker squares (8 px around each)
between the image and the twin's render of its fitted scene, with the markers painted into the
texture rectified from the image and no back-projection. The texel size is given relative to
the competition texture's grid (2,880 texels over the twin's floor scaled by 0.99968); the
texture is centred on the floor (extent = side x texel / 2), as Gazebo centres it::

    .venv/bin/arenabench twin tests/data/task1c_image.jpg --arena-size 3.7,3.7 --out /tmp/t
    .venv/bin/python tools/texel_grid_scan.py /tmp/t/scene.json tests/data/task1c_image.jpg \\
        --sides 2874 2888 --texel 0.998 1.002 0.0001 --procs 2 --out /tmp/scan.jsonl

writes one JSON line per pair (``n``, ``texel_rel``, ``cost``, ``s``), in a fixed random order
so that a run cut short by ``--deadline`` still covers the grid evenly. A try takes about 3 s
of one core (it rectifies the whole floor).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from multiprocessing import Pool
from pathlib import Path

import numpy as np

#: The competition texture's grid, in the example twin's terms: sides and floor scale.
COMPETITION_SIDE, COMPETITION_SCALE = 2880, 0.99968

_STATE: dict = {}


def _start(scene_path: str, image_path: str) -> None:
    """Per worker: the image, the scene, a renderer, and the boxes' pixels."""
    import cv2

    from arenabench.generator.model.scene import load_scene
    from arenabench.generator.rendering.render import Renderer

    real = cv2.imread(image_path)
    scene = load_scene(Path(scene_path))
    renderer = Renderer()
    full = renderer.render(scene).rgb.astype(np.float32)
    bare = renderer.render(replace(scene, obstacles=())).rgb.astype(np.float32)
    _STATE.update(real=real, gray=cv2.cvtColor(real, cv2.COLOR_BGR2GRAY).astype(float),
                  scene=scene, renderer=renderer, boxes=np.abs(full - bare).max(-1) > 0)


def _cost(job: tuple[int, float]) -> dict:
    from arenabench.frame import CORNER_ORDER
    from arenabench.generator.fitting import rectify
    from arenabench.generator.model import camera as cam
    from arenabench.generator.model.layout import floor_extent, marker_corners_world

    n, texel_rel = job
    base = _STATE["scene"]
    e = floor_extent(base.arena)
    scale = n * (2 * e * COMPETITION_SCALE / COMPETITION_SIDE) * texel_rel / (2 * e)
    scene = rectify.with_extent(base, e * scale)
    k, pose = cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera)
    squares = np.zeros(_STATE["gray"].shape, bool)
    for corner in CORNER_ORDER:
        c = marker_corners_world(scene.arena, scene.markers, corner)
        px = cam.project(np.c_[c, np.zeros(4)], k, pose)
        x0, y0 = np.floor(px.min(0)).astype(int) - 8
        x1, y1 = np.ceil(px.max(0)).astype(int) + 8
        squares[y0:y1, x0:x1] = True
    printed = replace(scene, markers=replace(scene.markers, printed=True, quiet_zone_m=0.0))
    t = time.perf_counter()
    rect = rectify.Rectification(_STATE["real"], printed, _STATE["boxes"], texels=n)
    cost = rectify.painted_cost(_STATE["gray"], printed, rect, squares, _STATE["renderer"])
    return {"n": n, "texel_rel": texel_rel, "scale": scale, "cost": cost,
            "s": time.perf_counter() - t}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="the twin's scene.json")
    ap.add_argument("image", help="the image the twin was built from")
    ap.add_argument("--sides", nargs=2, type=int, required=True, metavar=("FIRST", "END"))
    ap.add_argument("--texel", nargs=3, type=float, required=True,
                    metavar=("FIRST", "END", "STEP"), help="relative to the competition's")
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--deadline", type=float, default=float("inf"), help="seconds")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    texels = np.round(np.arange(*a.texel), 6)
    jobs = [(n, float(t)) for n in range(*a.sides) for t in texels]
    jobs = [jobs[i] for i in np.random.default_rng(0).permutation(len(jobs))]
    t0, done = time.monotonic(), 0
    with open(a.out, "w") as f, Pool(a.procs, _start, (a.scene, a.image)) as pool:
        for row in pool.imap_unordered(_cost, jobs):
            f.write(json.dumps(row) + "\n")
            done += 1
            print(f"\r{done}/{len(jobs)}", end="", flush=True)
            if time.monotonic() - t0 > a.deadline:
                pool.terminate()
                break
    print(f"\n{done} of {len(jobs)} pairs in {time.monotonic() - t0:.0f} s: {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
