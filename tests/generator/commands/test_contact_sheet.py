"""`arenabench contact-sheet` and the tiling behind it."""

import subprocess
import sys

import cv2
import numpy as np
import pytest
from clirun import run_cli

from arenabench.generator.commands.contact_sheet import tile_images
from arenabench.generator.parameters.params import Range
from arenabench.generator.parameters.presets import PRESETS, resolve


def test_tiles_keep_aspect_and_layout():
    wide = np.zeros((50, 100, 3), np.uint8)
    tall = np.full((100, 50, 3), 200, np.uint8)
    sheet = tile_images([wide, tall, wide], ["a", "b", "c"], columns=2, tile=40)
    cell_w, cell_h = 40 + 12, 40 + 22 + 12
    assert sheet.shape == (2 * cell_h, 2 * cell_w, 3)
    # the wide image fills the tile's width and half its height (black), the rest stays white
    assert (sheet[6:26, 6:46] == 0).all() and (sheet[27:46, 6:46] == 255).all()
    with pytest.raises(ValueError, match="equal length"):
        tile_images([wide], ["a", "b"])


def test_every_preset_resolves_and_hard_adds_real_degradations():
    for name in PRESETS:
        resolve(name)
    hard = PRESETS["eyrc-hard"][1]
    for key in ("degrade.noise_sigma", "degrade.jpeg_quality", "lighting.shadow_strength",
                "degrade.motion_blur_px", "camera.tilt_deg"):
        assert isinstance(hard[key], Range) and hard[key].hi > 0, key


@pytest.mark.integration
def test_cli_writes_a_sheet(tmp_path):
    out = tmp_path / "sheet.png"
    proc = subprocess.run(
        [sys.executable, "-m", "arenabench", "contact-sheet", "--preset", "eyrc-hard",
         "--count", "3", "--columns", "3", "--tile", "64", "--out", str(out)],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    sheet = cv2.imread(str(out))
    assert sheet.shape == (64 + 22 + 12, 3 * (64 + 12), 3)
    assert sheet.std() > 10  # real renders, not a blank page
    assert [p.name for p in tmp_path.iterdir()] == ["sheet.png"]


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--preset", "nope"], "unknown preset 'nope'"),
        (["--out", "x.gif"], "--out must end in .jpg or .png"),
        (["--set", "camera.tilt_deg=abc"], "camera.tilt_deg"),
    ],
)
def test_cli_usage_errors(tmp_path, args, fragment):
    proc = run_cli("contact-sheet", *args, cwd=tmp_path)
    assert proc.returncode == 2
    assert fragment in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
