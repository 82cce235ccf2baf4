"""Which box edges of the published example are blended, edge by edge, on the real image and on
the render of its fitted scene (docs/rendering.md, "Edge by edge").

For each edge segment (a window of the 1000 x 1000 example, found by eye on the real image):
the share of its rows (vertical edges) or columns (horizontal edges) that hold a blended pixel,
grey 131-234 between the box faces and the floor. Under the two-sample model an axis-aligned
edge is blended along its whole length or nowhere, depending on where it falls inside its
pixels; a sloped edge alternates runs of both.

    .venv/bin/python tools/edge_phases.py
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from arenabench.generator.model.scene import load_scene
from arenabench.generator.rendering.render import Renderer

ROOT = Path(__file__).resolve().parent.parent
IMAGE = ROOT / "tests" / "data" / "task1c_image.jpg"
SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"

#: (edge, "h" for a horizontal edge / "v" for a vertical one, positions along it, window
#: across it) in pixels of the example.
SEGMENTS: tuple[tuple[str, str, range, range], ...] = (
    ("box 1 north edge: top face / floor", "h", range(300, 470), range(392, 400)),
    ("box 1 east edge: top + dark face / floor", "v", range(400, 478), range(478, 488)),
    ("box 1 south contact: dark face / floor", "h", range(300, 470), range(476, 484)),
    ("box 1 west edge (sloped)", "v", range(398, 480), range(280, 300)),
    ("box 2 north edge: north face / floor", "h", range(555, 700), range(775, 784)),
    ("box 2 west contact: dark face / floor", "v", range(786, 856), range(535, 545)),
    ("box 2 west corner edge (sloped)", "v", range(857, 880), range(535, 545)),
    ("box 2 south edge: top face / floor", "h", range(560, 700), range(878, 890)),
    ("box 2 east edge (sloped)", "v", range(785, 880), range(698, 715)),
)


def blended_share(gray: np.ndarray, axis: str, along: range, across: range) -> float:
    """Share of the positions ``along`` an edge whose window ``across`` it holds a pixel of
    grey 131-234."""
    lines = gray[np.ix_(across, along)].T if axis == "h" else gray[np.ix_(along, across)]
    return float(((lines > 130) & (lines < 235)).any(axis=1).mean())


def main() -> None:
    real = cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE)
    with Renderer() as renderer:
        render = cv2.cvtColor(renderer.render(load_scene(SCENE)).rgb, cv2.COLOR_RGB2GRAY)
    print(f"{'edge':44s} {'real':>5s} {'render':>7s}")
    for name, axis, along, across in SEGMENTS:
        print(f"{name:44s} {blended_share(real, axis, along, across):5.2f} "
              f"{blended_share(render, axis, along, across):7.2f}")


if __name__ == "__main__":
    main()
