"""``arenabench render``: render one scene file with its ground truth.

Writes ``DIR/images/000000.png``, ``DIR/gt/000000.json`` (the dataset GT schema) and
``DIR/manifest.jsonl`` (a one-image dataset ``arenabench eval DIR`` reads), atomically.
Scene files are :meth:`Scene.to_dict` JSON, e.g. the fitted
``generator/scenes/task1c_example.json`` (``arenabench fit``).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from arenabench.cliopts import CommandParser, add_out, output_problem, usage_error
from arenabench.exitcodes import ExitCode
from arenabench.generator.model.scene import Scene, load_scene

__all__ = ["load_scene", "render_scene_files", "scene_gt_record"]

def scene_gt_record(scene: Scene, *, sid: str = "000000", source: str = "scene") -> dict[str, Any]:
    """The GT record of a scene rendered on its own (same schema as dataset GT files)."""
    from arenabench.generator.dataset.make import gt_record

    return gt_record(scene, sid=sid, preset=source)


def render_scene_files(scene: Scene, out: str | Path, *, source: str = "scene") -> Path:
    """Render ``scene`` into ``out/images/000000.png`` + ``out/gt/000000.json`` and
    ``out/manifest.jsonl`` (so ``arenabench eval OUT`` scores it); returns the PNG.

    The image and the GT are both made before the first file is written: a scene whose
    ground truth cannot be computed leaves nothing.
    """
    import cv2

    from arenabench.fileio import atomic_write_bytes, atomic_write_text, dumps_json, sha256_bytes
    from arenabench.generator.dataset.dataset_writer import manifest_line
    from arenabench.generator.rendering.render import Renderer
    from arenabench.imageio import encode_png

    out = Path(out)
    gt = dumps_json(scene_gt_record(scene, source=source)).encode("utf-8")
    with Renderer() as renderer:
        rgb = renderer.render(scene).rgb
    png = encode_png(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    image = atomic_write_bytes(out / "images" / "000000.png", png)
    atomic_write_bytes(out / "gt" / "000000.json", gt)
    atomic_write_text(out / "manifest.jsonl",
                      manifest_line("000000", "png", sha256_bytes(png), sha256_bytes(gt)))
    return image


def build_parser() -> CommandParser:
    """The ``arenabench render`` argument parser."""
    p = CommandParser(
        prog="arenabench render",
        description="Render a scene file (JSON, e.g. from 'arenabench fit') with its ground "
                    "truth: DIR/images/000000.png, DIR/gt/000000.json and "
                    "DIR/manifest.jsonl ('arenabench eval DIR' scores it).",
    )
    p.add_argument("scene", help="scene file (JSON)")
    add_out(p, required=True, help="output directory")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench render``; returns 0 on success, 2 on bad input."""
    args = build_parser().parse_args(argv)
    if problem := output_problem(args.out):
        return usage_error("arenabench render", problem)
    if (Path(args.out) / "dataset.json").exists():  # its manifest would be replaced
        print(f"arenabench render: error: --out {args.out}: holds a generated dataset "
              "(dataset.json); use another folder", file=sys.stderr)
        return ExitCode.USAGE
    from arenabench.generator.dataset.gl_check import OffscreenGLError, require_offscreen_gl

    try:
        scene = load_scene(args.scene)
        require_offscreen_gl()
        image = render_scene_files(scene, args.out, source=Path(args.scene).stem)
    except (ValueError, OffscreenGLError) as exc:
        print(f"arenabench render: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    print(f"wrote {image}, {Path(args.out) / 'gt' / '000000.json'} and "
          f"{Path(args.out) / 'manifest.jsonl'} (score it: arenabench eval {args.out} "
          "--pipeline reference)", file=sys.stderr)
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
