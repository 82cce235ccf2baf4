"""Configuration of the detection pipeline: :class:`DetectConfig` and its two profiles.

Profiles
--------
``seed``
    The published write-up's method, weak spots included, so the harness can measure it as
    published: resize to 1000 x 1000, grayscale, global threshold 70, ArUco search over the
    predefined dictionaries taking the first that yields exactly four markers, corner ``k`` of
    the ``k``-th marker sorted by id (marker-local index), warp, obstacle mask = pixels whose
    inverted gray level exceeds the same threshold (gray < 255 - 70), external contours,
    ``count`` = contours larger than ``min_area``, ``total_area`` = sum of *all* contour areas.
``reference`` (default)
    The same method made sound: reference corners chosen by geometry (inner or outer, see
    :class:`arenabench.frame.FrameSpec`), so neither image rotation nor marker print
    orientation breaks it; retry of the marker search on the plain grayscale image when the
    thresholded one does not give four markers; markers, their quiet zone, pixels outside the
    input image and a thin band along the frame edges masked out of the segmentation; obstacle
    mask = colour distance from the floor (median colour of the warped arena) above an
    automatic (Otsu) or fixed threshold, opened to drop thin lines; ``total_area`` = sum of the
    counted obstacles' areas.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Literal

from arenabench.frame import FrameSpec

Profile = Literal["reference", "seed"]
AreaMethod = Literal["contour", "pixels"]

PROFILES: tuple[str, ...] = ("reference", "seed")

#: The dictionaries the published method searches, in its order (first that yields 4 wins).
PUBLISHED_DICTIONARIES: tuple[str, ...] = (
    "DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000",
    "DICT_5X5_50", "DICT_5X5_100", "DICT_5X5_250", "DICT_5X5_1000",
    "DICT_6X6_50", "DICT_6X6_100", "DICT_6X6_250", "DICT_6X6_1000",
    "DICT_7X7_50", "DICT_7X7_100", "DICT_7X7_250", "DICT_7X7_1000",
    "DICT_ARUCO_ORIGINAL",
    "DICT_APRILTAG_16h5", "DICT_APRILTAG_25h9", "DICT_APRILTAG_36h10", "DICT_APRILTAG_36h11",
)  # fmt: skip

#: Every predefined dictionary: the published ones, then newer ones where OpenCV has them.
ALL_DICTIONARIES: tuple[str, ...] = (*PUBLISHED_DICTIONARIES, "DICT_ARUCO_MIP_36h12")


def _check_int(name: str, value: Any, lo: int, hi: int | None = None) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < lo or (
        hi is not None and value > hi
    ):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise ValueError(f"{name} must be an integer {rng}, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class DetectConfig:
    """Parameters of :func:`arenabench.pipeline.detect` (frozen, keyword-only).

    Parameters
    ----------
    profile : {"reference", "seed"}
        Which method runs (see the module docstring). Default ``"reference"``.
    resize : int or None
        Side of the square the input is resized to before anything else (1000, as published);
        ``None`` keeps the input size. Reported corners and the homography always refer to
        the *input* image's pixels.
    threshold : int or None
        Global threshold (0-255) applied to the grayscale image before the marker search
        (70, as published): pixels above it become white. ``None`` runs the marker search on
        the grayscale image (ArUco's own adaptive thresholding). In the ``seed`` profile the
        same value also binarises the warped image (obstacle = gray < 255 - threshold).
    marker_fallback : bool or None
        Retry the marker search on the grayscale image when the thresholded one gives fewer
        than four markers. ``None``: on for ``reference``, off for ``seed``.
    dictionaries : tuple of str or None
        Dictionary names searched, in order; the first that yields the markers wins.
        ``None``: the published 21 for ``seed``; those plus newer ones (``ALL_DICTIONARIES``)
        that the installed OpenCV has for ``reference``.
    min_area : float
        Contours larger than this (frame px^2) count as obstacles (500, as published).
    frame : FrameSpec
        Rectified frame size and corner convention (``inner`` or ``outer``; ``seed`` takes
        fixed marker-local corners and requires ``inner``).
    obstacle_threshold : int or None
        ``reference``: colour distance from the floor (max over B, G, R of the absolute
        difference) above which a pixel is an obstacle. ``None`` = automatic (Otsu on the
        arena's distance histogram, but never below ``min_contrast``).
    min_contrast : int
        ``reference``: lower bound of the automatic obstacle threshold, so an empty arena's
        noise is not segmented (default 30).
    marker_margin_px : float
        ``reference``: each marker's mask is grown by this many frame px on every side to
        cover its white quiet zone and edge blur (default 12).
    border_margin_px : int
        ``reference``: a band this wide along the frame edges is excluded (default 2).
    open_px : int
        ``reference``: side of the square kernel of the morphological opening that removes
        lines thinner than it (the arena's border line); 0 or 1 disables (default 5).
    area_method : {"contour", "pixels"}
        How an obstacle's area is measured. ``"contour"`` (default, the competition's
        convention): ``cv2.contourArea`` of the external contour, i.e. the polygon through the
        boundary pixels' centres, about half a perimeter below the pixel count (about 1 % for a
        200 px box). ``"pixels"``: the number of pixels inside the external contour (unbiased
        against an analytic area). Both are always reported per obstacle.
    """

    profile: Profile = "reference"
    resize: int | None = 1000
    threshold: int | None = 70
    marker_fallback: bool | None = None
    dictionaries: tuple[str, ...] | None = None
    min_area: float = 500.0
    frame: FrameSpec = field(default_factory=FrameSpec)
    obstacle_threshold: int | None = None
    min_contrast: int = 30
    marker_margin_px: float = 12.0
    border_margin_px: int = 2
    open_px: int = 5
    area_method: AreaMethod = "contour"

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ValueError(f"profile must be one of {PROFILES}, got {self.profile!r}")
        if self.resize is not None:
            _check_int("resize", self.resize, 16)
        if self.threshold is not None:
            _check_int("threshold", self.threshold, 0, 255)
        if self.marker_fallback is not None and not isinstance(self.marker_fallback, bool):
            raise ValueError(
                f"marker_fallback must be a bool or None, got {self.marker_fallback!r}"
            )
        if self.dictionaries is not None:
            if isinstance(self.dictionaries, str) or not all(
                isinstance(d, str) for d in self.dictionaries
            ):
                raise ValueError(
                    f"dictionaries must be a tuple of dictionary names, got {self.dictionaries!r}"
                )
            if not self.dictionaries:
                raise ValueError("dictionaries must not be empty (None = all predefined)")
            object.__setattr__(self, "dictionaries", tuple(self.dictionaries))
        if isinstance(self.min_area, bool) or not isinstance(self.min_area, (int, float)) or not (
            self.min_area >= 0
        ):
            raise ValueError(f"min_area must be a number >= 0, got {self.min_area!r}")
        if not isinstance(self.frame, FrameSpec):
            raise ValueError(f"frame must be a FrameSpec, got {self.frame!r}")
        if self.profile == "seed" and self.frame.corners != "inner":
            raise ValueError(
                "frame.corners must be 'inner' for the seed profile (it takes fixed "
                f"marker-local corners), got {self.frame.corners!r}"
            )
        if self.obstacle_threshold is not None:
            _check_int("obstacle_threshold", self.obstacle_threshold, 1, 255)
        _check_int("min_contrast", self.min_contrast, 1, 255)
        if isinstance(self.marker_margin_px, bool) or not isinstance(
            self.marker_margin_px, (int, float)
        ) or not (0 <= self.marker_margin_px <= 1e4):
            raise ValueError(
                f"marker_margin_px must be a number >= 0, got {self.marker_margin_px!r}"
            )
        _check_int("border_margin_px", self.border_margin_px, 0)
        _check_int("open_px", self.open_px, 0, 101)
        if self.area_method not in ("contour", "pixels"):
            raise ValueError(
                f"area_method must be 'contour' or 'pixels', got {self.area_method!r}"
            )

    @classmethod
    def for_profile(cls, profile: str, **overrides: Any) -> DetectConfig:
        """The configuration of ``profile`` with ``overrides`` applied (keyword arguments)."""
        return cls(profile=profile, **overrides)  # type: ignore[arg-type]

    def with_(self, **changes: Any) -> DetectConfig:
        """A copy with ``changes`` applied (validated again)."""
        return replace(self, **changes)

    @property
    def uses_fallback(self) -> bool:
        """Whether the marker search retries on the grayscale image."""
        if self.marker_fallback is None:
            return self.profile == "reference"
        return self.marker_fallback

    @property
    def dictionary_order(self) -> tuple[str, ...]:
        """Dictionary names searched, in order (before filtering by what OpenCV has)."""
        if self.dictionaries is not None:
            return self.dictionaries
        return PUBLISHED_DICTIONARIES if self.profile == "seed" else ALL_DICTIONARIES

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form."""
        return {
            "profile": self.profile,
            "resize": self.resize,
            "threshold": self.threshold,
            "marker_fallback": self.uses_fallback,
            "dictionaries": list(self.dictionary_order),
            "min_area": float(self.min_area),
            "frame": {"size": int(self.frame.size), "corners": self.frame.corners},
            "obstacle_threshold": self.obstacle_threshold,
            "min_contrast": self.min_contrast,
            "marker_margin_px": float(self.marker_margin_px),
            "border_margin_px": self.border_margin_px,
            "open_px": self.open_px,
            "area_method": self.area_method,
        }
