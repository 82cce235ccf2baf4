"""A competition-style script whose answer depends on the shade of the boxes' side faces
(phase-check tests of open parameters).

It answers the reference pipeline's count, plus one obstacle when more than ``DARK_ABOVE``
(an environment variable) pixels of the image are as dark as a side face in the ambient shade
(grey 55-90): lighter east faces (``lighting.east_fill``) take pixels out of that band, and the
same scene then passes.
"""

from __future__ import annotations

import os
import sys

import competition_style
import cv2
import numpy as np
from competition_style import main

from arenabench.pipeline import detect as reference_detect

#: The grey levels of a side face in the ambient shade (the twin's south, east and west faces).
DARK_BAND = (55, 90)


def dark_pixels(image_bgr: np.ndarray) -> int:
    """Pixels of the image inside :data:`DARK_BAND`."""
    grey = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
    return int(((grey >= DARK_BAND[0]) & (grey <= DARK_BAND[1])).sum())


def detect(image_bgr: np.ndarray) -> dict:
    """The reference answer, one obstacle too many above ``DARK_ABOVE`` dark pixels."""
    det = reference_detect(image_bgr)
    if not det.ok:
        return competition_style.not_found(list(det.marker_ids or []))
    extra = 1 if dark_pixels(image_bgr) > int(os.environ["DARK_ABOVE"]) else 0
    return {"status": "ok", "count": det.count + extra, "area": det.area,
            "marker_ids": list(det.marker_ids)}


if __name__ == "__main__":
    sys.exit(main(detect))
