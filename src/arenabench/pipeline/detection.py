"""The pipeline itself: :func:`detect` (a pure function: no file I/O, no printing)."""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from arenabench.pipeline import geometry, markers, segmentation
from arenabench.pipeline.config import DetectConfig
from arenabench.pipeline.result import Detection, Obstacle

_DEFAULT_CONFIG = DetectConfig()


class _Clock:
    """Accumulates wall time per stage name (ms)."""

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + (now - self._t) * 1000.0
        self._t = now


def _as_bgr_or_gray(image: Any) -> tuple[np.ndarray, bool]:
    """Validate ``image``; return it as BGR (or one-channel) uint8 and whether it is gray."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f"image must be a numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(
            f"image must be uint8, got dtype {image.dtype} "
            "(arenabench.imageio.load_image converts 16-bit images)"
        )
    if image.ndim == 2:
        gray = True
    elif image.ndim == 3 and image.shape[2] in (1, 3, 4):
        gray = image.shape[2] == 1
        if image.shape[2] == 4:
            image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
        elif gray:
            image = image[:, :, 0]
    else:
        raise ValueError(f"image must be H x W, H x W x 1, 3 or 4, got shape {image.shape}")
    if image.shape[0] < 16 or image.shape[1] < 16:
        raise ValueError(f"image must be at least 16 x 16 px, got shape {image.shape}")
    return np.ascontiguousarray(image), gray


def _corners_to_input(corners: np.ndarray, s_inv: np.ndarray) -> list[list[float]]:
    return [[float(x), float(y)] for x, y in geometry.apply_homography(s_inv, corners)]


def _not_found(
    config: DetectConfig,
    search: markers.MarkerSearch,
    s_inv: np.ndarray,
    image_size: list[int],
    clock: _Clock,
    message: str,
) -> Detection:
    order = sorted(range(len(search.ids)), key=lambda k: search.ids[k])
    return Detection(
        status="markers_not_found",
        profile=config.profile,
        dictionary=search.dictionary,
        marker_ids=[int(search.ids[k]) for k in order],
        marker_corners={
            int(search.ids[k]): _corners_to_input(search.corners[k], s_inv) for k in order
        },
        reference_corners=[],
        reference_ids=[],
        homography=None,
        frame=config.frame.to_dict(),
        count=0,
        total_area=0.0,
        obstacles=[],
        image_size=image_size,
        timings_ms=dict(clock.timings),
        details={"marker_source": search.source, "marker_passes": search.passes},
        message=message,
    )


def detect(image: np.ndarray, config: DetectConfig | None = None) -> Detection:
    """Find the arena markers and the obstacles in one overhead image.

    Parameters
    ----------
    image : numpy.ndarray
        uint8 image: BGR (H x W x 3, as ``cv2.imread`` gives), BGRA (alpha ignored) or
        grayscale (H x W or H x W x 1).
    config : DetectConfig, optional
        Profile and parameters; default ``DetectConfig()`` (the ``reference`` profile).

    Returns
    -------
    Detection
        ``status`` ``ok`` with the count, total area, per-obstacle contours, homography and
        per-stage timings; or ``markers_not_found`` (count 0, area 0.0) with the ids found.

    Raises
    ------
    ValueError
        When ``image`` is not a uint8 array of a supported shape, or ``config.dictionaries``
        names a dictionary the installed OpenCV lacks.
    """
    config = _DEFAULT_CONFIG if config is None else config
    if not isinstance(config, DetectConfig):
        raise ValueError(f"config must be a DetectConfig, got {type(config).__name__}")
    clock = _Clock()
    img, is_gray = _as_bgr_or_gray(image)
    in_h, in_w = img.shape[:2]
    image_size = [int(in_w), int(in_h)]
    names = markers.available_dictionaries(
        config.dictionary_order, strict=config.dictionaries is not None
    )
    if not names:
        raise ValueError("dictionaries: none of the requested dictionaries exist in this OpenCV")

    # 1. resize
    s = np.eye(3)
    if config.resize is not None and (in_w, in_h) != (config.resize, config.resize):
        img = cv2.resize(img, (config.resize, config.resize), interpolation=cv2.INTER_LINEAR)
        s = geometry.resize_matrix((in_w, in_h), (config.resize, config.resize))
    s_inv = np.linalg.inv(s)
    clock.lap("resize")

    # 2. grayscale
    gray = img if is_gray else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    clock.lap("grayscale")

    # 3. global threshold
    if config.threshold is not None:
        _, marker_input = cv2.threshold(gray, config.threshold, 255, cv2.THRESH_BINARY)
        source = "threshold"
    else:
        marker_input, source = gray, "gray"
    clock.lap("threshold")

    # 4. markers
    # the pre-check (pipeline/marker_prefilter.py) is the reference profile's; seed: as published
    prefilter = config.profile == "reference"
    search = markers.search_markers(marker_input, names, rule=config.profile, source=source,
                                    prefilter=prefilter)
    if not search.found and config.uses_fallback and source != "gray":
        retry = markers.search_markers(gray, names, rule=config.profile, source="gray",
                                       prefilter=prefilter)
        retry.passes += search.passes
        if retry.found or len(set(retry.ids)) > len(set(search.ids)):
            search = retry
        else:
            search.passes = retry.passes
    clock.lap("markers")
    if not search.found:
        n = len(set(search.ids))
        where = f" ({search.dictionary})" if search.dictionary else ""
        return _not_found(
            config, search, s_inv, image_size, clock,
            f"found {n} marker(s){where}, need 4 in one dictionary",
        )

    # 5. reference corners and homography
    if config.profile == "seed":
        src = geometry.corners_by_index(search.corners)
        ref_ids = list(search.ids)
    else:
        src, ref_ids = geometry.corners_by_geometry(
            search.ids, search.corners, config.frame.corners
        )
        if not geometry.quad_is_sound(src):
            return _not_found(
                config, search, s_inv, image_size, clock,
                "the four markers do not form a convex quadrilateral",
            )
    h_frame = geometry.frame_homography(src, config.frame)
    if not np.all(np.isfinite(h_frame)):
        return _not_found(
            config, search, s_inv, image_size, clock, "degenerate marker geometry"
        )
    h_input = h_frame @ s
    h_input = h_input / h_input[2, 2]
    clock.lap("homography")

    size = int(config.frame.size)
    details: dict[str, Any] = {"marker_source": search.source, "marker_passes": search.passes}
    if config.profile == "seed":
        # 6. warp, 7. segmentation (as published)
        warped = cv2.warpPerspective(gray, h_frame, (size, size))
        clock.lap("warp")
        seed_threshold = 70 if config.threshold is None else int(config.threshold)
        mask = segmentation.seed_mask(warped, seed_threshold)
        clock.lap("segment")
    else:
        bgr = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if is_gray else img
        quads = [geometry.apply_homography(h_frame, c) for c in search.corners]
        keep = segmentation.exclusion_mask(
            size,
            marker_quads_frame=quads,
            marker_margin_px=float(config.marker_margin_px),
            border_margin_px=config.border_margin_px,
        )
        floor = segmentation.estimate_floor(bgr, h_frame, size, keep)
        if floor is None:
            return _not_found(
                config, search, s_inv, image_size, clock, "the arena lies outside the image"
            )
        dist = segmentation.floor_distance(bgr, floor)
        clock.lap("segment")
        # Frame pixels outside the image get distance 0, i.e. floor: never obstacles.
        dist_frame = cv2.warpPerspective(dist, h_frame, (size, size), borderValue=0)
        clock.lap("warp")
        mask, threshold = segmentation.threshold_distance(
            dist_frame,
            keep,
            obstacle_threshold=config.obstacle_threshold,
            min_contrast=config.min_contrast,
            open_px=config.open_px,
        )
        details.update({"floor_bgr": list(floor), "obstacle_threshold": threshold})
        clock.lap("segment")

    # 8. contours, count, area
    blobs = segmentation.measure_contours(mask)

    def measure(b: segmentation.Blob) -> float:
        return float(b.pixel_area) if config.area_method == "pixels" else b.contour_area

    counted = [b for b in blobs if measure(b) > config.min_area]
    if config.profile == "seed":
        total = float(sum(b.contour_area for b in blobs))
    else:
        total = float(sum(measure(b) for b in counted))
    obstacles = [
        Obstacle(
            contour=[[float(x), float(y)] for x, y in b.contour],
            area=b.contour_area,
            pixel_area=b.pixel_area,
        )
        for b in counted
    ]
    details["contours"] = len(blobs)
    clock.lap("contours")

    return Detection(
        status="ok",
        profile=config.profile,
        dictionary=search.dictionary,
        marker_ids=sorted(int(i) for i in search.ids),
        marker_corners={
            int(i): _corners_to_input(c, s_inv)
            for i, c in sorted(zip(search.ids, search.corners, strict=True), key=lambda t: t[0])
        },
        reference_corners=_corners_to_input(src, s_inv),
        reference_ids=[int(i) for i in ref_ids],
        homography=[[float(v) for v in row] for row in h_input],
        frame=config.frame.to_dict(),
        count=len(counted),
        total_area=total,
        obstacles=obstacles,
        image_size=image_size,
        timings_ms=dict(clock.timings),
        details=details,
    )
