"""Tiny OpenCV-drawn arenas with exact ground truth, and a simple detector for them.

Drawn with ``tests/drawing.py`` (fronto-parallel, competition marker layout, exact analytic
truth); boxes are dark and rotated, and the floor brightness varies (``light.gain``).

Run as a script it is a competition-style pipeline: ``toy_arena.py --image PATH`` writes
``obstacles.txt`` into the working directory (exit 3 when markers are not found).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import cv2
import numpy as np

IDS = {"nw": 80, "ne": 85, "se": 90, "sw": 95}


def _dictionary():
    return cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_100)


def draw_toy_arena(
    rng: np.random.Generator, *, n_boxes: int, gain: float
) -> tuple[np.ndarray, dict]:
    """Draw one arena with tests/drawing.py; returns (BGR image, GT dict in the
    arenabench.gt/1 layout). ``gain`` scales the floor brightness."""
    from drawing import Box, draw_arena  # tests/ is on sys.path (pytest's pythonpath option)

    boxes: list[Box] = []
    tries = 0
    while len(boxes) < n_boxes and tries < 1000:
        tries += 1
        w, h = (float(v) for v in rng.uniform(120, 260, size=2))
        cx, cy = (
            float(v)
            for v in rng.uniform(80 + max(w, h) / 2 * 1.42, 920 - max(w, h) / 2 * 1.42, size=2)
        )
        r = max(w, h) / 2 * 1.42 + 25
        if any(
            abs(cx - b.cx) < r + max(b.w, b.h) / 2 * 1.42
            and abs(cy - b.cy) < r + max(b.w, b.h) / 2 * 1.42
            for b in boxes
        ):
            continue
        shade = int(rng.integers(20, 70))
        angle = float(rng.uniform(0, 90))
        boxes.append(Box(cx, cy, w, h, angle_deg=angle, color=(shade, shade, shade)))
    image, truth = draw_arena(
        obstacles=boxes, floor=round(248 * gain), background=round(225 * gain)
    )
    inverse = np.linalg.inv(truth.homography)
    obstacles = []
    for poly in truth.polygons_frame:
        pts = np.hstack([poly, np.ones((len(poly), 1))]) @ inverse.T
        image_poly = (pts[:, :2] / pts[:, 2:3]).tolist()
        area = float(abs(cv2.contourArea(poly.astype(np.float32))))
        obstacles.append(
            {
                "shape": "box",
                "image_polygon_px": image_poly,
                "footprint_frame_px": poly.tolist(),
                "visible_frame_px": poly.tolist(),
                "footprint_area_px": area,
                "visible_area_px": area,
                "in_view": True,
            }
        )
    gt = {
        "schema": "arenabench.gt/1",
        "image_size": [image.shape[1], image.shape[0]],
        "preset": "toy",
        "count": truth.count,
        "components": truth.count,
        "area": {"visible_px": truth.area_px, "footprint_px": truth.area_px},
        "frame": truth.frame.to_dict(),
        "homography": truth.homography.tolist(),
        "markers": [
            {"dictionary": "DICT_4X4_100", "id": i, "in_view": True} for i in truth.marker_ids
        ],
        "obstacles": obstacles,
        "params": {"obstacles.count": float(n_boxes), "light.gain": float(gain)},
    }
    return image, gt


def write_toy_dataset(root: Path, *, n: int = 8, seed: int = 0) -> Path:
    """Write ``n`` toy arenas as a dataset folder (manifest.jsonl, images/, gt/)."""
    rng = np.random.default_rng(seed)
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "gt").mkdir(exist_ok=True)
    lines = []
    for i in range(n):
        ident = f"{i:06d}"
        image, gt = draw_toy_arena(rng, n_boxes=i % 4, gain=float(rng.uniform(0.7, 1.0)))
        gt.update({"id": ident, "image": f"images/{ident}.png", "seed": seed})
        ok, png = cv2.imencode(".png", image)
        assert ok
        gt_bytes = json.dumps(gt).encode("utf-8")
        (root / "images" / f"{ident}.png").write_bytes(png.tobytes())
        (root / "gt" / f"{ident}.json").write_bytes(gt_bytes)
        lines.append(
            json.dumps(
                {
                    "id": ident,
                    "image": f"images/{ident}.png",
                    "gt": f"gt/{ident}.json",
                    "image_sha256": hashlib.sha256(png.tobytes()).hexdigest(),
                    "gt_sha256": hashlib.sha256(gt_bytes).hexdigest(),
                }
            )
        )
    (root / "manifest.jsonl").write_text("\n".join(lines) + "\n")
    return root


def detect(image: np.ndarray) -> dict:
    """Find the four markers, warp to the 1000 x 1000 frame, count and measure dark blobs."""
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    detector = cv2.aruco.ArucoDetector(_dictionary(), cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(gray)
    found = (
        {}
        if ids is None
        else {int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), corners, strict=False)}
    )
    if not all(v in found for v in IDS.values()):
        return {"status": "markers_not_found", "count": 0, "area": 0.0, "marker_ids": sorted(found)}
    centre = np.mean([found[v].mean(axis=0) for v in IDS.values()], axis=0)
    src = []
    for name in ("nw", "ne", "se", "sw"):
        pts = found[IDS[name]]
        src.append(pts[np.argmin(np.linalg.norm(pts - centre, axis=1))])
    dst = np.array([[0, 0], [1000, 0], [1000, 1000], [0, 1000]], dtype=np.float32)
    H = cv2.getPerspectiveTransform(np.array(src, dtype=np.float32), dst)
    top = cv2.warpPerspective(gray, H, (1000, 1000))
    mask = (top < 100).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    areas = [cv2.contourArea(c) for c in contours if cv2.contourArea(c) > 200]
    return {
        "status": "ok",
        "count": len(areas),
        "area": float(sum(areas)),
        "marker_ids": sorted(found),
    }


def obstacles_text(result: dict, *, area_key: str = "Area") -> str:
    """Competition obstacles.txt text of a result."""
    ids = ", ".join(str(i) for i in result["marker_ids"])
    return f"Aruco ID: [{ids}]\nObstacles: {result['count']}\n{area_key}: {result['area']}\n"


def main(argv: list[str] | None = None, *, area_key: str = "Area") -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--image", required=True)
    args = parser.parse_args(argv)
    image = cv2.imread(args.image)
    if image is None:
        print(f"cannot read {args.image}", file=sys.stderr)
        return 1
    result = detect(image)
    Path("obstacles.txt").write_text(obstacles_text(result, area_key=area_key))
    print(json.dumps(result))
    return 3 if result["status"] != "ok" else 0


if __name__ == "__main__":
    sys.exit(main())
