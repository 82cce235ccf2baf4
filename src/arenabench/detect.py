"""``arenabench detect`` (also ``python -m arenabench.detect``): competition-compatible I/O.

Runs the pipeline on ``--image PATH`` and writes ``obstacles.txt`` in the competition's exact
format to the working directory (or ``--output FILE``; ``-`` is standard output, and an
existing device or FIFO such as ``/dev/stdout`` is written through, never replaced);
``--json`` also prints the Detection on stdout as one compact JSON line (``--indent N`` for
people, ``--contours`` to include the obstacle contours). Drops into any place a team's
``map.py --image PATH`` would run.

stdout carries only the ``--json`` line (or the competition output with ``--output -``); one
human line on stderr says where ``obstacles.txt`` went and what it holds.

Exit status: 0 ok; 2 bad input or usage (one line on stderr, ``arenabench detect: error:
...``); 3 markers not found (``obstacles.txt`` is still written, with the ids found, count 0
and area 0.0, so graders can parse it).
"""

from __future__ import annotations

import sys

from arenabench.cliopts import CommandParser, output_problem, usage_error
from arenabench.competition import (
    OBSTACLES_FILE,
    format_obstacles_txt,
)
from arenabench.exitcodes import ExitCode
from arenabench.fileio import write_output_text
from arenabench.frame import FrameSpec
from arenabench.pipeline.config import PROFILES

PROG = "arenabench detect"


def build_parser() -> CommandParser:
    """The command's argument parser."""
    p = CommandParser(
        prog=PROG,
        description="Detect the arena markers and obstacles in one overhead image and write "
        "obstacles.txt in the competition's format.",
    )
    p.add_argument("--image", required=True, help="input image (PNG, JPEG, ...)")
    p.add_argument("--output", default=OBSTACLES_FILE, metavar="FILE",
                   help="where to write the competition output (default: ./obstacles.txt; "
                        "'-' is standard output)")
    p.add_argument("--json", action="store_true",
                   help="also print the Detection on stdout as one compact JSON line (what "
                        "'arenabench eval --output json' reads)")
    p.add_argument("--indent", type=int, default=None, metavar="N",
                   help="with --json: indent the JSON by N spaces (default: one line)")
    p.add_argument("--contours", action="store_true",
                   help="with --json: include each obstacle's contour points (frame px)")
    p.add_argument("--profile", choices=PROFILES, default="reference",
                   help="reference (default): the sound method; seed: as published")
    p.add_argument("--threshold", type=int, default=70,
                   help="global threshold before the marker search (default 70)")
    p.add_argument("--min-area", type=float, default=500.0,
                   help="contours larger than this (frame px^2) count (default 500)")
    p.add_argument("--corners", choices=("inner", "outer"), default="inner",
                   help="marker corners mapped to the frame corners (default inner)")
    p.add_argument("--frame-size", type=int, default=1000,
                   help="side of the rectified frame in px (default 1000)")
    p.add_argument("--obstacle-threshold", type=int, default=None,
                   help="reference: fixed colour distance from the floor (default: automatic)")
    p.add_argument("--area-method", choices=("contour", "pixels"), default="contour",
                   help="obstacle area: cv2.contourArea (default) or pixel count")
    return p


def _error(message: str) -> int:
    return usage_error(PROG, message)


def main(argv: list[str] | None = None) -> int:
    """Run the command; return its exit status."""
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args

    if args.indent is not None and args.indent < 0:
        return _error(f"--indent must be >= 0, got {args.indent}")

    from arenabench.imageio import ImageLoadError, load_image
    from arenabench.pipeline import DetectConfig, detect

    try:
        config = DetectConfig(
            profile=args.profile,
            threshold=args.threshold,
            min_area=args.min_area,
            frame=FrameSpec(size=args.frame_size, corners=args.corners),
            obstacle_threshold=args.obstacle_threshold,
            area_method=args.area_method,
        )
    except ValueError as exc:
        return _error(str(exc))
    if args.output != "-" and (problem := output_problem(
            args.output, option="--output", file=True, allow_special=True)):
        return _error(problem)
    try:
        image = load_image(args.image)
    except ImageLoadError as exc:
        return _error(str(exc))
    try:
        result = detect(image, config)
    except ValueError as exc:
        return _error(str(exc))
    text = format_obstacles_txt(result.marker_ids, result.count, result.total_area)
    try:
        write_output_text(args.output, text)
    except BrokenPipeError:
        raise  # the reader went away: arenabench.cli.run exits quietly with 141
    except OSError as exc:
        return _error(f"cannot write {args.output}: {exc.strerror or exc}")
    if args.json:
        print(result.to_json(indent=args.indent, contours=args.contours), flush=True)
    print(f"{PROG}: wrote {args.output}: marker ids {list(result.marker_ids)}, "
          f"{result.count} obstacles, area {result.total_area:.1f} px^2", file=sys.stderr)
    if not result.ok:
        print(f"{PROG}: markers not found: {result.message}", file=sys.stderr)
        return ExitCode.MARKERS_NOT_FOUND
    return ExitCode.OK


if __name__ == "__main__":
    from arenabench.cli import run

    raise SystemExit(run(main))
