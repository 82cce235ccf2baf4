"""``arenabench contact-sheet``: a grid of a preset's scenes, to see what a preset looks like.

Each tile is one scene rendered exactly as ``arenabench generate`` would render it (same seed,
same index), captioned with its id and ground-truth count and visible area.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from arenabench.cliopts import (
    CommandParser,
    add_count,
    add_no_progress,
    add_out,
    add_preset,
    add_seed,
    add_set,
    output_problem,
    usage_error,
)
from arenabench.exitcodes import ExitCode
from arenabench.fileio import atomic_write_bytes
from arenabench.generator.parameters.presets import DEFAULT_PRESET, preset_names, resolve_preset
from arenabench.limits import MAX_IMAGE_SIDE_PX, check_at_most

#: Padding around a tile and height of its caption strip, in px.
_PAD, _TEXT_H = 6, 22


def tile_images(
    images: list[np.ndarray], captions: list[str], *, columns: int = 4, tile: int = 320
) -> np.ndarray:
    """Tile BGR images into a captioned grid.

    Parameters
    ----------
    images : list of numpy.ndarray
        BGR uint8 images of any size (each is resized to fit a ``tile`` x ``tile`` square,
        keeping its aspect).
    captions : list of str
        One caption per image, drawn under it.
    columns : int, keyword-only
        Tiles per row.
    tile : int, keyword-only
        Side of a tile's image area in px.

    Returns
    -------
    numpy.ndarray
        The sheet, BGR uint8.

    Raises
    ------
    ValueError
        When the lists differ in length, are empty, or ``columns``/``tile`` are not positive.
    """
    if not images or len(images) != len(captions):
        raise ValueError(
            f"images and captions must be non-empty and of equal length, got {len(images)} "
            f"and {len(captions)}"
        )
    width, height = sheet_size(len(images), columns=columns, tile=tile)
    pad, text_h = _PAD, _TEXT_H
    cell_w, cell_h = tile + 2 * pad, tile + text_h + 2 * pad
    sheet = np.full((height, width, 3), 255, np.uint8)
    for k, (img, caption) in enumerate(zip(images, captions, strict=True)):
        h, w = img.shape[:2]
        scale = tile / max(h, w)
        small = cv2.resize(img, (max(1, round(w * scale)), max(1, round(h * scale))),
                           interpolation=cv2.INTER_AREA)
        r, c = divmod(k, columns)
        y0, x0 = r * cell_h + pad, c * cell_w + pad
        sheet[y0:y0 + small.shape[0], x0:x0 + small.shape[1]] = small
        cv2.putText(sheet, caption, (x0, y0 + tile + text_h - 6), cv2.FONT_HERSHEY_SIMPLEX,
                    0.45, (40, 40, 40), 1, cv2.LINE_AA)
    return sheet


def sheet_size(count: int, *, columns: int, tile: int) -> tuple[int, int]:
    """Width and height in px of a sheet of ``count`` tiles.

    Raises
    ------
    ValueError
        When ``count``, ``columns`` or ``tile`` are out of range, or the sheet would be wider
        or taller than :data:`arenabench.limits.MAX_IMAGE_SIDE_PX`.
    """
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    if columns < 1 or tile < 16:
        raise ValueError(f"columns must be >= 1 and tile >= 16, got {columns} and {tile}")
    check_at_most(tile, MAX_IMAGE_SIDE_PX, "tile")
    rows = -(-count // columns)
    width = columns * (tile + 2 * _PAD)
    height = rows * (tile + _TEXT_H + 2 * _PAD)
    check_at_most(width, MAX_IMAGE_SIDE_PX, f"sheet width ({columns} columns x tile {tile})")
    check_at_most(height, MAX_IMAGE_SIDE_PX, f"sheet height ({rows} rows x tile {tile})")
    return width, height


def render_sheet(preset: Any, *, count: int = 16, seed: int = 0,
                 overrides: dict | None = None, columns: int = 4, tile: int = 320,
                 progress: bool = False) -> np.ndarray:
    """Render scenes ``0..count-1`` of ``preset`` with ``seed`` and tile them.

    Parameters
    ----------
    preset : str or ResolvedPreset
        Preset name, or a preset file's
        :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`.
    count, seed : int, keyword-only
        Scenes to render and the run seed (scene i is scene i of ``arenabench generate``).
    overrides : dict, keyword-only
        Parsed ``--set`` values.
    columns, tile : int, keyword-only
        Layout, see :func:`tile_images`.
    progress : bool, keyword-only
        Show progress on stderr (:mod:`arenabench.progress`).

    Returns
    -------
    numpy.ndarray
        The sheet, BGR uint8.
    """
    sheet_size(count, columns=columns, tile=tile)  # refuse before rendering anything
    from arenabench import glplatform

    glplatform.configure()
    from arenabench.generator.dataset.make import make_sample
    from arenabench.generator.rendering.render import Renderer
    from arenabench.progress import progress as progress_bar

    images, captions = [], []
    with Renderer() as renderer, progress_bar(count, desc="contact-sheet",
                                              enabled=progress) as bar:
        for index in range(count):
            s = make_sample(preset, seed=seed, index=index, overrides=overrides,
                            renderer=renderer)
            images.append(s.bgr)
            captions.append(
                f"{s.id}  count {s.gt['count']}  area {s.gt['area']['visible_px']:.0f}"
            )
            bar.update(1)
    return tile_images(images, captions, columns=columns, tile=tile)


def build_parser() -> CommandParser:
    """The ``arenabench contact-sheet`` argument parser."""
    p = CommandParser(
        prog="arenabench contact-sheet",
        description="Render the first COUNT scenes of a preset and tile them into one image.",
    )
    add_preset(p, resolve=resolve_preset, default=DEFAULT_PRESET, names=preset_names())
    add_count(p, default=16, help="scenes")
    add_seed(p, help="run seed")
    add_set(p)
    p.add_argument("--columns", type=int, default=4, help="tiles per row (default 4)")
    p.add_argument("--tile", type=int, default=320, help="tile side in px (default 320)")
    add_out(p, help="output image (.jpg or .png; default contact-PRESET.jpg)")
    add_no_progress(p)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench contact-sheet``; returns 0, or 2 on a usage error."""
    args = build_parser().parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, its line printed)
        return args
    from arenabench.generator.model.sampler import SamplingError
    from arenabench.generator.parameters.param_values import parse_overrides

    out = args.out or Path(f"contact-{args.preset.name}.jpg")
    if out.suffix.lower() not in (".jpg", ".jpeg", ".png"):
        print(f"arenabench contact-sheet: error: --out must end in .jpg or .png, got {out}",
              file=sys.stderr)
        return ExitCode.USAGE
    if problem := output_problem(out, file=True):
        return usage_error("arenabench contact-sheet", problem)
    from arenabench.generator.dataset.gl_check import OffscreenGLError, require_offscreen_gl

    try:
        overrides = parse_overrides(args.overrides)
        require_offscreen_gl()
        sheet = render_sheet(args.preset, count=args.count, seed=args.seed,
                             overrides=overrides, columns=args.columns,
                             tile=args.tile, progress=not args.no_progress)
    except (SamplingError, ValueError, OffscreenGLError) as exc:
        print(f"arenabench contact-sheet: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    params = [cv2.IMWRITE_JPEG_QUALITY, 85] if out.suffix.lower() != ".png" else []
    ok, buf = cv2.imencode(out.suffix.lower(), sheet, params)
    if not ok:  # pragma: no cover - OpenCV failure
        print("arenabench contact-sheet: error: image encoding failed", file=sys.stderr)
        return ExitCode.USAGE
    atomic_write_bytes(out, buf.tobytes())
    print(f"contact sheet of {args.count} {args.preset.name} scenes (seed {args.seed}): {out}")
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
