"""ArUco marker search over many dictionaries, with few detection passes.

The published method runs one ``detectMarkers`` pass per predefined dictionary (21) and takes
the first that yields four markers. Measured with OpenCV 5.0 on the competition image, a pass
costs about 2.5 ms of candidate detection plus an identification cost that grows with the
dictionary's size (``DICT_4X4_50`` about 2.6 ms in all, ``DICT_4X4_1000`` about 7 ms,
``DICT_APRILTAG_36h10`` about 27 ms); one ``detectMarkersMultiDict`` call over all 22
dictionaries costs about 95 ms, the identification dominating. So this module keeps the
published *result* (the first dictionary, in order, that satisfies the selection rule) but
groups the ordered dictionaries into small *stages* (about 300 markers each; the competition's
``DICT_4X4_50`` + ``DICT_4X4_100`` form the first) and runs one multi-dictionary pass per
stage, stopping at the first stage that holds a winner. The competition image therefore costs
one pass of about 3.5 ms; a search that finds nothing costs every stage (about 100 ms).
Where OpenCV lacks ``detectMarkersMultiDict`` (before 4.11) each dictionary is its own pass.

Two more savings, both exact:

- *Nested dictionaries share a pass.* ``DICT_4X4_50`` is a prefix of ``DICT_4X4_100`` (and so
  on up to ``_1000``, for 4x4 to 7x7). OpenCV identifies a candidate as the *first* id whose
  code lies within the dictionary's correction distance (``int(maxCorrectionBits *
  errorCorrectionRate)``), so where two nested dictionaries have the same correction distance
  one pass over the larger gives the smaller one's result too: its hits with ids below the
  smaller size. Within a stage such dictionaries are merged (:func:`pass_plan`); the first
  stage is a single ``DICT_4X4_100`` pass. Merging a whole family into one ``_1000`` pass
  ("once per family") was measured and rejected: a ``DICT_4X4_1000`` pass costs about 3x a
  ``DICT_4X4_100`` pass on the competition scenes (every box is a candidate that scans the
  whole dictionary), and the ``_1000`` dictionaries of 6x6 and 7x7 correct fewer bits than
  their ``_50`` .. ``_250``, so their result would differ.
- *Too few candidates end the search.* Candidate quadrilaterals do not depend on the
  dictionary; when a pass saw fewer than four (identified plus rejected), no dictionary can
  yield four markers and the remaining stages are skipped (blank or marker-less images cost
  one pass instead of every stage).
- *Uniform candidates end the search.* When the first pass identified nothing, each
  candidate is sampled as OpenCV samples it for identification (perspective removal to
  ``(size + 2 border) x cellSize`` pixels, nearest neighbour, the inner region's standard
  deviation against ``minOtsuStdDev``): a candidate that is uniform for every marker size of
  the remaining dictionaries reads as all-white (its border fails) or all-black (identified
  only by a dictionary that accepts the all-zero code, checked with ``Dictionary.identify``).
  When no candidate can be identified, no later stage can find a marker, and the search ends
  with the same result (an image of only boxes: 1 pass instead of 14). The test is
  conservative (uniform means well under the threshold).

Detector objects are built once per (stage, parameters) and cached at module level.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from arenabench.aruco import aruco_dictionary
from arenabench.frame import COMPETITION_MARKER_IDS
from arenabench.pipeline import marker_prefilter

#: Stages hold dictionaries totalling at most this many markers (see the module docstring).
STAGE_BUDGET = 300
#: The first stage scans at most this many: the competition's DICT_4X4_100 in one small pass.
FIRST_STAGE_BUDGET = 100

_HAS_MULTI = hasattr(cv2.aruco, "ArucoDetector") and hasattr(
    cv2.aruco.ArucoDetector, "detectMarkersMultiDict"
)
_DETECTOR_CACHE: dict[tuple[str, ...], cv2.aruco.ArucoDetector] = {}


def available_dictionaries(names: Sequence[str], *, strict: bool) -> tuple[str, ...]:
    """Filter ``names`` to those the installed OpenCV defines.

    Raises
    ------
    ValueError
        With ``strict``, naming the first unknown dictionary.
    """
    out = []
    for name in names:
        if isinstance(getattr(cv2.aruco, name, None), int):
            out.append(name)
        elif strict:
            raise ValueError(f"dictionaries: unknown ArUco dictionary {name!r}")
    return tuple(out)


def plan_stages(
    names: Sequence[str], *, budget: int = STAGE_BUDGET, first_budget: int = FIRST_STAGE_BUDGET
) -> list[tuple[str, ...]]:
    """Group ordered dictionary names into consecutive stages of at most ``budget`` markers.

    A stage's size counts the markers its passes scan: nested dictionaries that share a pass
    (:func:`pass_plan`) count once, as the larger.
    """
    if not _HAS_MULTI:
        return [(n,) for n in names]
    stages: list[tuple[str, ...]] = []
    current: list[str] = []
    for name in names:
        limit = first_budget if not stages else budget
        if current and _stage_cost([*current, name]) > limit:
            stages.append(tuple(current))
            current = []
        current.append(name)
    if current:
        stages.append(tuple(current))
    return stages


def correction_bits(name: str) -> int:
    """Bits OpenCV corrects when identifying a ``name`` marker with default parameters."""
    rate = float(cv2.aruco.DetectorParameters().errorCorrectionRate)
    return int(float(aruco_dictionary(name).maxCorrectionBits) * rate)


def extends(big: str, small: str) -> bool:
    """Whether one pass over ``big`` gives ``small``'s result exactly (see the module notes).

    True when ``small``'s codes are a prefix of ``big``'s (same marker size) and both correct
    the same number of bits.
    """
    b, s = aruco_dictionary(big), aruco_dictionary(small)
    n = int(s.bytesList.shape[0])
    return (
        int(b.markerSize) == int(s.markerSize)
        and int(b.bytesList.shape[0]) >= n
        and bool(np.array_equal(b.bytesList[:n], s.bytesList))
        and correction_bits(big) == correction_bits(small)
    )


def pass_plan(stage: Sequence[str]) -> list[tuple[str, tuple[str, ...]]]:
    """Physical passes of a stage: ``(dictionary run, logical dictionaries it answers for)``.

    Consecutive dictionaries where the later extends the earlier (:func:`extends`) share one
    pass over the later.
    """
    plan: list[tuple[str, list[str]]] = []
    for name in stage:
        if plan and extends(name, plan[-1][0]):
            plan[-1] = (name, [*plan[-1][1], name])
        else:
            plan.append((name, [name]))
    return [(run, tuple(logical)) for run, logical in plan]


def _stage_cost(stage: Sequence[str]) -> int:
    return sum(int(aruco_dictionary(run).bytesList.shape[0]) for run, _ in pass_plan(stage))


def _detector(stage: tuple[str, ...]) -> cv2.aruco.ArucoDetector:
    det = _DETECTOR_CACHE.get(stage)
    if det is None:
        params = cv2.aruco.DetectorParameters()
        det = cv2.aruco.ArucoDetector(aruco_dictionary(stage[0]), params)
        if len(stage) > 1:
            det.setDictionaries([aruco_dictionary(n) for n in stage])
        _DETECTOR_CACHE[stage] = det
    return det


@dataclass
class DictionaryHits:
    """What one dictionary's identification found: ids and (4, 2) corners, cv2.aruco order."""

    dictionary: str
    ids: list[int] = field(default_factory=list)
    corners: list[np.ndarray] = field(default_factory=list)


@dataclass
class MarkerSearch:
    """Outcome of the marker search.

    ``found`` is True when a dictionary satisfied the selection rule; then ``ids`` and
    ``corners`` hold the four chosen markers. Otherwise they hold what the dictionary with the
    most detections found (possibly nothing), for reporting.
    """

    found: bool
    dictionary: str | None
    ids: list[int]
    corners: list[np.ndarray]
    source: str
    passes: int


def _run_stage(
    image: np.ndarray, stage: tuple[str, ...], quads: list[np.ndarray] | None = None
) -> tuple[list[DictionaryHits], int]:
    """Hits of every dictionary of ``stage`` and the number of candidates the pass saw
    (their corners appended to ``quads`` when given)."""
    plan = pass_plan(stage)
    runs = tuple(run for run, _ in plan)
    det = _detector(runs)
    if len(runs) == 1:
        corners, ids, rejected = det.detectMarkers(image)
        which = None if ids is None else np.zeros(len(ids), dtype=int)
    else:
        corners, ids, rejected, which = det.detectMarkersMultiDict(image)
        which = None if ids is None else np.asarray(which).ravel()
    n_found = 0 if ids is None else len(ids)
    candidates = n_found + (0 if rejected is None else len(rejected))
    if quads is not None:
        for c in (*(corners if ids is not None else ()), *(rejected or ())):
            quads.append(np.asarray(c, dtype=np.float32).reshape(4, 2))
    hits = {name: DictionaryHits(name) for name in stage}
    if n_found == 0:
        return [hits[n] for n in stage], candidates
    for c, i, w in zip(corners, np.asarray(ids).ravel(), which, strict=True):
        quad = np.asarray(c, dtype=np.float64).reshape(4, 2)
        for name in plan[int(w)][1]:
            if int(i) < int(aruco_dictionary(name).bytesList.shape[0]):
                hits[name].ids.append(int(i))
                hits[name].corners.append(quad)
    return [hits[n] for n in stage], candidates


#: A candidate counts as uniform when the standard deviation of its sampled inner region is
#: below this fraction of ``minOtsuStdDev`` (OpenCV's own test uses the whole value).
UNIFORM_STD_FRACTION = 0.5
#: Whether the search ends once no candidate can be identified (tests compare it off and on).
UNIFORM_SHORTCUT = True
_ZERO_CODE: dict[str, bool] = {}


def _zero_code_identified(name: str) -> bool:
    """Whether dictionary ``name`` identifies an all-black inner code (default parameters)."""
    hit = _ZERO_CODE.get(name)
    if hit is None:
        d = aruco_dictionary(name)
        size = int(d.markerSize)
        rate = float(cv2.aruco.DetectorParameters().errorCorrectionRate)
        hit = bool(d.identify(np.zeros((size, size), np.uint8), rate)[0])
        _ZERO_CODE[name] = hit
    return hit


def _uniform_value(image: np.ndarray, quad: np.ndarray, size: int) -> int | None:
    """0 (black) or 1 (white) when OpenCV reads candidate ``quad`` for markers of ``size``
    bits as uniform, else ``None`` (its bits depend on the content: it may be a marker)."""
    params = cv2.aruco.DetectorParameters()
    cell = int(params.perspectiveRemovePixelPerCell)
    side = (size + 2 * int(params.markerBorderBits)) * cell
    dst = np.float32([[0, 0], [side - 1, 0], [side - 1, side - 1], [0, side - 1]])
    warp = cv2.getPerspectiveTransform(quad.astype(np.float32), dst)
    sampled = cv2.warpPerspective(image, warp, (side, side), flags=cv2.INTER_NEAREST)
    inner = sampled[cell // 2 : side - cell // 2, cell // 2 : side - cell // 2]
    mean, std = cv2.meanStdDev(inner)
    m = float(mean[0, 0])
    if float(std[0, 0]) >= UNIFORM_STD_FRACTION * float(params.minOtsuStdDev) or abs(
        m - 127.5
    ) < 10.0:
        return None
    return 1 if m > 127.5 else 0


def could_identify(image: np.ndarray, quads: Sequence[np.ndarray],
                   names: Sequence[str]) -> bool:
    """Whether any candidate in ``quads`` might be identified by a dictionary of ``names``
    (``False`` only when each is provably uniform, see the module notes)."""
    if cv2.aruco.DetectorParameters().detectInvertedMarker:
        return True
    by_size: dict[int, list[str]] = {}
    for name in names:
        by_size.setdefault(int(aruco_dictionary(name).markerSize), []).append(name)
    for quad in quads:
        for size, dicts in by_size.items():
            value = _uniform_value(image, quad, size)
            if value is None or (value == 0 and any(_zero_code_identified(n) for n in dicts)):
                return True
    return False


def _quad_area(points: np.ndarray) -> float:
    hull = cv2.convexHull(points.astype(np.float32))
    return float(cv2.contourArea(hull))


def select_reference_four(hits: DictionaryHits) -> tuple[list[int], list[np.ndarray]] | None:
    """``reference`` rule: four distinct markers, or None.

    Duplicated ids keep their largest detection. With more than four distinct ids, the
    competition ids (80, 85, 90, 95) are taken when all present, else the four whose centres
    span the largest convex quadrilateral.
    """
    best: dict[int, np.ndarray] = {}
    for i, c in zip(hits.ids, hits.corners, strict=True):
        if i not in best or _quad_area(c) > _quad_area(best[i]):
            best[i] = c
    if len(best) < 4:
        return None
    ids = sorted(best)
    if len(ids) > 4:
        comp = sorted(COMPETITION_MARKER_IDS.values())
        if all(i in best for i in comp):
            ids = comp
        else:
            centres = {i: best[i].mean(axis=0) for i in ids}
            ids = list(
                max(
                    itertools.combinations(ids, 4),
                    key=lambda combo: _quad_area(np.array([centres[i] for i in combo])),
                )
            )
    return ids, [best[i] for i in ids]


def select_seed_four(hits: DictionaryHits) -> tuple[list[int], list[np.ndarray]] | None:
    """``seed`` rule (as published): exactly four detections; sorted by id."""
    if len(hits.ids) != 4:
        return None
    order = sorted(range(4), key=lambda k: hits.ids[k])
    return [hits.ids[k] for k in order], [hits.corners[k] for k in order]


def search_markers(
    image: np.ndarray, names: Sequence[str], *, rule: str, source: str, prefilter: bool = False
) -> MarkerSearch:
    """Search ``image`` (uint8, one channel) for the markers, dictionaries in ``names`` order.

    Parameters
    ----------
    image : numpy.ndarray
        Grayscale or binary uint8 image.
    names : sequence of str
        Dictionary names in search order (all must exist in OpenCV).
    rule : {"reference", "seed"}
        Selection rule (see :func:`select_reference_four`, :func:`select_seed_four`).
    source : str
        Label of the image searched (``"threshold"`` or ``"gray"``), reported back.
    prefilter : bool
        Skip the search (no pass) when :func:`.marker_prefilter.could_hold_marker` finds no
        marker-like structure, where :func:`.marker_prefilter.worth_checking` says so (grey
        and busy thresholded images, whose search of noise is costly).
    """
    if prefilter and marker_prefilter.worth_checking(image, source=source) and (
        not marker_prefilter.could_hold_marker(image)
    ):
        return MarkerSearch(False, None, [], [], source, 0)
    select = select_seed_four if rule == "seed" else select_reference_four
    most: DictionaryHits | None = None
    passes = 0
    stages = plan_stages(names)
    for k, stage in enumerate(stages):
        passes += 1
        quads: list[np.ndarray] | None = [] if k == 0 else None
        stage_hits, candidates = _run_stage(image, stage, quads)
        for hits in stage_hits:
            chosen = select(hits)
            if chosen is not None:
                return MarkerSearch(True, hits.dictionary, chosen[0], chosen[1], source, passes)
            if hits.ids and (most is None or len(set(hits.ids)) > len(set(most.ids))):
                most = hits
        if candidates < 4:  # candidates do not depend on the dictionary: none can give 4
            break
        later = [n for st in stages[k + 1 :] for n in st]
        if UNIFORM_SHORTCUT and quads is not None and most is None and later and not could_identify(
            image, quads, later
        ):
            break  # no candidate can be identified by a later dictionary: nothing to find
    if most is None:
        return MarkerSearch(False, None, [], [], source, passes)
    order = sorted(range(len(most.ids)), key=lambda k: most.ids[k])
    return MarkerSearch(
        False,
        most.dictionary,
        [most.ids[k] for k in order],
        [most.corners[k] for k in order],
        source,
        passes,
    )
