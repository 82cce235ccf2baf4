"""The competition's ``obstacles.txt`` format: writing it exactly, and parsing what teams write.

Format (the key of the last line is ``Area:`` or ``Total Area:`` depending on the team)::

    Aruco ID: [80, 85, 90, 95]
    Obstacles: 2
    Area: 72141.5
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from arenabench.limits import MAX_COUNT, MAX_MARKER_ID

OBSTACLES_FILE = "obstacles.txt"

#: Largest ``|area_rel_err|`` of a passing answer unless ``--tolerance`` says otherwise
#: (every command and report reads it from here).
DEFAULT_TOLERANCE = 0.05

# Also matches nan / inf spellings, so that they are refused by name rather than as "unrecognised".
_NUMBER = r"[-+]?(?:(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?|nan|inf(?:inity)?)"
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


#: Exit status by which a competition-style command (``arenabench detect``, a team's script
#: run by the harness) says "markers not found".
EXIT_MARKERS_NOT_FOUND = 3

def _refuse(name: str, problem: str, value: Any, shown: str | None) -> OutputFormatError:
    if shown is not None:
        quoted = shown
    elif isinstance(value, int) and value.bit_length() > 64:
        quoted = f"an integer of {value.bit_length()} bits"  # repr may refuse huge ints
    else:
        try:
            quoted = repr(value)[:100]
        except Exception:
            quoted = f"<unprintable {type(value).__name__}>"
    return OutputFormatError(f"{name} {problem}: {quoted}")


def check_count(value: Any, *, name: str = "count", shown: str | None = None) -> int:
    """An obstacle count as a Python ``int``, or :class:`OutputFormatError`.

    Accepted: an integer in ``[0, MAX_COUNT]`` (:data:`arenabench.limits.MAX_COUNT`, the most
    obstacles a scene holds), or a float with such an integral value (``2.0``). Refused:
    booleans, strings, fractions, NaN, infinities, negative values and larger values (the
    message names the bound).

    Parameters
    ----------
    value : Any
        What a pipeline reported.
    name : str
        Field name used in the message.
    shown : str, optional
        Text quoted in the message (default: ``repr(value)``).
    """
    return _check_integer(value, name=name, shown=shown, maximum=MAX_COUNT,
                          bound="the most obstacles a scene holds")


def check_marker_id(value: Any, *, shown: str | None = None) -> int:
    """A reported ArUco marker id as a Python ``int`` in ``[0, MAX_MARKER_ID]``
    (:data:`arenabench.limits.MAX_MARKER_ID`), or :class:`OutputFormatError` (the rules of
    :func:`check_count`)."""
    return _check_integer(value, name="marker id", shown=shown, maximum=MAX_MARKER_ID,
                          bound="the largest id of any ArUco dictionary")


def _check_integer(value: Any, *, name: str, shown: str | None, maximum: int,
                   bound: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _refuse(name, "is not an integer", value, shown)
    if isinstance(value, numbers.Integral):
        number = int(value)
    else:
        as_float = float(value)
        if not math.isfinite(as_float):
            raise _refuse(name, "is not a finite number", value, shown)
        if as_float != int(as_float):
            raise _refuse(name, "is not an integer", value, shown)
        number = int(as_float)
    if number < 0:
        raise _refuse(name, "is negative", value, shown)
    if number > maximum:
        raise _refuse(name, f"is larger than {maximum}, {bound}", value, shown)
    return number


def check_area(value: Any, *, name: str = "area", shown: str | None = None) -> float:
    """An obstacle area (frame px) as a finite, non-negative ``float``, or
    :class:`OutputFormatError` (booleans, strings, NaN, infinities, negative values).

    Parameters
    ----------
    value : Any
        What a pipeline reported.
    name : str
        Field name used in the message.
    shown : str, optional
        Text quoted in the message (default: ``repr(value)``).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _refuse(name, "is not a number", value, shown)
    try:
        number = float(value)
    except OverflowError:  # a Python int beyond the float range
        raise _refuse(name, "is not a finite number", value, shown) from None
    if not math.isfinite(number):
        raise _refuse(name, "is not a finite number", value, shown)
    if number < 0:
        raise _refuse(name, "is negative", value, shown)
    return number + 0.0  # -0.0 becomes 0.0


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
        When the count or area line is missing or malformed, or a value is not finite,
        negative, or (for the count and the marker ids) not an integer or beyond any scene
        (:func:`check_count`, :func:`check_marker_id`); the message quotes the text.
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
                tokens = [int(tok) for tok in re.split(r"[,\s]+", body) if tok]
            except ValueError:
                raise OutputFormatError(f"bad marker id list: {raw!r}"[:300]) from None
            if len(tokens) > MAX_MARKER_ID + 1:
                raise OutputFormatError(f"more marker ids ({len(tokens)}) than any ArUco "
                                        f"dictionary holds ({MAX_MARKER_ID + 1})")
            ids = [check_marker_id(i, shown=repr(raw.strip())[:200]) for i in tokens]
        elif m := _RE_COUNT.match(line):
            count = check_count(float(m.group(1)), name="obstacle count", shown=repr(raw.strip()))
        elif m := _RE_AREA.match(line):
            area = check_area(float(m.group(1)), shown=repr(raw.strip()))
        else:
            raise OutputFormatError(f"unrecognised line: {raw!r}")
    if count is None or area is None:
        missing = " and ".join(n for n, v in (("Obstacles", count), ("Area", area)) if v is None)
        snippet = text.strip()[:200]
        raise OutputFormatError(f"missing {missing} line in output: {snippet!r}")
    return CompetitionOutput(count=count, area=area, marker_ids=ids)
