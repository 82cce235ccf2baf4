"""Numbers as people write them on a command line or in a file: plain ASCII decimal."""

from __future__ import annotations

import re

#: How a number is written on a command line or in a preset file: plain ASCII decimal digits,
#: a sign, a point and an exponent; no underscores (``1_0``), no other scripts' digits (``٣``),
#: no spaces.
_INT_TEXT = re.compile(r"[+-]?[0-9]+")
_FLOAT_TEXT = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def plain_number(text: str, kind: str = "float") -> int | float:
    """``text`` as a number when it is written as plain ASCII decimal (:data:`_FLOAT_TEXT`;
    ``kind="int"``: digits only). Python's ``int()`` and ``float()`` also read ``1_0``,
    ``٣`` (an Arabic-Indic three), surrounding white space, ``inf`` and ``nan``; a command line
    does not.

    Raises
    ------
    ValueError
        When ``text`` is not such a number.
    """
    pattern = _INT_TEXT if kind == "int" else _FLOAT_TEXT
    if not isinstance(text, str) or not pattern.fullmatch(text):
        raise ValueError(f"not a plain decimal number: {text!r}")
    return int(text) if kind == "int" else float(text)
