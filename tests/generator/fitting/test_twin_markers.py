"""Arenas with more markers than four (generator/fitting/markers.py): the four that bound the
arena are found among the others (the outermost, one per corner), the others recorded, and
the dictionary named is the one that decodes every id found; drawn with OpenCV's own ArUco
markers and found by its detector."""

import cv2
import numpy as np
import pytest

from arenabench.generator.fitting.markers import MarkersNotFoundError, find_markers, outermost

SIDE = 900
MARKER = 60


def _arena(places: dict[int, tuple[int, int]], dictionary: str = "DICT_4X4_250",
           turn: float = 0.0) -> np.ndarray:
    """A light floor with ``places`` (id -> top-left corner) markers, turned by ``turn`` deg
    about the image's centre."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    img = np.full((SIDE, SIDE), 235, np.uint8)
    for marker_id, (x, y) in places.items():
        tile = np.full((MARKER + 20, MARKER + 20), 255, np.uint8)
        tile[10:-10, 10:-10] = cv2.aruco.generateImageMarker(d, marker_id, MARKER)
        img[y - 10:y + MARKER + 10, x - 10:x + MARKER + 10] = tile
    if turn:
        m = cv2.getRotationMatrix2D((SIDE / 2, SIDE / 2), turn, 0.7)
        img = cv2.warpAffine(img, m, (SIDE, SIDE), borderValue=235)
    return img


#: Four corner markers (ids 3, 7, 11, 12), four at the edges' midpoints, two inside.
CORNERS = {3: (40, 40), 7: (800, 40), 11: (800, 800), 12: (40, 800)}
EDGES = {120: (420, 40), 121: (800, 420), 122: (420, 800), 123: (40, 420)}
INSIDE = {200: (300, 300), 201: (560, 500)}


@pytest.mark.parametrize("turn", [0.0, 30.0], ids=["square", "turned-30-deg"])
def test_the_four_corner_markers_are_found_among_eight_and_more(turn):
    found = find_markers(_arena({**CORNERS, **EDGES, **INSIDE}, turn=turn))
    assert sorted(found.ids) == [3, 7, 11, 12]
    assert found.others == (120, 121, 122, 123, 200, 201)
    # the ids go to 201: the smallest dictionary decoding every id found is named, the
    # smallest holding the corner ids noted beside it
    assert found.dictionary == "DICT_4X4_250" and found.smallest == "DICT_4X4_50"


def test_four_markers_alone_are_found_as_before():
    found = find_markers(_arena(CORNERS))
    assert found.ids == (3, 7, 11, 12) and found.others == ()
    assert found.dictionary == "DICT_4X4_50" == found.smallest


def test_markers_in_a_row_bound_no_arena():
    row = {i: (60 + 130 * i, 420) for i in range(6)}
    with pytest.raises(MarkersNotFoundError, match="bound no quadrilateral"):
        outermost({i: np.array([[x, y], [x + 60, y], [x + 60, y + 60], [x, y + 60]], float)
                   for i, (x, y) in row.items()})
