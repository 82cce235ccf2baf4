"""The reference pipeline, but it reports one obstacle too many when it finds exactly one."""

import argparse
from pathlib import Path

from arenabench.imageio import load_image
from arenabench.pipeline import DetectConfig, detect

parser = argparse.ArgumentParser()
parser.add_argument("--image", required=True)
det = detect(load_image(parser.parse_args().image), DetectConfig())
count = det.count + 1 if det.count == 1 else det.count
Path("obstacles.txt").write_text(
    f"Aruco ID: {sorted(det.marker_ids)}\nObstacles: {count}\nArea: {det.total_area}\n"
)
