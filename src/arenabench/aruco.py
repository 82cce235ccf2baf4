"""ArUco dictionaries by name: the one place the pipeline and the generator get them."""

from __future__ import annotations

import functools

import cv2


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
