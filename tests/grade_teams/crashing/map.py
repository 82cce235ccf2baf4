"""The reference pipeline, but it crashes whenever it finds an odd number of obstacles."""

import argparse
from pathlib import Path

from arenabench.imageio import load_image
from arenabench.pipeline import DetectConfig, detect

parser = argparse.ArgumentParser()
parser.add_argument("--image", required=True)
det = detect(load_image(parser.parse_args().image), DetectConfig())
if det.count % 2:
    raise RuntimeError(f"deliberate crash on {det.count} obstacles")
Path("obstacles.txt").write_text(
    f"Aruco ID: {sorted(det.marker_ids)}\nObstacles: {det.count}\nArea: {det.total_area}\n"
)
