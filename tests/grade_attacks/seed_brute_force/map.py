"""A hostile submission: re-renders the set for candidate seeds until an image matches its
own byte for byte, then copies that scene's ground truth (found every scene of a
seed-1 set after 26 renders). Tries seeds 0..3, scene 0 only, to keep the test short."""

import argparse
import json
import sys
import tempfile
from pathlib import Path

ap = argparse.ArgumentParser()
ap.add_argument("--image", required=True)
image = Path(ap.parse_args().image).read_bytes()

from arenabench.generator.dataset.dataset_writer import generate_dataset  # noqa: E402

for seed in range(4):
    out = Path(tempfile.mkdtemp()) / "guess"
    generate_dataset(out, preset="eyrc", count=1, seed=seed, workers=1, progress=False)
    (guess,) = (out / "images").glob("000000.*")  # PNG or JPEG, as the preset writes it
    if guess.read_bytes() == image:
        gt = json.loads((out / "gt" / "000000.json").read_text())
        print(f"found seed {seed}", file=sys.stderr)
        Path("obstacles.txt").write_text(
            f"Aruco ID: [80, 85, 90, 95]\nObstacles: {gt['count']}\n"
            f"Area: {gt['area']['visible_px']}\n")
        sys.exit(0)
print("seed not found", file=sys.stderr)
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\nObstacles: 0\nArea: 0\n")
