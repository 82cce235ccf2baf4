"""Regenerate the README's images in docs/images/ (``make docs-images``).

Contact sheets of the first 16 scenes (seed 0) of every preset, and ``presets.jpg``: scene 1
of each preset side by side. Every image is a function of the generator version, so rerun this
whenever GENERATOR_VERSION changes.
"""

from __future__ import annotations

from pathlib import Path

import cv2

from arenabench.generator.commands.contact_sheet import render_sheet, tile_images
from arenabench.generator.dataset.make import make_sample
from arenabench.generator.parameters.presets import PRESETS
from arenabench.generator.rendering.render import Renderer

OUT = Path(__file__).resolve().parent.parent / "docs" / "images"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    firsts, captions = [], []
    with Renderer() as renderer:
        for preset in PRESETS:
            firsts.append(make_sample(preset, seed=0, index=1, renderer=renderer).bgr)
            captions.append(preset)
    cv2.imwrite(str(OUT / "presets.jpg"), tile_images(firsts, captions, columns=len(firsts),
                                                      tile=256),
                [cv2.IMWRITE_JPEG_QUALITY, 85])
    for preset in PRESETS:
        sheet = render_sheet(preset, count=16, seed=0)
        cv2.imwrite(str(OUT / f"contact-{preset}.jpg"), sheet, [cv2.IMWRITE_JPEG_QUALITY, 85])
        print(f"docs/images/contact-{preset}.jpg")


if __name__ == "__main__":
    main()
