"""The reference pipeline with pixel-count areas, written as 'Total Area:' (some teams do)."""

import argparse
from pathlib import Path

from arenabench.imageio import load_image
from arenabench.pipeline import DetectConfig, detect

parser = argparse.ArgumentParser()
parser.add_argument("--image", required=True)
image = parser.parse_args().image
det = detect(load_image(image), DetectConfig(area_method="pixels"))
Path("obstacles.txt").write_text(
    f"Aruco ID: {sorted(det.marker_ids)}\nObstacles: {det.count}\nTotal Area: {det.total_area}\n"
)
