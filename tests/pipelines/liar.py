"""A pipeline that answers numbers no obstacle count or area can be.

In-process (``--pipeline liar:NAME``) each function returns the answer of :data:`ANSWERS`
with that name. As a script it prints (``--json TEXT``: a JSON line on stdout, which may hold
``NaN``/``Infinity``) or writes (``--obstacles TEXT``: ``obstacles.txt``) what it is given.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ANSWERS: dict[str, dict] = {
    "nan_area": {"count": 1, "area": float("nan")},
    "inf_area": {"count": 1, "area": float("inf")},
    "negative_area": {"count": 1, "area": -100.0},
    "string_area": {"count": 1, "area": "nan"},
    "bool_count": {"count": True, "area": 100.0},
    "fractional_count": {"count": 1.5, "area": 100.0},
    "infinite_count": {"count": float("inf"), "area": 100.0},
    "negative_count": {"count": -1, "area": 100.0},
    "nan_marker_id": {"count": 1, "area": 100.0, "marker_ids": [80, float("nan")]},
    "huge_count": {"count": 2**20000, "area": 100.0},  # repr() of it raises in Python 3.11+
    "count_2_53": {"count": 2**53, "area": 100.0},  # more obstacles than a scene can hold
    "count_6000": {"count": 6000, "area": 100.0},
    "huge_marker_id": {"count": 1, "area": 100.0, "marker_ids": [80, 10**6]},
    "endless_marker_ids": {"count": 1, "area": 100.0, "marker_ids": range(10**12)},
    "huge_area": {"count": 1, "area": 2**20000},
    "status_array": {"status": [1, 2], "count": 1, "area": 100.0},
}


def _answer(name: str):
    def run(image):
        return dict(ANSWERS[name])

    run.__name__ = run.__qualname__ = name
    return run


for _name in ANSWERS:
    globals()[_name] = _answer(_name)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--image", required=True)
    p.add_argument("--json", default=None)
    p.add_argument("--obstacles", default=None)
    args = p.parse_args(argv)
    if args.json is not None:
        print(args.json)
    if args.obstacles is not None:
        Path("obstacles.txt").write_text(args.obstacles.replace("\\n", "\n"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
