"""The twin's fit verdict: ``good`` when its render of the image is within every bound of
:data:`BOUNDS`, ``poor`` otherwise, naming each region that is off, by how much, and what the
twin could not explain there (:func:`causes`).

The bounds come from the blind round trips (``tests/twin_blind.py``, docs/measurements.md):
twins of generator renders with hidden parameters, which the twin can reproduce. A real image
outside them shows something the twin does not model (blur, noise, lens distortion, glare, the
floor beyond the markers, another feature); its preset is then a guess at that arena, and the
verdict says so instead of letting a script trust it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from arenabench.generator.fitting.regions import RegionFigures

#: The verdict's values.
GOOD, POOR = "good", "poor"


@dataclass(frozen=True)
class Bound:
    """One figure of a twin's render against its image, and the most it may be.

    Attributes
    ----------
    key : str
        The figure (:func:`figure_values`).
    limit : float
        The largest value of a good twin.
    unit : str
        The figure's unit.
    why : str
        Where the limit comes from.
    """

    key: str
    limit: float
    unit: str
    why: str


#: Every bound a good twin holds, in the order the verdict names them.
BOUNDS: tuple[Bound, ...] = (
    Bound("marker squares", 1.5, "grey levels",
          "mean absolute grey difference in the squares 8 px around the markers: the bound the "
          "blind round trips hold (their twins 0.08-1.35)"),
    Bound("worst marker", 2.5, "grey levels",
          "the same in the square of the worst marker: one marker off moves the frame a "
          "pipeline warps to"),
    Bound("detector corners", 1.5, "px",
          "the largest distance of the default cv2.aruco detector's whole-pixel corners on the "
          "render from those on the image (0 on the published example): the round trips hold "
          "1.5 (one corner a pixel off diagonally, 1.41, on twins within every tolerance)"),
    Bound("floor", 3.0, "grey levels",
          "mean absolute grey difference over the floor outside markers and boxes: JPEG "
          "rounding and the modes of 8-bit images keep a reproduced floor within 2"),
    Bound("faces", 6.0, "grey levels",
          "the same over the boxes' faces (the light's fit leaves a few grey levels on faces "
          "it sees obliquely)"),
)
#: The bounds by figure.
BOUND_OF = {b.key: b for b in BOUNDS}


@dataclass(frozen=True)
class Off:
    """A figure outside its bound.

    Attributes
    ----------
    key : str
        The figure.
    value, limit : float
        Its value and its bound.
    unit : str
        Their unit.
    """

    key: str
    value: float
    limit: float
    unit: str

    def text(self) -> str:
        """``marker squares 5.83 grey levels (bound 1.5)``."""
        if self.value == float("inf"):
            return (f"{self.key}: a marker not found on the render (bound {self.limit:g} "
                    f"{self.unit})")
        return f"{self.key} {self.value:.2f} {self.unit} (bound {self.limit:g})"


@dataclass(frozen=True)
class FitVerdict:
    """A twin's verdict.

    Attributes
    ----------
    verdict : str
        ``"good"`` or ``"poor"``.
    off : tuple of Off
        The figures outside their bounds (empty when good).
    causes : tuple of str
        What the twin could not explain, as found on the image against the render (may be
        empty for a good twin; for a poor one at least one line, "an unmodelled feature"
        when nothing more specific is found).
    """

    verdict: str
    off: tuple[Off, ...]
    causes: tuple[str, ...]

    @property
    def good(self) -> bool:
        """The twin holds every bound."""
        return self.verdict == GOOD

    def line(self) -> str:
        """One line: ``fit: good (every region within bounds)`` or ``fit: poor: ...``."""
        if self.good:
            return "fit: good (every region within the bounds the blind round trips hold)"
        off = "; ".join(o.text() for o in self.off)
        return f"fit: poor: {off}; the image shows {', '.join(self.causes)}"

    def to_dict(self) -> dict:
        """``twin.json["verdict"]``."""
        return {"verdict": self.verdict,
                "off": [{"figure": o.key,
                 "value": None if o.value == float("inf") else round(o.value, 4),
                 "bound": o.limit,
                         "unit": o.unit} for o in self.off],
                "causes": list(self.causes),
                "bounds": [{"figure": b.key, "bound": b.limit, "unit": b.unit, "why": b.why}
                           for b in BOUNDS]}


def figure_values(figures: RegionFigures) -> dict[str, float | None]:
    """The figures :data:`BOUNDS` name, from a twin's region figures (``None``: no such
    region in this image; a marker the detector missed on the render: infinitely far)."""
    corners = [float("inf") if v is None else float(v) for v in figures.detector_px.values()]
    return {
        "marker squares": figures.mad.get("markers"),
        "worst marker": max(figures.per_marker.values(), default=None),
        "detector corners": max(corners, default=None),
        "floor": figures.mad.get("floor"),
        "faces": figures.mad.get("faces"),
    }


def judge(figures: RegionFigures, real_gray: np.ndarray, render_gray: np.ndarray,
          masks: dict[str, np.ndarray], *, corner_rms_px: float | None = None) -> FitVerdict:
    """The verdict of a twin whose render is ``render_gray`` of the image ``real_gray``
    (both (H, W) uint8), with the region ``masks`` its figures were measured in."""
    values = figure_values(figures)
    off = tuple(Off(b.key, float(values[b.key]), b.limit, b.unit) for b in BOUNDS
                if values.get(b.key) is not None and not values[b.key] <= b.limit)
    if not off:
        return FitVerdict(GOOD, (), ())
    found = causes(real_gray, render_gray, masks, corner_rms_px=corner_rms_px)
    explained: set[str] = set()
    for cause in found:
        explained |= next((keys for start, keys in EXPLAINS if cause.startswith(start)), set())
    rest = [o.key for o in off if o.key not in explained]
    if rest:
        found += (f"an unmodelled feature in {', '.join(rest)} (none of blur, noise, glare, "
                  "exposure, lens distortion or the floor explains it)",)
    return FitVerdict(POOR, off, found)


#: Which figures each cause accounts for (by the start of its text): a change of the whole
#: image accounts for every region; lens distortion for the markers; the floor for itself.
EXPLAINS: tuple[tuple[str, set[str]], ...] = (
    ("blur", {b.key for b in BOUNDS}), ("edges sharper", {b.key for b in BOUNDS}),
    ("noise", {b.key for b in BOUNDS}), ("glare", {b.key for b in BOUNDS}),
    ("exposure", {b.key for b in BOUNDS}),
    ("lens distortion", {"marker squares", "worst marker", "detector corners"}),
    ("a floor unlike", {"floor"}),
)
#: How much softer (or sharper) the image's marker edges may be than the render's before the
#: difference is put down to blur (their mean gradient's ratio).
SHARPNESS_RATIO = 0.75
#: Noise (grey levels, the spread of a pixel about its 3 x 3 median on the floor) the image
#: may have beyond the render's before it is named.
NOISE_EXCESS = 1.5
#: Share of floor pixels clipped white (>= 250) in the image beyond the render's that is glare.
GLARE_SHARE = 0.01
#: Mean signed grey difference over the floor that is put down to exposure.
EXPOSURE_LEVELS = 4.0
#: RMS distance (px) of the markers' sub-pixel corners from the fitted pinhole camera beyond
#: which the camera is not a pinhole (lens distortion); the published example's is 1.1, the
#: markers touching its border line.
CORNER_RMS_PX = 1.6


def _gradient(gray: np.ndarray, mask: np.ndarray) -> float:
    """RMS gradient in ``mask``: a blur of sigma 1 px takes it to 0.77 of the sharp image's,
    sigma 3 to 0.44 (the published example's marker squares); noise hardly moves it."""
    g = gray.astype(np.float32)
    gx, gy = cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1)
    return float(np.sqrt(np.mean((gx * gx + gy * gy)[mask]))) if mask.any() else 0.0


def _noise(gray: np.ndarray, mask: np.ndarray) -> float:
    if not mask.any():
        return 0.0
    resid = gray.astype(np.float32) - cv2.medianBlur(gray, 3).astype(np.float32)
    return float(np.median(np.abs(resid[mask])) * 1.4826)


def causes(real_gray: np.ndarray, render_gray: np.ndarray, masks: dict[str, np.ndarray], *,
           corner_rms_px: float | None = None) -> tuple[str, ...]:
    """What the image shows that the render does not, each with its figure: blur (or
    sharpness), noise, glare, exposure, lens distortion, the floor beyond the markers."""
    out = []
    markers = masks.get("markers", np.zeros(real_gray.shape, bool))
    floor = masks.get("floor", np.zeros(real_gray.shape, bool))
    seen, drawn = _gradient(real_gray, markers), _gradient(render_gray, markers)
    if drawn > 0 and seen / drawn < SHARPNESS_RATIO:
        out.append(f"blur or defocus (its marker edges {seen / drawn:.2f} as sharp as the "
                   "render's; the twin renders none)")
    elif seen > 0 and drawn / seen < SHARPNESS_RATIO:
        out.append(f"edges sharper than the render's ({seen / drawn:.2f} times)")
    excess = _noise(real_gray, floor) - _noise(render_gray, floor)
    if excess > NOISE_EXCESS:
        out.append(f"noise (about {excess:.1f} grey levels more than the render's; the twin "
                   "renders none)")
    if floor.any():
        # clipped white the render does not have, thin lines left out (a printed frame's
        # white is 255 in a digital image and softened on the render: not glare)
        white = ((real_gray >= 250) & (render_gray < 250) & floor).astype(np.uint8)
        white = cv2.morphologyEx(white, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
        clipped = float(white[floor].mean())
        if clipped > GLARE_SHARE:
            out.append(f"glare ({100 * clipped:.1f} % of the floor clipped white where the "
                       "render is not)")
        shift = float(real_gray[floor].astype(np.float64).mean()
                      - render_gray[floor].astype(np.float64).mean())
        if abs(shift) > EXPOSURE_LEVELS:
            out.append(f"exposure or uneven light (the floor {shift:+.1f} grey levels from "
                       "the render's on average)")
    if corner_rms_px is not None and corner_rms_px > CORNER_RMS_PX:
        out.append(f"lens distortion or a camera that is not a pinhole (the markers' corners "
                   f"{corner_rms_px:.2f} px RMS from the fitted camera)")
    if floor.any():
        diff = np.abs(real_gray.astype(np.float64) - render_gray.astype(np.float64))
        if float(diff[floor].mean()) > BOUND_OF["floor"].limit:
            out.append(f"a floor unlike the render's ({float(diff[floor].mean()):.2f} grey "
                       "levels: lines, tapes, logos or the floor beyond the markers the twin "
                       "did not reproduce)")
    return tuple(out)
