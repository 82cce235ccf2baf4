"""The competition's ``obstacles.txt`` format: writing it exactly, and parsing what teams write.

Format (the key of the last line is ``Area:`` or ``Total Area:`` depending on the team)::

    Aruco ID: [80, 85, 90, 95]
    Obstacles: 2
    Area: 72141.5
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

OBSTACLES_FILE = "obstacles.txt"

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
_RE_IDS = re.compile(r"^\s*aruco\s*ids?\s*:\s*\[?([^\]]*)\]?\s*$", re.IGNORECASE)
_RE_COUNT = re.compile(rf"^\s*obstacles\s*:\s*({_NUMBER})\s*$", re.IGNORECASE)
_RE_AREA = re.compile(rf"^\s*(?:total\s+)?area\s*:\s*({_NUMBER})\s*$", re.IGNORECASE)


class OutputFormatError(ValueError):
    """A pipeline's output could not be parsed; the message quotes the offending text."""


@dataclass(frozen=True)
class CompetitionOutput:
    """What a competition-style pipeline reported."""

    count: int
    area: float
    marker_ids: list[int] = field(default_factory=list)


def format_obstacles_txt(marker_ids: Sequence[int], count: int, area: float) -> str:
    """Render the competition's ``obstacles.txt`` text exactly.

    Parameters
    ----------
    marker_ids : sequence of int
        Marker ids, written as a Python list (``[80, 85, 90, 95]``).
    count : int
        Number of obstacles.
    area : float
        Total obstacle area in frame px.
    """
    ids = ", ".join(str(int(i)) for i in marker_ids)
    return f"Aruco ID: [{ids}]\nObstacles: {int(count)}\nArea: {float(area)}\n"


def parse_obstacles_txt(text: str) -> CompetitionOutput:
    """Parse ``obstacles.txt`` text.

    Accepts ``Area:`` and ``Total Area:``, any letter case, blank lines and surrounding spaces.
    The ``Aruco ID`` line is optional.

    Raises
    ------
    OutputFormatError
        When the count or area line is missing or malformed; the message quotes the text.
    """
    ids: list[int] = []
    count: int | None = None
    area: float | None = None
    for raw in text.splitlines():
        line = raw.strip()
        if not line:
            continue
        if m := _RE_IDS.match(line):
            body = m.group(1).strip()
            try:
                ids = [int(tok) for tok in re.split(r"[,\s]+", body) if tok]
            except ValueError:
                raise OutputFormatError(f"bad marker id list: {raw!r}") from None
        elif m := _RE_COUNT.match(line):
            value = float(m.group(1))
            if value != int(value) or value < 0:
                raise OutputFormatError(f"obstacle count is not a non-negative integer: {raw!r}")
            count = int(value)
        elif m := _RE_AREA.match(line):
            area = float(m.group(1))
        else:
            raise OutputFormatError(f"unrecognised line: {raw!r}")
    if count is None or area is None:
        missing = " and ".join(n for n, v in (("Obstacles", count), ("Area", area)) if v is None)
        snippet = text.strip()[:200]
        raise OutputFormatError(f"missing {missing} line in output: {snippet!r}")
    return CompetitionOutput(count=count, area=area, marker_ids=ids)
