"""The tutorial's pictures (docs/twin-tutorial.md) from a real twin: the image, the twin's
render of the same scene (written as the image was), their difference, and one marker of each
zoomed, into docs/images/PREFIX-*.png::

    .venv/bin/arenabench twin tests/data/task1c_image.jpg --out /tmp/example-twin \
        --texture generator/assets/arena_texture.png --arena-size 3.7,3.7
    .venv/bin/python tools/twin_docs_images.py tests/data/task1c_image.jpg /tmp/example-twin
    .venv/bin/arenabench twin tests/data/task1c_image.jpg --out /tmp/example-own \
        --arena-size 3.7,3.7
    .venv/bin/python tools/twin_docs_images.py tests/data/task1c_image.jpg /tmp/example-own \
        --prefix twin-own
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from arenabench.generator.fitting.image_file import as_written, read_file_facts
from arenabench.generator.fitting.markers import find_markers
from arenabench.generator.fitting.regions import difference_image, marker_squares
from arenabench.generator.model.scene import load_scene
from arenabench.generator.rendering.render import Renderer
from arenabench.imageio import decode_image

OUT = Path(__file__).resolve().parent.parent / "docs" / "images"
#: Width (px) of the whole-image pictures, and zoom of the marker crops.
WHOLE_PX, ZOOM = 400, 3


def _write(name: str, img: np.ndarray) -> None:
    path = OUT / name
    cv2.imwrite(str(path), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"docs/images/{name}: {path.stat().st_size // 1024} KB")


def main(argv: list[str] | None = None) -> int:
    """Write the pictures."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("image", type=Path, help="the image the twin was made from")
    p.add_argument("twin", type=Path, help="the twin's folder (arenabench twin --out)")
    p.add_argument("--prefix", default="twin", help="file names' prefix (default twin)")
    args = p.parse_args(argv)
    data = args.image.read_bytes()
    real = decode_image(data, name=str(args.image))
    scene = load_scene(args.twin / "scene.json")
    with Renderer() as renderer:
        render = cv2.cvtColor(renderer.render(scene).rgb, cv2.COLOR_RGB2BGR)
    render = as_written(render, read_file_facts(data))
    rg, tg = (cv2.cvtColor(i, cv2.COLOR_BGR2GRAY) for i in (real, render))
    diff = difference_image(tg, rg)
    small = (WHOLE_PX, round(real.shape[0] * WHOLE_PX / real.shape[1]))
    OUT.mkdir(parents=True, exist_ok=True)
    for name, img in ((f"{args.prefix}-example.png", rg), (f"{args.prefix}-render.png", tg),
                      (f"{args.prefix}-difference.png", diff)):
        _write(name, cv2.resize(img, small, interpolation=cv2.INTER_AREA))
    # one marker (the first found) zoomed: image, twin, difference side by side
    square = next(iter(marker_squares(find_markers(rg), rg.shape).values()))
    ys, xs = np.nonzero(square)
    crop = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
    tiles = [cv2.cvtColor(rg[crop], cv2.COLOR_GRAY2BGR), cv2.cvtColor(tg[crop],
                                                                      cv2.COLOR_GRAY2BGR),
             diff[crop]]
    gap = np.full((tiles[0].shape[0], 2, 3), 255, np.uint8)
    row = np.hstack([tiles[0], gap, tiles[1], gap, tiles[2]])
    _write(f"{args.prefix}-marker.png", cv2.resize(row, None, fx=ZOOM, fy=ZOOM,
                                         interpolation=cv2.INTER_NEAREST))
    figures = json.loads((args.twin / "twin.json").read_text())["figures"]
    print(f"marker squares {figures['mad']['markers']:.2f} grey levels, whole image "
          f"{figures['whole']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
