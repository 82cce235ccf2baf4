"""The arena's corner markers, found in the image alone: dictionary, ids, layout, printed
rotation and sub-pixel corners.

Every predefined ``cv2.aruco`` dictionary is tried. Dictionaries of one family (``DICT_4X4_50``,
``_100``, ``_250``, ``_1000``) print the same marker for the same id (each is the start of the
next), so the family is what the image shows; the smallest dictionary of the family that holds
every id found is the one named. Among families that find markers, the one that finds four with
the fewest bit errors wins. The four markers are named by where they sit around their centroid:
north-west is the one towards the image's top left (so the twin's north is the image's top,
within 45 degrees), then clockwise. The printed rotation is read from where each marker's
corner 0 lies, measured along the arena's own axes (from the marker layout), so a camera
heading does not change it.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass

import cv2
import numpy as np

from arenabench.frame import CORNER_ORDER


def _predefined() -> tuple[str, ...]:
    """Every predefined dictionary once (OpenCV 5 spells some twice, ``_36H11`` and
    ``_36h11``: the lower-case one, OpenCV 4's, is kept), smallest first within a family."""
    by_value: dict[int, str] = {}
    for name in sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_")):
        value = getattr(cv2.aruco, name)
        if isinstance(value, int) and (value not in by_value or name > by_value[value]):
            by_value[value] = name  # "h" sorts after "H"

    def key(name: str) -> tuple[str, int]:
        m = re.match(r"^(DICT_\d+X\d+)_(\d+)$", name)
        return (m.group(1), int(m.group(2))) if m else (name, 0)

    return tuple(sorted(by_value.values(), key=key))


#: The dictionaries tried, in a fixed order.
DICTIONARIES: tuple[str, ...] = _predefined()

_FAMILY = re.compile(r"^DICT_(\d+X\d+)_(\d+)$")


class MarkersNotFoundError(ValueError):
    """The image does not show four corner markers of one dictionary (the message says what
    was found and which dictionaries were tried)."""


@dataclass(frozen=True)
class MarkerFinding:
    """The four corner markers as the image shows them.

    Attributes
    ----------
    dictionary : str
        The smallest dictionary of the family that holds every id found.
    family : tuple of str
        Every dictionary that prints the same four markers (the family's larger ones).
    ids : tuple of int
        Ids at the north-west, north-east, south-east and south-west corners.
    corners : dict
        Sub-pixel image corners (4, 2) of each marker in cv2.aruco's order, by corner name
        (``nw`` .. ``sw``).
    detector_corners : dict
        The same as ``cv2.aruco.ArucoDetector`` with default parameters reports them (what
        competition scripts see).
    rotation_deg : float
        Printed rotation of the markers (counter-clockwise seen from above; 180 = the
        competition arena's), the same for all four.
    bit_errors : int
        Bits that differ from the dictionary's codewords, summed over the four markers.
    tried : tuple of str
        The dictionaries tried.
    others : tuple of int
        Ids of the markers found besides the four corner ones (an arena with more markers:
        they are part of its printed floor).
    smallest : str
        The smallest dictionary of the family holding the four corner ids (a fact; the
        ``dictionary`` decodes every id found).
    """

    dictionary: str
    family: tuple[str, ...]
    ids: tuple[int, int, int, int]
    corners: dict[str, np.ndarray]
    detector_corners: dict[str, np.ndarray]
    rotation_deg: float
    bit_errors: int
    tried: tuple[str, ...]
    others: tuple[int, ...] = ()
    smallest: str = ""

    @property
    def module_count(self) -> int:
        """Modules across a marker, its black border included."""
        return _dictionary(self.dictionary).markerSize + 2


def _dictionary(name: str):
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def _detect(gray: np.ndarray, name: str, *, refine: bool) -> dict[int, np.ndarray]:
    params = cv2.aruco.DetectorParameters()
    if refine:
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    corners, ids, _ = cv2.aruco.ArucoDetector(_dictionary(name), params).detectMarkers(gray)
    if ids is None:
        return {}
    return {int(i): c.reshape(4, 2).astype(np.float64) for i, c in
            zip(ids.ravel(), corners, strict=True)}


def detector_corner_offsets(gray: np.ndarray, finding: MarkerFinding) -> dict[int, float | None]:
    """How far ``cv2.aruco``'s default detector (no corner refinement: what competition
    scripts call) reports ``finding``'s markers on ``gray`` from where it reports them on the
    image ``finding`` was made from.

    The default detector's corners are whole pixels read off a thresholded outline, so two
    images whose sub-pixel corners agree within a tenth of a pixel can still give corners a
    pixel or two apart; a script that warps the arena from them then sees another frame.

    Parameters
    ----------
    gray : ndarray
        (H, W) uint8 image of the same arena (a twin's render of the fitted scene).
    finding : MarkerFinding
        The markers found on the image (their ``detector_corners``).

    Returns
    -------
    dict
        Marker id -> the largest of its four corners' distances (px), or ``None`` where the
        detector does not find that marker on ``gray``.
    """
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise ValueError(f"gray must be an (H, W) uint8 image, got {gray.shape} {gray.dtype}")
    found = _detect(gray, finding.dictionary, refine=False)
    out: dict[int, float | None] = {}
    for corner, marker_id in zip(CORNER_ORDER, finding.ids, strict=True):
        quad = found.get(marker_id)
        out[marker_id] = (None if quad is None else round(float(np.linalg.norm(
            quad - finding.detector_corners[corner], axis=1).max()), 3))
    return out


def detector_offset_text(offsets: dict[int, float | None]) -> str:
    """``detector_corner_offsets`` in words: "at the same pixels", "within 2 px (...)" or
    which markers the detector misses."""
    missed = [str(k) for k, v in offsets.items() if v is None]
    if missed:
        return f"marker(s) {', '.join(missed)} not found by the default detector"
    worst = max(offsets.values(), default=0.0)
    if worst == 0:
        return "at the same pixels"
    return (f"within {worst:g} px ("
            + ", ".join(f"{k}: {v:g}" for k, v in offsets.items()) + ")")


def marker_bits(gray: np.ndarray, quad: np.ndarray, size: int) -> np.ndarray:
    """The (size, size) bits inside a marker's border, read at its cell centres (Otsu
    threshold of the marker's own pixels), in the marker's own orientation (corner 0 top left)."""
    cells = size + 2
    px = 12
    dst = np.array([[0, 0], [cells * px, 0], [cells * px, cells * px], [0, cells * px]],
                   np.float32)
    h = cv2.getPerspectiveTransform(quad.astype(np.float32), dst)
    warped = cv2.warpPerspective(gray, h, (cells * px, cells * px), flags=cv2.INTER_LINEAR)
    _, binary = cv2.threshold(warped, 0, 1, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    centre = px // 2
    # a 5 x 5 window round each cell centre, by majority
    votes = np.zeros((cells, cells))
    for dy in (-2, 0, 2):
        for dx in (-2, 0, 2):
            votes += binary[centre + dy::px, centre + dx::px][:cells, :cells]
    sample = (votes >= 5).astype(np.uint8)
    return sample[1:-1, 1:-1]


def _bit_errors(gray: np.ndarray, quad: np.ndarray, name: str, marker_id: int) -> int:
    d = _dictionary(name)
    bits = marker_bits(gray, quad, d.markerSize)
    want = d.getMarkerBits(marker_id) if hasattr(d, "getMarkerBits") else None
    if want is None:  # pragma: no cover - OpenCV 4.7 and earlier
        return int(d.getDistanceToId(bits, marker_id, False))
    return int(np.count_nonzero(np.asarray(want, np.uint8) != bits))


def _family(name: str) -> tuple[str, int] | None:
    m = _FAMILY.match(name)
    return (m.group(1), int(m.group(2))) if m else None


def _layout(found: dict[int, np.ndarray]) -> dict[str, int]:
    """Ids by arena corner: north-west is the marker towards the image's top left of the
    centroid, the others follow clockwise in the image."""
    centres = {i: q.mean(axis=0) for i, q in found.items()}
    g = np.mean(list(centres.values()), axis=0)
    angle = {i: math.degrees(math.atan2(c[1] - g[1], c[0] - g[0])) for i, c in centres.items()}
    nw = min(angle, key=lambda i: abs((angle[i] + 135.0 + 180.0) % 360.0 - 180.0))
    order = sorted(angle, key=lambda i: (angle[i] - angle[nw]) % 360.0)
    return dict(zip(CORNER_ORDER, order, strict=True))


def printed_rotation(corners: dict[str, np.ndarray]) -> float:
    """The markers' printed rotation (deg, counter-clockwise seen from above) from where their
    corner 0 lies along the arena's axes (north: from the south markers' centres to the north
    ones', east likewise).

    Raises
    ------
    MarkersNotFoundError
        When the four markers are not printed the same way.
    """
    c = {k: q.mean(axis=0) for k, q in corners.items()}
    north = (c["nw"] + c["ne"] - c["sw"] - c["se"]) / 2.0
    east = (c["ne"] + c["se"] - c["nw"] - c["sw"]) / 2.0
    basis = np.linalg.inv(np.column_stack([east / np.linalg.norm(east),
                                           north / np.linalg.norm(north)]))
    rotations = []
    for name, quad in corners.items():
        e, n = basis @ (quad[0] - c[name])
        # upright: corner 0 is the marker's north-west corner (-e, +n); each 90 deg turn
        # counter-clockwise moves it a quarter turn on
        angle = math.degrees(math.atan2(n, e)) - 135.0
        rotations.append(round(angle / 90.0) * 90.0 % 360.0)
    if len(set(rotations)) != 1:
        raise MarkersNotFoundError(
            "image: the four markers are printed in different rotations "
            f"({', '.join(f'{k} {r:g}' for k, r in zip(corners, rotations, strict=True))} deg); "
            "the generator prints all four the same way")
    return rotations[0]


def find_markers(gray: np.ndarray) -> MarkerFinding:
    """Find the arena's four corner markers in a grey image.

    Parameters
    ----------
    gray : numpy.ndarray
        (H, W) uint8 image.

    Returns
    -------
    MarkerFinding

    Raises
    ------
    MarkersNotFoundError
        No dictionary finds four markers (the message names what each found, or that none
        found any, and the dictionaries tried).
    """
    if gray.ndim != 2 or gray.dtype != np.uint8:
        raise ValueError(f"gray must be an (H, W) uint8 image, got {gray.shape} {gray.dtype}")
    candidates = []
    partial = []
    for name in DICTIONARIES:
        found = _detect(gray, name, refine=False)
        if len(found) >= 4:
            errors = sum(_bit_errors(gray, q, name, i) for i, q in found.items())
            candidates.append((len(found), errors, name, found))
        elif found:
            partial.append((len(found), name, sorted(found)))
    if not candidates:
        tried = f"tried {len(DICTIONARIES)} dictionaries: {', '.join(DICTIONARIES)}"
        if partial:
            n, name, ids = max(partial, key=lambda p: p[0])  # the first of the most
            shown = ", ".join(map(str, ids))
            raise MarkersNotFoundError(
                f"image: found {n} marker(s) of {name} (ids {shown}), not four: a twin needs "
                f"one marker in each corner of the arena ({tried})")
        raise MarkersNotFoundError(f"image: no ArUco markers found ({tried})")
    # per family (its dictionaries print the same markers): the member decoding the most
    # markers, the smallest of those: it decodes every id found
    families: dict[str, list] = {}
    for n, errors, name, found in candidates:
        fam = _family(name)
        families.setdefault(fam[0] if fam else name, []).append(
            (-n, fam[1] if fam else 0, name, found, errors))
    members = {key: sorted(found, key=lambda m: m[:3]) for key, found in families.items()}
    # across families: the fewest bit errors per marker
    score = {key: m[0][4] / -m[0][0] for key, m in members.items()}
    best = min(score.values())
    tied = sorted(key for key, s in score.items() if s == best)
    if len(tied) > 1:
        raise MarkersNotFoundError(f"image: four markers found by several dictionary families "
                                   f"equally well ({', '.join(tied)}); cannot tell which one "
                                   "is printed")
    chosen = members[tied[0]]
    _, _, name, found, errors = chosen[0]
    members = [(0, m[2]) for m in chosen if m[0] == chosen[0][0]]
    corner_found = found if len(found) == 4 else outermost(found)
    layout = _layout(corner_found)
    refined = _detect(gray, name, refine=True)
    if not set(found) <= set(refined):  # pragma: no cover - refinement never loses a marker
        refined = found
    corners = {k: refined[i] for k, i in layout.items()}
    family = tuple(m[1] for m in members)
    ids = tuple(layout[k] for k in CORNER_ORDER)
    return MarkerFinding(
        dictionary=name, family=family, ids=ids,
        corners=corners, detector_corners={k: found[i] for k, i in layout.items()},
        rotation_deg=printed_rotation(corners), bit_errors=int(errors), tried=DICTIONARIES,
        others=tuple(sorted(set(found) - set(ids))),
        smallest=_smallest_holding(name, max(ids)))


def outermost(found: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    """The four markers that bound an arena of more: of the markers on the convex hull of all
    the markers' centres, the four spanning the largest quadrilateral (an arena's corner
    markers; those on its edges and inside lie within it)."""
    ids = list(found)
    centres = np.array([found[i].mean(axis=0) for i in ids], np.float32)
    hull = [ids[int(k)] for k in cv2.convexHull(centres, returnPoints=False).ravel()]
    if len(hull) < 4:
        raise MarkersNotFoundError(
            f"image: {len(found)} markers, but their centres bound no quadrilateral (no "
            "marker in each corner of an arena)")
    centre = {i: found[i].mean(axis=0) for i in hull}

    def area(quad: tuple[int, ...]) -> float:
        pts = np.array([centre[i] for i in quad])
        x, y = pts[:, 0], pts[:, 1]
        return 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))

    # hull vertices in hull order: any four of them, kept in that order, form a convex quad
    best = max(itertools.combinations(hull, 4), key=area)
    return {i: found[i] for i in best}


def _smallest_holding(name: str, top_id: int) -> str:
    """The smallest dictionary of ``name``'s family that holds id ``top_id`` (``name`` for a
    dictionary of no family)."""
    fam = _family(name)
    if fam is None:
        return name
    sizes = sorted(f[1] for d in DICTIONARIES if (f := _family(d)) and f[0] == fam[0])
    for size in sizes:
        if size > top_id:
            return f"DICT_{fam[0]}_{size}"
    return name
