"""How far the markers may move before a competition style's count on ``eyrc`` changes: the
camera raised by a few hundredths of a millimetre (package units, as ``eyrc`` states its
altitude), the largest move of a marker corner in the image (px) that gives, and the pass
count of one style on N scenes at each (``tests/pipelines/pass_rates.py``).

"Otsu every contour" thresholds the warped frame with Otsu's threshold and counts every
contour, so on scenes with a single box (threshold about 184) one pixel of the warp's corner,
on a marker's inner corner, decides whether a speck is counted (docs/measurements.md)::

    PYTHONPATH=tests/pipelines .venv/bin/python tools/marker_knife_edge.py --count 200
    PYTHONPATH=tests/pipelines .venv/bin/python tools/marker_knife_edge.py --twin DIR ...

``--twin DIR`` (repeatable) also prints how far each twin's marker corners lie from
``eyrc``'s (``DIR/scene.json``, as ``arenabench twin`` writes it).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

#: Camera moves tried (mm, up).
MOVES_MM = (0.0, 0.05, -0.05, 0.1)
#: The style scored.
STYLE = "style_otsu_every_contour:detect"


def corners_px(scene) -> np.ndarray:
    """Image px of the 16 marker corners (:func:`~arenabench.generator.fitting.camera_fit.
    world_corners`' order), (16, 2)."""
    from arenabench.generator.fitting.camera_fit import world_corners
    from arenabench.generator.model import camera as cam

    return cam.project(world_corners(scene.arena, scene.markers),
                       cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera))


def main(argv: list[str] | None = None) -> int:
    """Print the corner moves and the style's counts."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--count", type=int, default=200, help="scenes of eyrc (seed 0)")
    p.add_argument("--twin", type=Path, action="append", default=[],
                   help="a twin's folder: its marker corners against eyrc's")
    args = p.parse_args(argv)
    if args.count < 1:
        print(f"--count must be >= 1, got {args.count}", file=sys.stderr)
        return 2
    for d in args.twin:
        if not (d / "scene.json").is_file():
            print(f"--twin {d}: no scene.json there", file=sys.stderr)
            return 2
    try:
        from pass_rates import score_preset
    except ImportError:
        print("needs tests/pipelines on PYTHONPATH (see --help)", file=sys.stderr)
        return 2
    from arenabench.generator.model.sampler import sample_scene
    from arenabench.generator.model.scene import load_scene

    eyrc = sample_scene("eyrc", seed=0, index=0).scene
    base = corners_px(eyrc)
    for d in args.twin:
        off = np.abs(corners_px(load_scene(d / "scene.json")) - base).max()
        print(f"twin {d}: marker corners within {off:.4f} px of eyrc's")
    altitude = eyrc.camera.altitude_m
    print(f"| camera raised (mm) | largest corner move (px) | {STYLE.removesuffix(':detect')} "
          f"passes of {args.count} |\n|---|---|---|")
    for mm in MOVES_MM:
        moved = replace(eyrc, camera=replace(eyrc.camera, altitude_m=altitude + mm / 1000.0))
        off = np.abs(corners_px(moved) - base).max()
        tally = score_preset("eyrc", count=args.count, seed=0, pipelines=(STYLE,),
                             references=("visible",),
                             overrides={"camera.altitude_m": altitude + mm / 1000.0})
        print(f"| {mm:+.2f} | {off:.4f} | {tally[STYLE].passed.get('visible', 0)} |",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
