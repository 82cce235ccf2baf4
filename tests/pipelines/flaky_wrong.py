"""A competition-style script that is always wrong (one obstacle too many) and, on images that
are not the set's own (the phase check's re-renders), crashes at random on about half its runs
(phase-check tests).

``FLAKY_STEADY``: a set's ``images`` folder; an image whose bytes are one of its files is never
crashed on, so that every image of the set fails by its answer and is phase-checked.
``FLAKY_LOG``: a folder; each run on another image leaves a file there saying ``crash`` or
``answered`` and the image file's JPEG quality and chroma subsampling (``answered 95 420``),
so that a test can count the runs that crashed and see how the images were encoded.
``FLAKY_CRASH_SHARE``: the share of those runs that crash (default 0.5).
"""

from __future__ import annotations

import hashlib
import os
import sys
import uuid
from pathlib import Path

import competition_style
from competition_style import main

from arenabench.pipeline import detect as reference_detect


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _steady(image: Path) -> bool:
    folder = os.environ.get("FLAKY_STEADY")
    if not folder:
        return False
    own = _digest(image)
    return any(_digest(p) == own for p in Path(folder).iterdir())


def detect(image_bgr):
    """The reference answer with one obstacle too many."""
    det = reference_detect(image_bgr)
    if not det.ok:
        return competition_style.not_found(list(det.marker_ids or []))
    return {"status": "ok", "count": det.count + 1, "area": det.area,
            "marker_ids": list(det.marker_ids)}


def _log(what: str, image: Path) -> None:
    folder = os.environ.get("FLAKY_LOG")
    if folder:
        from arenabench.imageio import jpeg_settings

        found = jpeg_settings(image.read_bytes())
        Path(folder, uuid.uuid4().hex).write_text(
            f"{what} {found.quality} {found.subsampling}", encoding="utf-8")


if __name__ == "__main__":
    image = Path(sys.argv[sys.argv.index("--image") + 1])
    if not _steady(image):
        share = float(os.environ.get("FLAKY_CRASH_SHARE", "0.5"))
        if os.urandom(2)[0] < 256 * share:  # at random
            _log("crash", image)
            raise RuntimeError("flaky: a random crash")
        _log("answered", image)
    sys.exit(main(detect))
