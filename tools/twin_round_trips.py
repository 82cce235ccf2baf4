"""Blind round trips of ``arenabench twin``: "real" images rendered by the generator with
hidden, randomly drawn parameters (``tests/twin_blind.py``), the twin given the image alone,
and what it recovered set against what was hidden.

For each case it prints every check (hidden value, twin's value, within tolerance or not), the
marker squares' figure, the parameters that came out open, and with ``--scenes N`` the
reference pipeline's pass rate on N scenes of the twin's preset; then the tolerances and a
summary::

    export PYTHONPATH=tests:tests/pipelines
    .venv/bin/python tools/twin_round_trips.py --cases 20 --scenes 100
    .venv/bin/python tools/twin_round_trips.py --seeds 3,7 --keep /tmp/b
    .venv/bin/python tools/twin_round_trips.py --presets all --scenes 100 --keep /tmp/p

``--presets`` runs the cases drawn from presets instead (``tests/twin_blind_presets.py``: every
preset, or the comma-separated ones named, ``--per-preset`` each) and prints their table: what
was hidden, the verdict and its causes, the marker squares, the camera, the reference pipeline's
pass rate where a good twin's image passes it, and whether the verdict was right.

(``tests`` on ``PYTHONPATH`` for the case drawer, ``tests/pipelines`` for the pass rates.)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path


def _seeds(args) -> list[int]:
    if args.seeds:
        return [int(s) for s in args.seeds.split(",")]
    return list(range(args.first, args.first + args.cases))


def main(argv: list[str] | None = None) -> int:
    """Run the cases and print the figures; 0 when every check and pass rate holds."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", type=int, default=20, help="cases (seeds FIRST..FIRST+N-1)")
    p.add_argument("--first", type=int, default=1, help="first seed (default 1)")
    p.add_argument("--seeds", default="", help="comma-separated seeds instead of --cases")
    p.add_argument("--scenes", type=int, default=0,
                   help="scenes of each twin for the reference pipeline's pass rate (0: none)")
    p.add_argument("--keep", type=Path, default=None,
                   help="keep the images and twins here (default: a temporary folder)")
    p.add_argument("--reuse", action="store_true",
                   help="compare the twins already in --keep again (no rebuilding)")
    p.add_argument("--presets", default="",
                   help="cases drawn from these presets ('all' or comma-separated names)")
    p.add_argument("--per-preset", type=int, default=0,
                   help="cases of each preset with --presets (default: all of them)")
    args = p.parse_args(argv)
    if args.presets:
        return _preset_cases(args)
    try:  # before any work
        from twin_blind import (
            TOLERANCES,
            hidden_case,
            reference_on_image,
            reference_pass_rate,
            round_trip,
        )
    except ImportError:
        print("needs tests (and tests/pipelines for --scenes) on PYTHONPATH (see --help)",
              file=sys.stderr)
        return 2
    from arenabench.generator.rendering.render import Renderer

    folder = args.keep or Path(tempfile.mkdtemp(prefix="twin-blind-"))
    failed, opened, not_applicable = [], Counter(), []
    rates = []
    with Renderer() as renderer:
        for seed in _seeds(args):
            case = hidden_case(seed)
            t = time.monotonic()
            result = round_trip(case, folder / f"case-{seed}", renderer, reuse=args.reuse)
            s = case.scene
            floor = s.arena.texture if case.texture is None else "image"
            print(f"case {seed}: {s.markers.dictionary} ids {list(s.markers.ids)} turned "
                  f"{s.markers.rotation_deg:g}, {floor} floor, "
                  f"{len(s.obstacles)} boxes, {s.camera.width}x{s.camera.height} fov "
                  f"{s.camera.fov_deg:.1f} tilt {s.camera.tilt_deg:.1f}, edges "
                  f"{s.render.edge_samples}/{s.render.edge_resolve}, {case.file_format}"
                  + (f" q{case.jpeg_quality} {case.jpeg_subsampling}"
                     if case.file_format == "jpeg" else "")
                  + f" (twin {time.monotonic() - t:.0f} s)")
            for name, (want, got, ok) in result["checks"].items():
                print(f"  {'ok  ' if ok else 'FAIL'} {name}: hidden {want}, twin {got}")
            print(f"  open: {', '.join(result['open'])}")
            opened.update(result["open"])
            if not result["ok"]:
                failed.append(seed)
            if args.scenes:
                rate = reference_pass_rate(folder / f"case-{seed}" / "twin", args.scenes)
                real_ok, account = reference_on_image(case, folder / f"case-{seed}"
                                                      / case.image_name)
                print(f"  ---- reference pipeline on the image itself: {account}")
                ok = rate >= TOLERANCES["pass_rate"][0]
                if real_ok:
                    rates.append(rate)
                    print(f"  {'ok  ' if ok else 'FAIL'} reference pipeline: {rate:.1%} of "
                          f"{args.scenes} scenes of the twin pass")
                else:  # the arena itself defeats it: a faithful twin's scenes do too
                    not_applicable.append(seed)
                    print(f"  n/a  reference pipeline: {rate:.1%} of {args.scenes} scenes of "
                          "the twin pass (it fails the real image too: no bound applies)")
                if real_ok and not ok and seed not in failed:
                    failed.append(seed)
            sys.stdout.flush()
    print("\ntolerances:")
    for name, (value, why) in TOLERANCES.items():
        print(f"  {name} {value:g}: {why}")
    n = len(_seeds(args))
    print(f"\n{n - len(failed)} of {n} cases within every tolerance"
          + (f" (failed: {', '.join(map(str, failed))})" if failed else ""))
    if rates:
        print(f"reference pipeline pass rate: lowest {min(rates):.1%}, mean "
              f"{sum(rates) / len(rates):.1%} over the {len(rates)} cases whose image it passes"
              + (f" (it fails the image itself in case {', '.join(map(str, not_applicable))})"
                 if not_applicable else ""))
    print("open, in how many cases: " + ", ".join(f"{k} {v}" for k, v in opened.most_common()))
    print(f"images and twins in {folder}")
    return 1 if failed else 0


def _row(r: dict, rate: str) -> str:
    px = r["checks"].get("camera (image px)", (None, "-", True))[1]
    variant = ", ".join(f"{k.split('.')[-1]} {v}" for k, v in r["overrides"].items())
    hidden = "; ".join(x for x in (variant, ", ".join(r["features"])) if x) or "-"
    missed = ", ".join(k for k, (_, _, ok) in r["checks"].items() if not ok) or "-"
    causes = "; ".join(c["text"].split(" (")[0] for c in r["causes"]) or "-"
    squares = "-" if r["marker_squares"] != r["marker_squares"] else f"{r['marker_squares']:.2f}"
    return (f"| {r['case']} | {hidden} | {r['verdict']} | {causes} | {squares} | {px} | "
            f"{missed} | {rate} | {r['judged']} |")


def _preset_cases(args) -> int:
    """Run the cases drawn from presets and print their table; 0 when no verdict is wrong."""
    import json

    try:
        from twin_blind import TOLERANCES, reference_pass_rate
        from twin_blind_presets import (
            BLIND_PRESETS,
            PRESET_CASES,
            preset_case,
            preset_round_trip,
            reference_passes_image,
        )
    except ImportError:
        print("needs tests and tests/pipelines on PYTHONPATH (see --help)", file=sys.stderr)
        return 2
    names = BLIND_PRESETS if args.presets == "all" else tuple(args.presets.split(","))
    unknown = sorted(set(names) - set(BLIND_PRESETS))
    if unknown:
        print(f"--presets: unknown preset(s) {', '.join(unknown)} (known: "
              f"{', '.join(BLIND_PRESETS)})", file=sys.stderr)
        return 2
    from arenabench.generator.rendering.render import Renderer

    folder = args.keep or Path(tempfile.mkdtemp(prefix="twin-blind-presets-"))
    rows, wrong = [], []
    with Renderer() as renderer:
        for name in names:
            for n in range(1, (args.per_preset or PRESET_CASES) + 1):
                case = preset_case(name, n)
                t = time.monotonic()
                r = preset_round_trip(case, folder / case.name, renderer)
                hidden = r.pop("hidden")
                rate = "-"
                if r["verdict"] == "good" and args.scenes:
                    if reference_passes_image(hidden):
                        value = reference_pass_rate(folder / case.name / "twin", args.scenes)
                        rate = f"{value:.0%}"
                        if value < TOLERANCES["pass_rate"][0]:
                            r["judged"], r["ok"] = "WRONG", False
                    else:
                        rate = "n/a (fails the image)"
                r.update(overrides=case.overrides, rate=rate,
                         seconds=round(time.monotonic() - t))
                (folder / case.name / "result.json").write_text(json.dumps(
                    r, default=str, indent=1))
                rows.append(_row(r, rate))
                print(rows[-1] + f" ({r['seconds']} s)", flush=True)
                if not r["ok"]:
                    wrong.append(case.name)
    print("\n| case | hidden | verdict | causes | marker squares | camera px | missed | "
          "reference rate | judged |\n|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\n{len(rows) - len(wrong)} of {len(rows)} verdicts right or cautious"
          + (f" (wrong: {', '.join(wrong)})" if wrong else "") + f"; twins in {folder}")
    return 1 if wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
