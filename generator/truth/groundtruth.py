"""Analytic ground truth (docs/ground-truth.md): geometry only, never read from pixels.

- Image -> frame homography ``H = world_to_frame @ inv(K [r1 r2 t])`` (floor plane z = 0).
- Visible silhouette of a box: its vertices projected from the camera centre onto z = 0
  (floor vertices stay put), convex hull, clipped to the frame square.
- ``count``: obstacles whose footprint overlaps the frame; ``components``: connected pieces of
  the union of visible silhouettes; areas are unions, in frame px.
- ``area.contour_px``: what ``cv2.contourArea`` of the external contours of the pixelated
  visible silhouettes gives (:func:`contour_area`).
"""

from __future__ import annotations

import copy
import functools
from typing import Any

import cv2
import numpy as np
import shapely
from shapely.geometry import MultiPoint, Polygon, box

from arenabench.fileio import rounded
from arenabench.frame import CORNER_ORDER, FrameSpec
from arenabench.generator.model import camera as cam
from arenabench.generator.model.distractors import occluded_fractions
from arenabench.generator.model.layout import (
    IN_VIEW_MARGIN_PX,
    MARKER_Z,
    box_footprint,
    box_vertices,
    marker_corners_world,
    world_to_frame,
)
from arenabench.generator.model.lens import densify, distort_points
from arenabench.generator.model.scene import Scene

#: Significant digits kept for matrices (homography, K, pose).
SIGNIFICANT_DIGITS = 12


def significant(a: np.ndarray, digits: int = SIGNIFICANT_DIGITS) -> list:
    """Nested lists of ``a``'s values rounded to ``digits`` significant digits."""
    def one(v: float) -> float:
        v = float(f"{float(v):.{digits}g}")
        return 0.0 if v == 0 else v

    return [significant(row, digits) for row in a] if np.ndim(a) > 1 else [one(v) for v in a]


def _apply(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.column_stack([pts, np.ones(len(pts))]) @ h.T
    return p[:, :2] / p[:, 2:3]


def _coords(geom) -> list[list[float]]:
    """Exterior ring (without the closing point) of a polygon; [] when empty or not a polygon."""
    if geom.is_empty:
        return []
    if geom.geom_type != "Polygon":
        geom = max(getattr(geom, "geoms", []), key=lambda g: g.area, default=None)
        if geom is None or geom.geom_type != "Polygon":
            return []
    return [list(p) for p in np.asarray(geom.exterior.coords)[:-1]]


def image_to_frame_homography(scene: Scene, frame: FrameSpec | None = None) -> np.ndarray:
    """3x3 homography from image px to frame px, normalised so that ``H[2, 2] = 1``."""
    K = cam.intrinsics(scene.camera)
    pose = cam.world_from_camera(scene.camera)
    h = world_to_frame(scene.arena, scene.markers, frame) @ np.linalg.inv(
        cam.floor_homography(K, pose)
    )
    return h / h[2, 2]


def visible_silhouette_world(scene: Scene, index: int) -> np.ndarray:
    """Floor points (x, y) hidden by obstacle ``index``: projected vertices, shape (8, 2).

    Raises
    ------
    ValueError
        When the camera is not above the obstacle's top.
    """
    ob = scene.obstacles[index]
    c = cam.world_from_camera(scene.camera)[:3, 3]
    if c[2] <= ob.height_m:
        raise ValueError(
            f"camera height {c[2]:.3f} m is not above obstacle {index} (height {ob.height_m} m)"
        )
    v = box_vertices(ob)
    t = c[2] / (c[2] - v[:, 2])
    return c[None, :2] + (v[:, :2] - c[None, :2]) * t[:, None]


def _polygons(geom) -> list[Polygon]:
    """The polygons of a (multi)polygon or collection; lines and points are dropped."""
    if geom.is_empty:
        return []
    parts = getattr(geom, "geoms", [geom])
    return [g for g in parts if g.geom_type == "Polygon" and not g.is_empty]


def contour_area(geom) -> float:
    """What ``cv2.contourArea`` summed over the external contours of ``geom`` gives once it is
    pixelated in the frame (pixel (i, j) set when its centre (i, j) lies inside).

    An external contour runs through the centres of the boundary pixels and fills holes. By
    Pick's theorem its area is the pixel count less half the number of boundary pixels, less
    one; the boundary pixels along an edge (dx, dy) number ``max(|dx|, |dy|)`` (one per column
    or row, whichever is more), and a closed outline has about four fewer. So, per connected
    piece: the area inside its outer ring, less half the ring's length in the max norm, plus 1.
    Checked against rasterised ground truth in
    ``tests/generator/truth/test_groundtruth_contour.py``.

    Parameters
    ----------
    geom : shapely geometry
        Polygon or MultiPolygon in frame px.

    Returns
    -------
    float
        Frame px (each piece counts at least 0).
    """
    total = 0.0
    for part in _polygons(geom):
        ring = np.asarray(part.exterior.coords)
        steps = float(np.abs(np.diff(ring, axis=0)).max(axis=1).sum())
        total += max(Polygon(part.exterior).area - steps / 2 + 1.0, 0.0)
    return total


def _components(geom) -> int:
    if geom.is_empty:
        return 0
    return len(geom.geoms) if hasattr(geom, "geoms") else 1


def compute_ground_truth(scene: Scene, *, frame: FrameSpec | None = None) -> dict[str, Any]:
    """Ground truth of ``scene`` (the geometric part of the GT file, floats rounded).

    Parameters
    ----------
    scene : Scene
        The scene description.
    frame : FrameSpec, keyword-only
        Rectified frame size and corner convention (default 1000 px, inner corners).

    Returns
    -------
    dict
        Keys ``image_size``, ``scene``, ``count``, ``components``, ``area`` (``visible_px``,
        ``footprint_px``, ``contour_px``), ``frame``,
        ``homography``, ``camera``, ``markers``, ``obstacles`` (docs/ground-truth.md); a
        new dict each call (the caller may change it).

    Notes
    -----
    The result is a pure function of ``scene`` and ``frame``; the last few are kept, so the
    points of a sweep that vary only post-render parameters compute each scene's GT once.
    """
    return copy.deepcopy(_ground_truth(scene, frame or FrameSpec()))


@functools.lru_cache(maxsize=4)
def _ground_truth(scene: Scene, frame: FrameSpec) -> dict[str, Any]:
    K = cam.intrinsics(scene.camera)
    pose = cam.world_from_camera(scene.camera)
    rvec, tvec = cam.rvec_tvec(pose)
    dist = np.asarray(scene.camera.dist, dtype=np.float64)
    image_box = box(-0.5, -0.5, scene.camera.width - 0.5, scene.camera.height - 0.5)
    w, h = scene.camera.width, scene.camera.height
    w2f = world_to_frame(scene.arena, scene.markers, frame)
    homography = image_to_frame_homography(scene, frame)
    frame_box = box(0.0, 0.0, float(frame.size), float(frame.size))

    def inside(px: np.ndarray, margin: float = 0.0) -> bool:
        return bool(
            np.all(px[:, 0] >= -0.5 + margin) and np.all(px[:, 0] <= w - 0.5 - margin)
            and np.all(px[:, 1] >= -0.5 + margin) and np.all(px[:, 1] <= h - 0.5 - margin)
        )

    obstacles, footprints, visibles, hidden = [], [], [], []
    count = 0
    for i, ob in enumerate(scene.obstacles):
        fp = Polygon(_apply(w2f, box_footprint(ob)))
        silhouette = visible_silhouette_world(scene, i)
        hidden.append(MultiPoint(silhouette).convex_hull)
        vis = MultiPoint(_apply(w2f, silhouette)).convex_hull
        fp_in, vis_in = fp.intersection(frame_box), vis.intersection(frame_box)
        if fp_in.area > 0:
            count += 1
        footprints.append(fp_in)
        visibles.append(vis_in)
        img_pts, _ = cv2.projectPoints(box_vertices(ob), rvec, tvec, K, dist)
        img_pts = img_pts.reshape(-1, 2)
        hull = MultiPoint(img_pts).convex_hull
        if np.any(dist):
            # A distorted hull has curved edges: densify the pinhole hull, then distort it.
            pin, _ = cv2.projectPoints(box_vertices(ob), rvec, tvec, K, np.zeros(5))
            ring = np.asarray(MultiPoint(pin.reshape(-1, 2)).convex_hull.exterior.coords)[:-1]
            hull = Polygon(distort_points(densify(ring, step_px=4.0), K, dist))
        obstacles.append({
            "shape": "box",
            "center_m": list(ob.center_m),
            "yaw_deg": ob.yaw_deg,
            "size_m": [ob.length_m, ob.width_m, ob.height_m],
            "color_rgb": list(ob.color_rgb),
            "footprint_frame_px": _coords(fp_in),
            "visible_frame_px": _coords(vis_in),
            "image_polygon_px": _coords(hull),
            "footprint_area_px": fp_in.area,
            "visible_area_px": vis_in.area,
            "in_view": inside(img_pts),
        })
    vis_union = shapely.union_all(visibles) if visibles else Polygon()
    fp_union = shapely.union_all(footprints) if footprints else Polygon()

    markers = []
    # a marker is hidden by floor patches and by boxes (what a box hides of the floor: a box
    # centred on a marker leaves none of it to detect)
    occluded = occluded_fractions(scene.arena, scene.markers, scene.patches, hidden=hidden)
    for corner, marker_id, occ in zip(CORNER_ORDER, scene.markers.ids, occluded, strict=True):
        xy = marker_corners_world(scene.arena, scene.markers, corner)
        pts = np.column_stack([xy, np.full(4, MARKER_Z)])
        px, _ = cv2.projectPoints(pts, rvec, tvec, K, dist)
        px = px.reshape(4, 2)
        quad = Polygon(px)
        in_view = inside(px, IN_VIEW_MARGIN_PX)
        markers.append({
            "dictionary": scene.markers.dictionary, "id": int(marker_id), "corner": corner,
            "corners_px": px, "in_view": in_view,
            "in_view_fraction": (quad.intersection(image_box).area / quad.area
                                 if quad.is_valid and quad.area > 0 else 0.0),
            "occluded_fraction": occ,
            "visible": bool(in_view and occ == 0.0),
        })

    gt = rounded({
        "image_size": [w, h],
        "scene": scene.to_dict(),
        "count": count,
        "components": _components(vis_union),
        "area": {"visible_px": vis_union.area, "footprint_px": fp_union.area,
                 "contour_px": contour_area(vis_union)},
        "frame": frame.to_dict(),
        "markers": markers,
        "obstacles": obstacles,
    })
    # Matrices keep significant digits: the homography's last row is ~1e-4 .. 1e-7.
    gt["homography"] = significant(homography)
    gt["camera"] = {"K": significant(K), "dist": significant(dist),
                    "world_from_camera": significant(pose)}
    # The homography maps the undistorted (pinhole) image to the frame: undistort image points
    # with K and dist first (cv2.undistortPoints(..., P=K)), then apply it.
    gt["homography_domain"] = "undistorted"
    return gt
