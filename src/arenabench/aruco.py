"""ArUco dictionaries by name: the one place the pipeline and the generator get them."""

from __future__ import annotations

import functools

import cv2
import numpy as np


@functools.cache
def aruco_dictionary(name: str, *, field: str = "dictionary") -> cv2.aruco.Dictionary:
    """The predefined OpenCV ArUco dictionary called ``name`` (e.g. ``"DICT_4X4_100"``),
    made once per name.

    Parameters
    ----------
    name : str
        The dictionary's name in ``cv2.aruco``.
    field : str, keyword-only
        The option or scene field ``name`` came from, named by the error.

    Raises
    ------
    ValueError
        One line naming ``field``: OpenCV has no such dictionary.
    """
    code = getattr(cv2.aruco, name, None) if isinstance(name, str) else None
    if not isinstance(name, str) or not name.startswith("DICT_") or not isinstance(code, int):
        raise ValueError(f"{field}: unknown ArUco dictionary {name!r}")
    return cv2.aruco.getPredefinedDictionary(code)


@functools.lru_cache(maxsize=4096)
def symmetric_turn(dictionary: str, marker_id: int) -> int | None:
    """The smallest quarter turn (90, 180 or 270 deg) under which marker ``marker_id`` of
    ``dictionary`` looks the same, or ``None``: a detector cannot tell such a marker's first
    corner (of every predefined dictionary, only DICT_ARUCO_ORIGINAL's id 1023 is one, at
    180)."""
    d = aruco_dictionary(dictionary)
    img = cv2.aruco.generateImageMarker(d, int(marker_id), d.markerSize + 2, borderBits=1)
    for quarter in (1, 2, 3):
        if np.array_equal(img, np.rot90(img, quarter)):
            return 90 * quarter
    return None
