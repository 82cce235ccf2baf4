"""Synthetic arenas drawn with OpenCV, with exact (analytic) truth, for pipeline tests.

The drawing is fronto-parallel: the arena is an axis-aligned square, a marker from
``cv2.aruco.generateImageMarker`` in each corner (competition layout by default: ids 80 NW,
85 NE, 90 SE, 95 SW, printed upside down unless ``upright=True``), a white quiet zone around
each marker, a thin dark border line along the arena's outer edge, a near-white floor and a
grey background. Obstacles are given in *inner-frame* px (1000 units between the markers'
inner corners, x east, y south) and filled with each pixel's covered fraction (supersampled), so
pixel coverage matches the polygon (pixel centres at integer coordinates).

Truth is computed from the drawing geometry, never from pixels: ``area_px`` is the polygons'
exact area in the requested frame's px; ``contour_area_px`` is the area of the polygons inset
by half a frame pixel, which is what ``cv2.contourArea`` of a traced mask measures (the
contour runs through the boundary pixels' centres).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from shapely.geometry import Polygon

from arenabench.frame import FrameSpec

COMPETITION_IDS = (80, 85, 90, 95)  # NW, NE, SE, SW


@dataclass(frozen=True)
class Box:
    """A filled rectangle in inner-frame px: centre, size (w along x, h along y), angle."""

    cx: float
    cy: float
    w: float
    h: float
    angle_deg: float = 0.0
    color: tuple[int, int, int] = (100, 100, 100)

    def polygon(self) -> np.ndarray:
        """Corners (4, 2), inner-frame px."""
        a = np.deg2rad(self.angle_deg)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [self.w / 2, self.h / 2]
        return half @ rot.T + [self.cx, self.cy]


@dataclass
class ArenaTruth:
    """What the drawing holds, computed analytically."""

    count: int
    area_px: float
    contour_area_px: float
    marker_ids: list[int]
    frame: FrameSpec
    reference_corners_image: np.ndarray
    homography: np.ndarray
    polygons_frame: list[np.ndarray] = field(default_factory=list)


def _map(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.hstack([np.asarray(pts, float), np.ones((len(pts), 1))]) @ h.T
    return p[:, :2] / p[:, 2:3]


_SS = 8  # supersampling factor of obstacle edges


def _fill_polygon(img: np.ndarray, poly: np.ndarray, color: Sequence[int]) -> None:
    """Blend ``color`` into ``img`` with each pixel's exact-ish coverage by ``poly``.

    The polygon is filled at ``_SS`` x resolution and area-averaged down, so a pixel's weight
    is the fraction of its square covered (OpenCV's own anti-aliased fill grows polygons by
    about half a pixel).
    """
    x0, y0 = np.floor(poly.min(axis=0)).astype(int) - 2
    x1, y1 = np.ceil(poly.max(axis=0)).astype(int) + 2
    w, h = x1 - x0 + 1, y1 - y0 + 1
    hi = np.zeros((h * _SS, w * _SS), dtype=np.uint8)
    local = (poly - [x0, y0] + 0.5) * _SS - 0.5  # pixel-centre convention at both scales
    cv2.fillPoly(hi, [np.round(local * 16).astype(np.int32)], 255, lineType=cv2.LINE_8,
                 shift=4)
    cover = cv2.resize(hi.astype(np.float32) / 255.0, (w, h), interpolation=cv2.INTER_AREA)
    roi = img[y0 : y1 + 1, x0 : x1 + 1].astype(np.float32)
    out = roi * (1.0 - cover[:, :, None]) + np.asarray(color, np.float32) * cover[:, :, None]
    img[y0 : y1 + 1, x0 : x1 + 1] = np.clip(np.round(out), 0, 255).astype(np.uint8)


def draw_arena(
    *,
    size: int = 1000,
    margin: int = 100,
    marker_side: int = 60,
    upright: bool = False,
    obstacles: Sequence[Box] = (),
    rotate: int = 0,
    ids: Sequence[int] = COMPETITION_IDS,
    dictionary: str = "DICT_4X4_100",
    border_line: bool = True,
    floor: int = 248,
    background: int = 225,
    frame: FrameSpec | None = None,
) -> tuple[np.ndarray, ArenaTruth]:
    """Draw a synthetic arena; return ``(bgr_image, truth)``.

    Parameters
    ----------
    size : int
        Image side in px.
    margin : int
        Distance from the image edge to the arena's outer edge.
    marker_side : int
        Marker side in px (a multiple of the marker's cell count keeps cells crisp).
    upright : bool
        Markers printed upright (corner 0 = outer corner) instead of upside down.
    obstacles : sequence of Box
        Obstacles in inner-frame px; they must not overlap each other or the markers.
    rotate : int
        Rotate the finished image counter-clockwise by 0, 90, 180 or 270 degrees.
    ids : sequence of 4 int
        Marker ids at NW, NE, SE, SW.
    dictionary : str
        ``cv2.aruco`` dictionary name.
    border_line : bool
        Draw the thin dark line along the arena's outer edge.
    floor, background : int
        Gray levels of the arena floor and of the surroundings.
    frame : FrameSpec, optional
        Frame the truth refers to (default inner, 1000 px).
    """
    if rotate not in (0, 90, 180, 270):
        raise ValueError(f"rotate must be 0, 90, 180 or 270, got {rotate!r}")
    frame = frame or FrameSpec()
    m = int(marker_side)
    a0 = margin - 0.5  # arena outer edge, continuous coords (pixel centres at integers)
    a1 = size - margin - 0.5
    img = np.full((size, size, 3), background, dtype=np.uint8)
    pad = 30
    cv2.rectangle(img, (margin - pad, margin - pad), (size - margin + pad - 1,) * 2,
                  (floor,) * 3, thickness=-1)
    if border_line:
        cv2.rectangle(img, (margin, margin), (size - margin - 1,) * 2, (40, 40, 40), 2)
    aruco_dict = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    origins = {  # top-left pixel of each marker
        "nw": (margin, margin),
        "ne": (size - margin - m, margin),
        "se": (size - margin - m, size - margin - m),
        "sw": (margin, size - margin - m),
    }
    qz = max(m // 6, 2)
    for x, y in origins.values():
        cv2.rectangle(img, (x - qz, y - qz), (x + m + qz - 1, y + m + qz - 1), (255,) * 3, -1)
    for (_corner, (x, y)), mid in zip(origins.items(), ids, strict=True):
        marker = cv2.aruco.generateImageMarker(aruco_dict, int(mid), m)
        if not upright:
            marker = np.rot90(marker, 2)
        img[y : y + m, x : x + m] = marker[:, :, None]

    inner = np.array([[a0 + m, a0 + m], [a1 - m, a0 + m], [a1 - m, a1 - m], [a0 + m, a1 - m]])
    outer = np.array([[a0, a0], [a1, a0], [a1, a1], [a0, a1]])
    frame_px = frame.corners_px()
    h_inner_frame_to_img = cv2.getPerspectiveTransform(
        (np.array([[0, 0], [1000, 0], [1000, 1000], [0, 1000]], float)).astype(np.float32),
        inner.astype(np.float32),
    ).astype(float)
    ref = inner if frame.corners == "inner" else outer
    h_img_to_frame = cv2.getPerspectiveTransform(
        ref.astype(np.float32), frame_px.astype(np.float32)
    ).astype(float)

    polys_frame = []
    area = contour_area = 0.0
    for box in obstacles:
        poly_img = _map(h_inner_frame_to_img, box.polygon())
        _fill_polygon(img, poly_img, box.color)
        pf = _map(h_img_to_frame, poly_img)
        polys_frame.append(pf)
        shp = Polygon(pf).intersection(Polygon(frame_px))
        area += shp.area
        contour_area += shp.buffer(-0.5, join_style="mitre").area

    k = rotate // 90
    if k:
        img = np.ascontiguousarray(np.rot90(img, k))
        # np.rot90 counter-clockwise: pixel (x, y) goes to (y, W - 1 - x), applied k times.
        rot = np.eye(3)
        step = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, size - 1.0], [0.0, 0.0, 1.0]])
        for _ in range(k):
            rot = step @ rot
        ref = _map(rot, ref)
        h_img_to_frame = h_img_to_frame @ np.linalg.inv(rot)
    truth = ArenaTruth(
        count=len(obstacles),
        area_px=float(area),
        contour_area_px=float(contour_area),
        marker_ids=sorted(int(i) for i in ids),
        frame=frame,
        reference_corners_image=ref,
        homography=h_img_to_frame / h_img_to_frame[2, 2],
        polygons_frame=polys_frame,
    )
    return img, truth


#: A layout used by several tests: two axis-aligned boxes and one rotated box.
STANDARD_BOXES = (
    Box(250, 300, 260, 160),
    Box(700, 720, 200, 240, color=(90, 110, 130)),
    Box(640, 260, 220, 140, angle_deg=30, color=(120, 120, 120)),
)
