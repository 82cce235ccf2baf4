"""No marker, no wait: a cheap look for marker-like structure before a grey-image marker search.

OpenCV finds marker candidates as contours of its adaptive threshold (a pixel is *dark* when
it is at least ``adaptiveThreshConstant`` grey levels below the mean of the ``w x w`` window
around it, for the windows ``adaptiveThreshWinSizeMin .. Max`` by ``Step``: 3, 13 and 23 px)
and keeps those that approximate a convex quadrilateral. On a grey image of noise that
threshold is dark at random in about half the pixels, the contours number about 50,000 per
window, and the candidate search alone costs about 90 ms of CPU (three windows of about 30 ms)
before it finds nothing.

A marker that OpenCV traces is a dark square border (one cell wide) against lighter
surroundings (its quiet zone). In the same adaptive threshold, with the same windows and the
same constant, it shows as a *dark* region holding a :data:`DARK_SIDE` x :data:`DARK_SIDE` px
square (solid: every pixel dark) next to a *light* region holding a :data:`LIGHT_SIDE` x
:data:`LIGHT_SIDE` px square (no pixel dark), the two at most :data:`GAP` px apart.
:func:`could_hold_marker` looks for such a pair (erosions and one dilation: about 5 ms of
CPU on a 1000 x 1000 image). On uniform noise the threshold is dark with probability about
0.47 per pixel, so a solid light 5 x 5 square has a probability of about 0.53**25 = 1.3e-7 per
position: none of 40 noise images (``markerless_images`` of :mod:`arenabench.eval.bench.items`,
seeds 0-39) passed; of their thresholded images (grey level 70), where dark pixels are rare
and light ones common, 1 of 40 did (then its search runs, about 25 ms). Where no pair is
found the search is skipped: no marker.

What this guarantees, and where not:

- Wherever a pair is found the search runs exactly as without this check, so its result is
  identical. Every image with box edges, arena lines or print on it has pairs, and so has a
  marker on a light quiet zone whose border band holds a 3 x 3 px square (a border of at least
  3 px, about 4.3 px when turned 45 degrees). The tests compare the results with the check on
  and off on every preset (24 scenes each), the competition example at noise levels up to
  sigma 80, sheets of one to three markers of 16 to 96 px (turned 0, 30 and 45 degrees, clean
  and noisy) and markers pasted on noise: identical, and the check passes on every one.
- Weaker noise passes more often (Gaussian noise of sigma 20 about a mid grey sometimes
  does): then the search runs as before, at its old cost.
- What is given up: a marker smaller than that alone on a structureless background, and the
  chance readings of noise (OpenCV can read a random candidate of a noise image as a valid
  code; none of the 40 noise images above gave one).
- The window of 3 px is not used: its dark pixels are the 1 px rim of dark regions, never a
  solid square. Inverted markers (``detectInvertedMarker``) switch the check off.

Which searches are checked (:func:`worth_checking`; in the ``reference`` profile only: the
``seed`` profile searches as published): every search of the grey image (the fallback, or
the first search when ``threshold`` is ``None``), and a search of the thresholded (binary)
image only where it is *busy*: more than
:data:`BUSY_FRACTION` of its horizontally adjacent pixel pairs differ (0.05 ms to count). On
the bench's noise image that is 24 %, and its search costs about 25 ms; on every preset's
scenes at most 0.6 %, on the competition example with noise of sigma 80 1.5 %, so images
with markers do not pay the check's 5 ms there.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Whether a grey-image search is checked first (the tests compare results with it off).
PREFILTER = True
#: Side (px) of the solid dark square a marker's border must hold.
DARK_SIDE = 3
#: Side (px) of the solid light square its quiet zone must hold.
LIGHT_SIDE = 5
#: A thresholded image is checked when more than this fraction of its horizontally adjacent
#: pixel pairs differ (see the module notes).
BUSY_FRACTION = 0.05
#: Largest gap (px) between the two squares (one blended edge pixel).
GAP = 1


def threshold_windows() -> tuple[int, ...]:
    """The adaptive-threshold windows of OpenCV's candidate search that the check uses: those
    wider than :data:`DARK_SIDE`, largest first (odd, as OpenCV makes them)."""
    p = cv2.aruco.DetectorParameters()
    lo, hi, step = (int(p.adaptiveThreshWinSizeMin), int(p.adaptiveThreshWinSizeMax),
                    max(1, int(p.adaptiveThreshWinSizeStep)))
    sizes = {w | 1 for w in range(lo, hi + 1, step)}
    return tuple(sorted((w for w in sizes if w > DARK_SIDE), reverse=True))


def could_hold_marker(gray: np.ndarray) -> bool:
    """Whether ``gray`` (uint8, one channel) shows a dark square next to a light one in
    OpenCV's adaptive threshold (see the module notes); ``False`` means no marker OpenCV
    could trace with a border of at least :data:`DARK_SIDE` px is there.
    """
    params = cv2.aruco.DetectorParameters()
    if params.detectInvertedMarker:
        return True
    constant = float(params.adaptiveThreshConstant)
    dark_kernel = np.ones((DARK_SIDE, DARK_SIDE), np.uint8)
    light_kernel = np.ones((LIGHT_SIDE, LIGHT_SIDE), np.uint8)
    reach = DARK_SIDE // 2 + LIGHT_SIDE // 2 + 1 + GAP  # centre to centre, either axis
    near_kernel = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    for window in threshold_windows():
        dark = cv2.adaptiveThreshold(gray, 255, cv2.ADAPTIVE_THRESH_MEAN_C,
                                     cv2.THRESH_BINARY_INV, window, constant)
        solid_dark = cv2.erode(dark, dark_kernel, borderType=cv2.BORDER_CONSTANT,
                               borderValue=0)
        if not cv2.countNonZero(solid_dark):
            continue
        solid_light = cv2.erode(cv2.bitwise_not(dark), light_kernel,
                                borderType=cv2.BORDER_CONSTANT, borderValue=0)
        if cv2.countNonZero(cv2.bitwise_and(cv2.dilate(solid_dark, near_kernel), solid_light)):
            return True
    return False


def worth_checking(image: np.ndarray, *, source: str) -> bool:
    """Whether a search of ``image`` (``source`` ``"gray"`` or ``"threshold"``) is checked
    first: always for grey images, for thresholded ones only when busy (module notes)."""
    if not PREFILTER:
        return False
    if source == "gray":
        return True
    differ = cv2.compare(image[:, 1:], image[:, :-1], cv2.CMP_NE)
    return cv2.countNonZero(differ) > BUSY_FRACTION * differ.size
