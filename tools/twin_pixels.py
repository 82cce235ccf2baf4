"""The fitted example's render against the published image, around the markers and overall
(docs/rendering.md, "Textures"): the figures of the table there, as PNG and as the twin's JPEG.

Prints the mean absolute grey difference in the marker squares (each detected marker's bounding
square grown by 8 px), over the whole image, SSIM, the four corner pixels (TL, TR, BL, BR) of
the inner-corner warp to 1000 px after a 2 px crop with that crop's Otsu threshold, and the
detection order with outline lengths.

    .venv/bin/python tools/twin_pixels.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from test_twin_fidelity import (  # noqa: E402  (the helpers the tests check these with)
    IMAGE,
    SCENE,
    _marker_squares,
    _outlines,
    _warp_corner_greys,
)

from arenabench.generator.render import Renderer  # noqa: E402
from arenabench.generator.scene import load_scene  # noqa: E402
from arenabench.generator.similarity import mean_abs_diff, ssim  # noqa: E402
from arenabench.imageio import decode_image, encode_jpeg  # noqa: E402


def figures(gray: np.ndarray, real: np.ndarray) -> str:
    """One line of figures of ``gray`` against ``real`` (both grayscale)."""
    squares = _marker_squares(real)
    mad_sq = float(np.abs(gray.astype(float) - real)[squares].mean())
    corners, otsu = _warp_corner_greys(gray)
    outlines = ", ".join(f"{i} {length:.2f}" for i, length in _outlines(gray))
    return (f"marker squares {mad_sq:.2f}  MAD {mean_abs_diff(gray, real):.3f}  "
            f"SSIM {ssim(gray, real):.4f}  corners {corners.tolist()} (Otsu {otsu:.0f})  "
            f"outlines {outlines}")


def main() -> int:
    """Print the figures for the real image, the render and the render as a JPEG."""
    real = cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE)
    with Renderer() as renderer:
        bgr = cv2.cvtColor(renderer.render(load_scene(SCENE)).rgb, cv2.COLOR_RGB2BGR)
    jpeg = decode_image(encode_jpeg(bgr, quality=95))
    print("real         ", figures(real, real))
    print("render       ", figures(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY), real))
    print("render (JPEG)", figures(cv2.cvtColor(jpeg, cv2.COLOR_BGR2GRAY), real))
    return 0


if __name__ == "__main__":
    sys.exit(main())
