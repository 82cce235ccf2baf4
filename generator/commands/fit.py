"""``arenabench fit``: fit a scene file to a real overhead image of the arena."""

from __future__ import annotations

import sys

from arenabench.cliopts import CommandParser, add_count, add_out, output_problem, usage_error
from arenabench.exitcodes import ExitCode
from arenabench.limits import MAX_REFINE_ROUNDS


def build_parser() -> CommandParser:
    """The ``arenabench fit`` argument parser."""
    p = CommandParser(
        prog="arenabench fit",
        description="Fit a scene (camera, boxes, colours, lighting) to IMAGE and write it as "
                    "a scene file for 'arenabench render'. The arena is the competition's own "
                    "texture (3.33 m between the markers' outer corners, DICT_4X4_100 ids "
                    "80/85/90/95 rotated 180 deg, 0.2268 m) seen by the camera that rendered "
                    "the competition's example (1000 x 1000 px; --fit-camera, or an image of "
                    "another size, fits one to the markers); with "
                    "--arena-side a procedural arena of that side, the camera and the marker "
                    "size fitted.",
    )
    p.add_argument("image", help="overhead image of the arena (PNG/JPEG)")
    add_out(p, required=True, help="scene file to write (JSON)")
    p.add_argument("--arena-side", type=float, default=None,
                   help="fit a procedural arena with this border square side in m instead of "
                        "the competition texture")
    p.add_argument("--fit-camera", action="store_true",
                   help="fit the camera to the four markers (field of view held at the "
                        "example camera's) instead of taking the camera that rendered the "
                        "competition's example (competition texture only)")
    add_count(p, "--refine-rounds", default=1, minimum=0, maximum=MAX_REFINE_ROUNDS,
              help="SSIM refinement rounds of the margin and border width")
    p.add_argument("--report", action="store_true",
                   help="also print the fit as JSON (fov, reprojection error, SSIM, MAD)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench fit``; returns 0 on success, 2 on bad input."""
    args = build_parser().parse_args(argv)
    from arenabench.fileio import (
        atomic_write_json,
        dumps_json,
    )
    from arenabench.generator.fitting.scene_fit import FitOptions, fit_scene
    from arenabench.generator.model.scene import ArenaSpec, MarkerSpec
    from arenabench.imageio import ImageLoadError, load_image

    if problem := output_problem(args.out, file=True):
        return usage_error("arenabench fit", problem)
    try:
        arena = None if args.arena_side is None else ArenaSpec(side_m=args.arena_side,
                                                               logo_text="eyantra")
    except ValueError as exc:  # the arena's own rule (finite, > 0), said of the option
        why = str(exc).removeprefix("arena.side_m ")
        print(f"arenabench fit: error: --arena-side {why}", file=sys.stderr)
        return ExitCode.USAGE
    try:
        image = load_image(args.image)
        if arena is None:
            from arenabench.generator.fitting.competition_world import (
                competition_camera,
                snap_obstacle,
            )

            camera = competition_camera()
            # the competition's camera for its image size; any other image: the camera fitted
            if args.fit_camera or image.shape[:2] != (camera.height, camera.width):
                camera = None
            options = FitOptions(refine_rounds=args.refine_rounds, camera=camera,
                                 snap=None if camera is None else snap_obstacle)
        else:
            options = FitOptions(arena=arena,
                                 markers=MarkerSpec(side_m=0.0669 * args.arena_side),
                                 fit_marker_side=True, fov_deg=None,
                                 refine_rounds=args.refine_rounds)
    except (ImageLoadError, ValueError) as exc:
        print(f"arenabench fit: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    try:
        result = fit_scene(image, options=options)
    except ValueError as exc:  # about the image's content: name the file
        why = str(exc).removeprefix("image: ")
        print(f"arenabench fit: error: {args.image}: {why}", file=sys.stderr)
        return ExitCode.USAGE
    atomic_write_json(args.out, result.scene.to_dict())
    summary = {"fov_deg": result.fov_deg, "reprojection_px": round(result.reprojection_px, 4),
               "ssim": round(result.ssim, 4), "mad": round(result.mad, 3),
               "obstacles": len(result.scene.obstacles)}
    print(f"fit {args.image}: fov {result.fov_deg:.2f} deg, reprojection "
          f"{result.reprojection_px:.2f} px, {len(result.scene.obstacles)} boxes, "
          f"SSIM {result.ssim:.4f}, MAD {result.mad:.2f} -> {args.out}", file=sys.stderr)
    if args.report:
        print(dumps_json(summary))
    return ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
