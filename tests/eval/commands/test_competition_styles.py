"""The seven competition-style test pipelines (tests/pipelines/style_*.py): each is right on the
competition's published example, writes the competition's ``obstacles.txt`` as a command, and
must pass the hidden-test twin preset ``eyrc`` the way it passed the real hidden tests.
"""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
from marks import integration_but
from pass_rates import STYLES, score_preset  # tests/pipelines (pytest's pythonpath)
from paths import ROOT, TESTS

from arenabench.eval.commands.eval import main as eval_main
from arenabench.generator.commands.generate import main as generate_main

PIPES = TESTS / "pipelines"
REAL = TESTS / "data" / "task1c_image.jpg"
#: One team's published result on the real example (tests/data/README.md).
REAL_COUNT, REAL_AREA = 2, 72141.5
TWIN_SCENES = 200
TWIN_PASS_RATE = 0.95



@pytest.fixture(scope="module")
def real_image():
    image = cv2.imread(str(REAL))
    assert image is not None
    return image


@pytest.mark.parametrize("style", STYLES)
def test_style_is_right_on_the_real_example(style, real_image):
    result = importlib.import_module(style).detect(real_image)
    assert result["status"] == "ok"
    assert result["count"] == REAL_COUNT
    assert result["area"] == pytest.approx(REAL_AREA, rel=0.01)
    assert sorted(result["marker_ids"]) == [80, 85, 90, 95]


@pytest.mark.parametrize("style", integration_but(STYLES, first=2))
def test_style_command_writes_the_competition_file(style, real_image, tmp_path):
    proc = subprocess.run([sys.executable, str(PIPES / f"{style}.py"), "--image", str(REAL)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    expected = importlib.import_module(style).detect(real_image)
    assert (tmp_path / "obstacles.txt").read_text() == (
        f"Aruco ID: {expected['marker_ids']}\n"
        f"Obstacles: {expected['count']}\n"
        f"Area: {expected['area']}\n"
    )


@pytest.mark.integration
def test_style_command_without_markers_exits_3(tmp_path):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((600, 600, 3), 255, dtype=np.uint8))
    proc = subprocess.run([sys.executable, str(PIPES / "style_canny.py"), "--image", str(blank)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 3
    assert (tmp_path / "obstacles.txt").read_text() == "Aruco ID: []\nObstacles: 0\nArea: 0.0\n"


@pytest.fixture(scope="module")
def tiny_set(tmp_path_factory):
    data = tmp_path_factory.mktemp("styles") / "eyrc"
    assert generate_main(["--preset", "eyrc", "--count", "3", "--seed", "4", "--out", str(data),
                          "--no-progress", "--workers", "1"]) == 0
    return data


@pytest.mark.integration
def test_style_as_a_graded_command_matches_in_process(tiny_set, tmp_path):
    data = tiny_set
    script = PIPES / "style_warp400.py"
    runs = {"cmd": ["--cmd", f"{{python}} {script} --image {{image}}"],
            "callable": ["--pipeline", "style_warp400:detect"]}
    preds = {}
    for name, spec in runs.items():
        out = tmp_path / name
        assert eval_main([str(data), *spec, "--out", str(out), "--formats", "json",
                          "--no-progress", "--workers", "2"]) == 0
        report = json.loads((out / "report.json").read_text())
        preds[name] = [(im["id"], im["pred"]["count"], im["pred"]["area"],
                        sorted(im["pred"]["marker_ids"])) for im in report["images"]]
    assert preds["cmd"] == preds["callable"]
    assert all(ids == [80, 85, 90, 95] for *_, ids in preds["cmd"])


@pytest.fixture(scope="module")
def fitted_render():
    """The fitted example's render, written as the twin writes it (JPEG, quality 95)."""
    from arenabench.generator.model.scene import load_scene
    from arenabench.generator.rendering.render import Renderer
    from arenabench.imageio import decode_image, encode_jpeg

    scene = load_scene(ROOT / "generator" / "scenes"
                       / "task1c_example.json")
    with Renderer() as r:
        bgr = cv2.cvtColor(r.render(scene).rgb, cv2.COLOR_RGB2BGR)
    return {"png": bgr, "jpeg": decode_image(encode_jpeg(bgr, quality=95))}


@pytest.mark.parametrize("style", integration_but(STYLES, first=2))
def test_style_counts_the_fitted_render_as_the_real_example(style, fitted_render):
    """The render of the fitted example (the same scene) gives every style the real image's
    count and an area within 1 % of its answer there, as a PNG and as the twin's JPEG."""
    module = importlib.import_module(style)
    want = module.detect(cv2.imread(str(REAL)))
    for kind, bgr in fitted_render.items():
        got = module.detect(bgr)
        assert got["count"] == want["count"] == REAL_COUNT, kind
        assert got["area"] == pytest.approx(want["area"], rel=0.01), kind


@pytest.fixture(scope="module")
def twin_tallies():
    """Every style on the same 200 eyrc scenes, each rendered once in memory."""
    return score_preset("eyrc", count=TWIN_SCENES, seed=0,
                        pipelines=tuple(f"{s}:detect" for s in STYLES), references=("visible",))


#: Known gap of the twin, kept visible: strict, so the test fails once the style passes.
TWIN_KNOWN_FAILURES = {
    "style_grey_band": "grey band 88-192 keeps a dark side face (grey ~71) only when an unbroken "
    "line of in-band blended pixels closes it off from the floor; with the real image's edges "
    "(two samples per pixel: a half blend of 188 or a hard step, by the edge's sub-pixel phase) "
    "that line breaks on most twin boxes with a large dark face; 45/200 pass (docs/rendering.md)",
    "style_canny": "Canny's non-maximum suppression drops the corner pixel of some box outlines "
    "(it depends on the sub-pixel phases of the two edges meeting there, which decide where "
    "each edge is blended); the loop opens and the box is lost; 168/200 pass "
    "(docs/rendering.md)",
}


@pytest.mark.acceptance
@pytest.mark.xdist_group("twin_tallies")  # the tallies are made once, on one worker
@pytest.mark.parametrize("style", [
    pytest.param(s, marks=pytest.mark.xfail(strict=True, reason=TWIN_KNOWN_FAILURES[s]))
    if s in TWIN_KNOWN_FAILURES else s
    for s in STYLES
])
def test_style_passes_the_twin_like_the_hidden_tests(style, twin_tallies):
    tally = twin_tallies[f"{style}:detect"]
    assert tally.n == TWIN_SCENES
    assert tally.rate("visible") >= TWIN_PASS_RATE, (
        f"{style}: {tally.passed['visible']}/{tally.n}, failures "
        f"{dict(tally.failures.get('visible', {}))}"
    )
