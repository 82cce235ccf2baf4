"""``arenabench twin``: a twin of an arena from one real render of it.

Writes ``DIR/preset.toml`` (a preset whose scenes are hidden-test-like for that arena),
``DIR/scene.json`` (the fitted scene of the image, for ``arenabench render``),
``DIR/twin.json`` (every parameter, pinned with its residual or open with the range kept and
why) and ``DIR/report.html`` (the image, the twin's render of it and their difference, region
by region), and ``DIR/textures/<sha256>.png`` when the arena is an image (the texture given,
or one rectified from the image; both files name it so). See docs/twin-tutorial.md and
docs/commands.md.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from arenabench.cliopts import (
    CommandParser,
    add_no_progress,
    add_out,
    lock_out,
    output_problem,
    usage_error,
    write_failure,
)
from arenabench.exitcodes import ExitCode

PROG = "arenabench twin"


def build_parser() -> CommandParser:
    """The ``arenabench twin`` argument parser."""
    p = CommandParser(
        prog=PROG,
        description="Build a twin of an arena from one real render of it: the markers "
                    "(every ArUco dictionary tried), the camera (fitted, then snapped to round "
                    "values), the arena (the texture given, or one rectified from the image), "
                    "light, greys, edges and the file's JPEG settings; write DIR/preset.toml, "
                    "DIR/scene.json, DIR/twin.json (every parameter pinned or open, and why) "
                    "and DIR/report.html.",
    )
    p.add_argument("image", type=Path, help="one real render of the arena (PNG or JPEG)")
    add_out(p, required=True, help="folder to write the twin into (new, empty, or an earlier "
                                   "twin's, which is replaced)")
    p.add_argument("--texture", type=Path, default=None, metavar="ARENA.png",
                   help="the arena's texture image (its markers printed on it); needs "
                        "--arena-size")
    p.add_argument("--arena-size", default=None, metavar="W,H",
                   help="the arena floor's size in metres: the area ARENA.png covers, or "
                        "without --texture the floor the image shows out to its edge "
                        "(without it the scale is open: the generator's default arena)")
    p.add_argument("--name", default=None,
                   help="the preset's name (default: twin-IMAGE-STEM)")
    p.add_argument("--accept-poor-fit", action="store_true",
                   help="exit 0 with a twin whose verdict is poor (its render outside the "
                        "bounds the blind round trips hold); without it such a twin is written "
                        "and the exit status is 6")
    add_no_progress(p)
    return p


def _size(text: str) -> tuple[float, float]:
    parts = text.split(",")
    try:
        w, h = (float(v) for v in parts)
    except ValueError:
        raise ValueError(f"--arena-size {text}: expected W,H in metres (two numbers), e.g. "
                         "3.7,3.7") from None
    if not all(math.isfinite(v) and v > 0 for v in (w, h)):
        raise ValueError(f"--arena-size {text}: both sides must be finite and > 0")
    if abs(w - h) > 0.01 * max(w, h):
        raise ValueError(f"--arena-size {text}: the generator's arenas are square")
    return w, h


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench twin``; 0 on success, 2 on bad input (one line, before any work),
    6 for a twin whose fit is poor (written; 0 with ``--accept-poor-fit``), 130 / 143 when
    stopped (nothing is written; an earlier twin in DIR is kept)."""
    args = build_parser().parse_args(argv)
    problem, size, name = _inputs(args)
    if problem:
        return usage_error(PROG, problem)
    from arenabench.generator.fitting.writer import TWIN_FILES

    if problem := output_problem(args.out, own=TWIN_FILES, what="twin"):
        return usage_error(PROG, problem)
    from arenabench.fileio import FolderLockedError
    from arenabench.generator.dataset.gl_check import OffscreenGLError, require_offscreen_gl
    from arenabench.generator.fitting.build import TwinOptions, build_twin
    from arenabench.generator.fitting.writer import write_twin
    from arenabench.interrupts import Interrupted, stop_on_signals

    try:
        require_offscreen_gl()
    except OffscreenGLError as exc:
        return usage_error(PROG, str(exc))
    show = not args.no_progress

    def progress(line: str) -> None:
        if show:
            print(f"twin: {line}", file=sys.stderr, flush=True)

    with stop_on_signals():
        try:
            with lock_out(args.out):
                twin = build_twin(args.image, TwinOptions(texture=args.texture,
                                                          arena_size_m=size, name=name),
                                  progress=progress)
                written = write_twin(args.out, twin, name=name)
        except FolderLockedError as exc:
            return usage_error(PROG, str(exc))
        except ValueError as exc:  # about the image's content, the texture or the size
            why = str(exc).removeprefix("image: ")
            where = "" if why.startswith("--") else f"{args.image}: "
            print(f"{PROG}: error: {where}{why}", file=sys.stderr)
            return ExitCode.USAGE
        except Interrupted as exc:
            print(f"{PROG}: {exc}; nothing written (an earlier twin in {args.out} is kept)",
                  file=sys.stderr)
            return exc.exit_code
        except OSError as exc:
            print(f"{PROG}: error: {write_failure(exc, args.out)}", file=sys.stderr)
            return ExitCode.FAILED
    return _said(args, twin, name, written)


def _inputs(args) -> tuple[str | None, tuple[float, float] | None, str]:
    """(what is wrong with the inputs or None, the arena's size, the preset's name), before
    any work."""
    from arenabench.generator.parameters.preset_files import NAME_RE
    from arenabench.imageio import image_file_problem

    name = args.name or f"twin-{args.image.stem}"
    if problem := image_file_problem(args.image):
        return f"{args.image}: {problem}", None, name
    if args.texture is not None:
        if problem := image_file_problem(args.texture):
            return f"--texture {args.texture}: {problem}", None, name
        if args.arena_size is None:
            return ("--texture needs --arena-size W,H (the metres the texture covers)", None,
                    name)
    try:
        size = None if args.arena_size is None else _size(args.arena_size)
    except ValueError as exc:
        return str(exc), None, name
    if not NAME_RE.fullmatch(name):
        return (f"--name {name!r}: 1 to 64 letters, digits, '.', '_' or '-', starting with a "
                "letter or digit"), None, name
    return None, size, name


def _said(args, twin, name: str, written) -> int:
    """The twin's lines (its verdict first) and exit status."""
    from arenabench.generator.fitting.build import records_text
    from arenabench.generator.fitting.markers import detector_offset_text

    print(f"twin {name}: {twin.verdict.line()}")
    f = twin.figures
    print(f"twin {name}: marker squares {f.mad['markers']:.2f} grey levels from the image, "
          f"whole image {f.whole:.2f}, the default detector's corners "
          f"{detector_offset_text(f.detector_px)}; parameters: {records_text(twin.records)}")
    print(f"wrote {', '.join(str(p) for p in written)}")
    print(f"generate from it: arenabench generate --preset {args.out / 'preset.toml'} "
          f"--count 200 --out SET")
    if not twin.verdict.good and not args.accept_poor_fit:
        print(f"{PROG}: the twin's fit is poor (written; its preset is a guess at this arena "
              "that scripts should not be held to): --accept-poor-fit to exit 0",
              file=sys.stderr)
        return ExitCode.POOR_FIT
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
