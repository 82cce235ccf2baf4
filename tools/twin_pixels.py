"""The fitted example's render against the published image, around the markers and overall
(docs/rendering.md, "Textures" and "The camera"): the figures of the tables there, as PNG and as
the twin's JPEG.

Prints the mean absolute grey difference in the marker squares (each detected marker's bounding
square grown by 8 px; the union, then per marker), over the whole image, SSIM, the four corner
pixels (TL, TR, BL, BR) of the inner-corner warp to 1000 px after a 2 px crop with that crop's
Otsu threshold, and the detection order with outline lengths.

With ``--align``, it also splits each marker square's difference into a geometric and a
photometric part: the image translation and scale (about the square's centre) that bring the
render's square closest to the real one, found by re-rendering with the camera's principal
point and focal length moved (no resampling of either image), the difference left once aligned,
and on the aligned squares the black and white levels and the share of pixels between them
(edge blur). A geometric residual shows as a shift of a tenth of a pixel or more and an aligned
difference far below the unaligned one.

    .venv/bin/python tools/twin_pixels.py [--align] [--scene SCENE.json]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "tests" / "generator"))  # test_twin_fidelity
sys.path.insert(0, str(ROOT / "tests" / "pipelines"))  # competition_style, for the corners

from test_twin_fidelity import (  # noqa: E402  (the helpers the tests check these with)
    IMAGE,
    SCENE,
    _marker_squares,
    _marker_squares_by_id,
    _outlines,
    _warp_corner_greys,
)

from arenabench.generator.fitting.similarity import mean_abs_diff, ssim  # noqa: E402
from arenabench.generator.model import camera as cam  # noqa: E402
from arenabench.generator.model.scene import Scene, load_scene  # noqa: E402
from arenabench.generator.rendering.render import Renderer  # noqa: E402
from arenabench.imageio import decode_image, encode_jpeg  # noqa: E402

#: Search steps of the alignment: image px for the shift, relative for the scale.
SHIFT_STEPS_PX = (0.2, 0.1, 0.05, 0.025, 0.0125)
SCALE_PER_PX = 0.02


def figures(gray: np.ndarray, real: np.ndarray) -> str:
    """One line of figures of ``gray`` against ``real`` (both grayscale)."""
    squares = _marker_squares(real)
    diff = np.abs(gray.astype(float) - real)
    per = ", ".join(f"{i} {diff[sq].mean():.2f}"
                    for i, sq in sorted(_marker_squares_by_id(real).items()))
    corners, otsu = _warp_corner_greys(gray)
    outlines = ", ".join(f"{i} {length:.2f}" for i, length in _outlines(gray))
    return (f"marker squares {diff[squares].mean():.2f} ({per})  MAD "
            f"{mean_abs_diff(gray, real):.3f}  SSIM {ssim(gray, real):.4f}  corners "
            f"{corners.tolist()} (Otsu {otsu:.0f})  outlines {outlines}")


def _render_gray(renderer: Renderer, scene: Scene, *, jpeg: bool) -> np.ndarray:
    bgr = cv2.cvtColor(renderer.render(scene).rgb, cv2.COLOR_RGB2BGR)
    if jpeg:
        bgr = decode_image(encode_jpeg(bgr, quality=95))
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)


def _moved(scene: Scene, shift: np.ndarray, scale: float, centre: np.ndarray) -> Scene:
    """``scene`` whose image is scaled by ``scale`` about ``centre`` (px), then shifted."""
    K = cam.intrinsics(scene.camera)
    d = shift - (scale - 1.0) * (centre - K[:2, 2])
    K[0, 0] *= scale
    K[1, 1] *= scale
    K[:2, 2] += d
    return replace(scene, camera=replace(scene.camera, K=tuple(map(tuple, K))))


def _levels(patch: np.ndarray) -> tuple[float, float, float]:
    """Black level, white level (means of the pixels within 20 % of each end) and the share of
    pixels between 10 % and 90 % of the way from black to white."""
    lo, hi = np.percentile(patch, 2), np.percentile(patch, 98)
    span = max(hi - lo, 1.0)
    black = patch[patch < lo + 0.2 * span].mean()
    white = patch[patch > hi - 0.2 * span].mean()
    mid = ((patch > black + 0.1 * (white - black)) & (patch < white - 0.1 * (white - black)))
    return float(black), float(white), float(mid.mean())


def align(scene: Scene, real: np.ndarray, renderer: Renderer, *, jpeg: bool) -> list[str]:
    """Per marker square: the geometric and photometric parts of the difference (lines)."""
    lines = []
    for marker_id, square in sorted(_marker_squares_by_id(real).items()):
        ys, xs = np.nonzero(square)
        centre = np.array([(xs.min() + xs.max()) / 2.0, (ys.min() + ys.max()) / 2.0])

        def cost(p: np.ndarray, _sq=square, _c=centre) -> float:
            gray = _render_gray(renderer, _moved(scene, p[:2], p[2], _c), jpeg=jpeg)
            return float(np.abs(gray.astype(float) - real)[_sq].mean())

        p = np.array([0.0, 0.0, 1.0])
        before = best = cost(p)
        for step in SHIFT_STEPS_PX:  # coordinate search, each step until nothing improves
            improved = True
            while improved:
                improved = False
                for k, size in ((0, step), (1, step), (2, step * SCALE_PER_PX)):
                    for sign in (-1.0, 1.0):
                        q = p.copy()
                        q[k] += sign * size
                        c = cost(q)
                        if c < best:
                            best, p, improved = c, q, True
        gray = _render_gray(renderer, _moved(scene, p[:2], p[2], centre), jpeg=jpeg)
        rb, rw, rm = _levels(gray[square].astype(float))
        tb, tw, tm = _levels(real[square].astype(float))
        lines.append(
            f"  {marker_id}: {before:.2f} -> aligned {best:.2f}  shift ({p[0]:+.3f}, "
            f"{p[1]:+.3f}) px  scale {p[2]:.5f}  black {rb:.1f} / real {tb:.1f}  white "
            f"{rw:.1f} / {tw:.1f}  between {rm:.3f} / {tm:.3f}")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Print the figures for the real image, the render and the render as a JPEG."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=str(SCENE), help="scene file (default: the example's)")
    p.add_argument("--align", action="store_true",
                   help="also split each marker square's difference into geometry and photometry "
                        "(about 150 renders)")
    args = p.parse_args(argv)
    real = cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE)
    scene = load_scene(args.scene)
    with Renderer() as renderer:
        bgr = cv2.cvtColor(renderer.render(scene).rgb, cv2.COLOR_RGB2BGR)
        jpeg = decode_image(encode_jpeg(bgr, quality=95))
        print("real         ", figures(real, real))
        print("render       ", figures(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY), real))
        print("render (JPEG)", figures(cv2.cvtColor(jpeg, cv2.COLOR_BGR2GRAY), real))
        if args.align:
            print("marker squares aligned (render as JPEG; shift and scale of the render's "
                  "image that fit the real one best):")
            print("\n".join(align(scene, real, renderer, jpeg=True)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
