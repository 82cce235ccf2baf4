"""Golden ground-truth hashes: a guard that ``GENERATOR_VERSION`` is bumped when GT changes.

For a few scenes of every preset, the platform-independent geometry of the GT record
(counts, areas and polygons rounded to 1e-3 px, marker corners, camera, sampled parameters,
scene description) is hashed, part by part, and compared with ``tests/data/golden_gt.json``.
Image bytes are not hashed (they differ between GL drivers), and every float is rounded and
printed with a fixed number of decimals, so the hashes do not depend on float reprs.

Regenerate after a deliberate change (bump ``GENERATOR_VERSION`` first)::

    .venv/bin/python -m tests.golden --update        # or: make golden

``--update`` refuses to change the hashes of a version that is already in the file: an
output change needs a new ``GENERATOR_VERSION`` (see docs/architecture.md, "Golden GT").
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

GOLDEN_PATH = Path(__file__).resolve().parent / "data" / "golden_gt.json"
#: Scenes per preset and the seed they are drawn with.
SCENES_PER_PRESET = 3
SEED = 0
#: Decimals kept per kind of value before hashing.
PX_DECIMALS = 3
VALUE_DECIMALS = 6
UPDATE_COMMAND = ".venv/bin/python -m tests.golden --update"


def _canonical(obj: Any, decimals: int) -> Any:
    """``obj`` with every float replaced by a fixed-decimal string (no platform float reprs)."""
    if isinstance(obj, dict):
        return {str(k): _canonical(v, decimals) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v, decimals) for v in obj]
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, int):
        return obj
    if isinstance(obj, float):
        text = f"{round(obj, decimals):.{decimals}f}"
        return "0." + "0" * decimals if text.lstrip("-") == "0." + "0" * decimals else text
    raise TypeError(f"cannot canonicalise {type(obj).__name__}: {obj!r}")


def _digest(obj: Any, decimals: int) -> str:
    text = json.dumps(_canonical(obj, decimals), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _ring(points: list[list[float]]) -> list[list[str]]:
    """A polygon ring rounded to :data:`PX_DECIMALS` and rotated to start at its smallest
    vertex, so a geometry library that starts clipped rings elsewhere changes no hash."""
    ring = [_canonical([float(x), float(y)], PX_DECIMALS) for x, y in points]
    if not ring:
        return ring
    start = min(range(len(ring)), key=lambda i: (float(ring[i][0]), float(ring[i][1])))
    return ring[start:] + ring[:start]


def gt_parts(gt: dict[str, Any]) -> dict[str, str]:
    """Hashes of the parts of one GT record (part name -> 16 hex digits)."""
    px = PX_DECIMALS
    polygons = ("footprint_frame_px", "visible_frame_px", "image_polygon_px")
    obstacles = [
        {**{k: _ring(ob[k]) for k in polygons},
         **{k: ob.get(k) for k in ("footprint_area_px", "visible_area_px", "in_view")}}
        for ob in gt["obstacles"]
    ]
    markers = [
        {k: m.get(k) for k in ("dictionary", "id", "corner", "corners_px", "in_view",
                               "visible")}
        for m in gt["markers"]
    ]
    return {
        "count": _digest([gt["count"], gt["components"]], px),
        "area": _digest(gt["area"], px),
        "obstacles": _digest(obstacles, px),
        "markers": _digest(markers, px),
        "camera": _digest({"K": gt["camera"]["K"], "dist": gt["camera"]["dist"],
                           "world_from_camera": gt["camera"]["world_from_camera"],
                           "image_size": gt["image_size"], "frame": gt["frame"]},
                          VALUE_DECIMALS),
        "params": _digest(gt["params"], VALUE_DECIMALS),
        "scene": _digest(gt["scene"], VALUE_DECIMALS),
    }


def scene_gt(preset: str, index: int) -> dict[str, Any]:
    """The GT record of scene ``index`` of ``preset`` (seed :data:`SEED`), without rendering."""
    from arenabench.fileio import rounded
    from arenabench.generator.dataset.make import gt_record, scene_id
    from arenabench.generator.model.sampler import sample_scene

    sampled = sample_scene(preset, seed=SEED, index=index)
    return gt_record(sampled.scene, sid=scene_id(index), preset=preset, seed=SEED, index=index,
                     params=rounded(sampled.params))


def current() -> dict[str, dict[str, str]]:
    """Part hashes of every golden scene, keyed ``"preset/index"``."""
    from arenabench.generator.parameters.presets import preset_names

    return {
        f"{name}/{index}": gt_parts(scene_gt(name, index))
        for name in preset_names()
        for index in range(SCENES_PER_PRESET)
    }


def generator_version() -> str:
    """The generator version the hashes belong to."""
    from arenabench.generator.dataset.make import GENERATOR_VERSION

    return GENERATOR_VERSION


def load() -> dict[str, dict[str, dict[str, str]]]:
    """``{generator_version: {"preset/index": {part: hash}}}`` from the golden file."""
    if not GOLDEN_PATH.is_file():
        return {}
    return json.loads(GOLDEN_PATH.read_text(encoding="utf-8"))


def differences(want: dict[str, dict[str, str]], have: dict[str, dict[str, str]]) -> list[str]:
    """One line per scene whose parts differ (or that only one side has)."""
    lines = []
    for key in sorted(set(want) | set(have)):
        if key not in want:
            lines.append(f"{key}: new scene (no golden entry)")
        elif key not in have:
            lines.append(f"{key}: golden entry for a scene no longer generated")
        else:
            parts = [p for p in sorted(set(want[key]) | set(have[key]))
                     if want[key].get(p) != have[key].get(p)]
            if parts:
                lines.append(f"{key}: {', '.join(parts)} changed")
    return lines


def update(*, force: bool = False) -> int:
    """Write the current hashes under the current ``GENERATOR_VERSION`` (only that version is
    kept). Refuses, without ``force``, to change the hashes of a version already recorded."""
    version, have = generator_version(), current()
    old = load().get(version)
    if old is not None and old != have and not force:
        diff = differences(old, have)
        print(f"golden: ground truth changed but GENERATOR_VERSION is still {version!r}:\n  "
              + "\n  ".join(diff)
              + "\nbump GENERATOR_VERSION in generator/dataset/make.py (and say what changed in "
              "its comment), then run this again; --force only if the recorded hashes were wrong.",
              file=sys.stderr)
        return 1
    text = json.dumps({version: have}, indent=2, sort_keys=True) + "\n"
    GOLDEN_PATH.parent.mkdir(parents=True, exist_ok=True)
    GOLDEN_PATH.write_text(text, encoding="utf-8")
    print(f"golden: wrote {len(have)} scenes for GENERATOR_VERSION {version!r} to {GOLDEN_PATH}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m tests.golden [--update [--force]]``: check (default) or rewrite the file."""
    p = argparse.ArgumentParser(prog="python -m tests.golden", description=__doc__.split("\n")[0])
    p.add_argument("--update", action="store_true", help="rewrite tests/data/golden_gt.json")
    p.add_argument("--force", action="store_true",
                   help="with --update: overwrite the hashes of the current version")
    args = p.parse_args(argv)
    if args.update:
        return update(force=args.force)
    version = generator_version()
    diff = differences(load().get(version, {}), current())
    if diff:
        print("\n".join(diff), file=sys.stderr)
        return 1
    print(f"golden: GT of every golden scene matches (GENERATOR_VERSION {version!r})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
