"""``arenabench render``: render one scene file with its ground truth.

Writes ``DIR/images/000000.png`` and ``DIR/gt/000000.json`` (the dataset GT schema),
atomically. Scene files are :meth:`Scene.to_dict` JSON, e.g. the fitted
``generator/scenes/task1c_example.json`` (``arenabench fit``).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from arenabench.cliopts import CommandParser, add_out
from arenabench.generator.scene import Scene, load_scene

__all__ = ["load_scene", "render_scene_files", "scene_gt_record"]

def scene_gt_record(scene: Scene, *, sid: str = "000000", source: str = "scene") -> dict[str, Any]:
    """The GT record of a scene rendered on its own (same schema as dataset GT files)."""
    from arenabench.generator.sample import gt_record

    return gt_record(scene, sid=sid, preset=source)


def render_scene_files(scene: Scene, out: str | Path, *, source: str = "scene") -> Path:
    """Render ``scene`` into ``out/images/000000.png`` + ``out/gt/000000.json``; returns the PNG."""
    import cv2

    from arenabench.fileio import atomic_write_bytes, atomic_write_json
    from arenabench.generator.render import Renderer
    from arenabench.imageio import encode_png

    out = Path(out)
    with Renderer() as renderer:
        rgb = renderer.render(scene).rgb
    png = encode_png(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    image = atomic_write_bytes(out / "images" / "000000.png", png)
    atomic_write_json(out / "gt" / "000000.json", scene_gt_record(scene, source=source))
    return image


def build_parser() -> CommandParser:
    """The ``arenabench render`` argument parser."""
    p = CommandParser(
        prog="arenabench render",
        description="Render a scene file (JSON, e.g. from 'arenabench fit') with its ground "
                    "truth: DIR/images/000000.png and DIR/gt/000000.json.",
    )
    p.add_argument("scene", help="scene file (JSON)")
    add_out(p, required=True, help="output directory")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench render``; returns 0 on success, 2 on bad input."""
    args = build_parser().parse_args(argv)
    from arenabench.fileio import OutputPathError, check_output_dir

    try:
        check_output_dir(args.out)
    except OutputPathError as exc:
        print(f"arenabench render: error: --out {args.out}: {exc}", file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene)
        image = render_scene_files(scene, args.out, source=Path(args.scene).stem)
    except ValueError as exc:
        print(f"arenabench render: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {image} and {Path(args.out) / 'gt' / '000000.json'}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
