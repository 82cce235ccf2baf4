"""Tiny OpenCV-drawn arenas with exact ground truth, and a simple detector for them.

Drawn fronto-parallel: markers of 60 px (rotated 180 degrees, ids 80/85/90/95 of
DICT_4X4_100) whose inner corners sit at (100, 100), (600, 100), (600, 600), (100, 600), so
the rectified 1000 x 1000 frame has exactly 2 frame px per image px (4 px^2 per image px^2).
Boxes are axis-aligned dark rectangles; their GT area is exact (w * h * 4).

Run as a script it is a competition-style pipeline: ``toy_arena.py --image PATH`` writes
``obstacles.txt`` into the working directory (exit 3 when markers are not found).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

IDS = {"nw": 80, "ne": 85, "se": 90, "sw": 95}
MARKER = 60
INNER = {"nw": (100, 100), "ne": (600, 100), "se": (600, 600), "sw": (100, 600)}
SIZE = 700
SCALE = 1000 / 500


def _dictionary():
    return cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_100)


def draw_toy_arena(
    rng: np.random.Generator, *, n_boxes: int, gain: float
) -> tuple[np.ndarray, dict]:
    """Draw one arena; returns (BGR image, GT dict in the arenabench.gt/1 layout)."""
    floor = round(200 * gain)
    image = np.full((SIZE, SIZE, 3), floor, dtype=np.uint8)
    markers = []
    for corner, (ix, iy) in INNER.items():
        x0 = ix - MARKER if corner in ("nw", "sw") else ix
        y0 = iy - MARKER if corner in ("nw", "ne") else iy
        tile = cv2.aruco.generateImageMarker(_dictionary(), IDS[corner], MARKER)
        tile = np.rot90(tile, 2)
        image[y0 : y0 + MARKER, x0 : x0 + MARKER] = tile[:, :, None]
        # cv2.aruco corner order of a 180-degree-rotated marker: BR, BL, TL, TR
        x1, y1 = x0 + MARKER, y0 + MARKER
        corners = [[x1, y1], [x0, y1], [x0, y0], [x1, y0]]
        markers.append(
            {
                "dictionary": "DICT_4X4_100",
                "id": IDS[corner],
                "corners_px": corners,
                "in_view": True,
            }
        )
    boxes: list[tuple[int, int, int, int]] = []
    tries = 0
    while len(boxes) < n_boxes and tries < 1000:
        tries += 1
        w, h = (int(v) for v in rng.integers(40, 110, size=2))
        x = int(rng.integers(115, 585 - w))
        y = int(rng.integers(115, 585 - h))
        if any(
            x < bx + bw + 12 and bx < x + w + 12 and y < by + bh + 12 and by < y + h + 12
            for bx, by, bw, bh in boxes
        ):
            continue
        boxes.append((x, y, w, h))
    obstacles = []
    for x, y, w, h in boxes:
        shade = int(rng.integers(20, 70))
        image[y : y + h, x : x + w] = (shade, shade, shade)
        poly = [[x, y], [x + w, y], [x + w, y + h], [x, y + h]]
        frame = [[(px - 100) * SCALE, (py - 100) * SCALE] for px, py in poly]
        area = float(w * h * SCALE * SCALE)
        obstacles.append(
            {
                "shape": "box",
                "image_polygon_px": poly,
                "footprint_frame_px": frame,
                "visible_frame_px": frame,
                "footprint_area_px": area,
                "visible_area_px": area,
                "in_view": True,
            }
        )
    total = float(sum(o["footprint_area_px"] for o in obstacles))
    H = [[SCALE, 0.0, -100 * SCALE], [0.0, SCALE, -100 * SCALE], [0.0, 0.0, 1.0]]
    gt = {
        "schema": "arenabench.gt/1",
        "image_size": [SIZE, SIZE],
        "preset": "toy",
        "count": len(obstacles),
        "components": len(obstacles),
        "area": {"visible_px": total, "footprint_px": total},
        "frame": {"size": [1000, 1000], "corners": "inner"},
        "homography": H,
        "markers": markers,
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
        cv2.imwrite(str(root / "images" / f"{ident}.png"), image)
        (root / "gt" / f"{ident}.json").write_text(json.dumps(gt))
        lines.append(
            json.dumps(
                {
                    "id": ident,
                    "image": f"images/{ident}.png",
                    "gt": f"gt/{ident}.json",
                    "image_sha256": "",
                    "gt_sha256": "",
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
