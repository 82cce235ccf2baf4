"""The rectified frame: the 1000 x 1000 top-down view every part of the project agrees on.

Conventions (defined in docs/ground-truth.md, "Coordinate systems"):

- World: metres, floor plane z = 0, z up; the arena is a square of side L centred at the
  origin; north is +y, east is +x.
- The homography H maps image px to frame px so that the four *reference corners* go to
  (0, 0), (S, 0), (S, S), (0, S) in the order north-west, north-east, south-east, south-west
  as seen from above, with S the frame size.
- Reference corners are the markers' ``inner`` corners (nearest the arena centre; the
  competition default) or their ``outer`` corners (the arena's extreme corners).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from arenabench.limits import MAX_IMAGE_SIDE_PX

#: Corner names in frame order.
CORNER_ORDER: tuple[str, ...] = ("nw", "ne", "se", "sw")

#: The competition arena's marker ids by corner, and their ArUco dictionary.
COMPETITION_MARKER_IDS: dict[str, int] = {"nw": 80, "ne": 85, "se": 90, "sw": 95}
COMPETITION_DICTIONARY = "DICT_4X4_100"

CornerConvention = Literal["inner", "outer"]


@dataclass(frozen=True)
class FrameSpec:
    """Size and corner convention of the rectified frame.

    Parameters
    ----------
    size : int
        Side of the square frame in px (default 1000).
    corners : {"inner", "outer"}
        Which marker corners map to the frame corners.
    """

    size: int = 1000
    corners: CornerConvention = "inner"

    def __post_init__(self) -> None:
        if int(self.size) != self.size or not 16 <= self.size <= MAX_IMAGE_SIDE_PX:
            raise ValueError(
                f"frame size must be an integer in [16, {MAX_IMAGE_SIDE_PX}], got {self.size!r}"
            )
        if self.corners not in ("inner", "outer"):
            raise ValueError(f"frame corners must be 'inner' or 'outer', got {self.corners!r}")

    def corners_px(self) -> np.ndarray:
        """Frame corners (4, 2) float64 in NW, NE, SE, SW order."""
        s = float(self.size)
        return np.array([[0.0, 0.0], [s, 0.0], [s, s], [0.0, s]])

    def to_dict(self) -> dict:
        """JSON form used in ground truth: ``{"size": [S, S], "corners": ...}``."""
        return {"size": [int(self.size), int(self.size)], "corners": self.corners}
