"""The images a ``--cmd`` run leaves in its working directory (its own warp) on the HTML
failure card: what is read from a hostile folder, and end to end, cold and warm, in a real
eval of a competition-style script on generated scenes, rendered in headless chromium."""

import base64
import json
import os
import re
import sys

import cv2
import numpy as np
import pytest
from paths import TESTS

from arenabench.eval.runs.run_images import (
    INPUT_COPY_NAMES,
    collect_run_images,
    image_size,
    thumbnail_jpeg,
)
from arenabench.imageio import encode_jpeg, encode_png
from arenabench.limits import (
    MAX_RUN_IMAGE_BYTES,
    MAX_RUN_IMAGE_ENTRIES,
    MAX_RUN_IMAGES,
    RUN_IMAGE_THUMB_PX,
)

PIPES = TESTS / "pipelines"


def _picture(w: int, h: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.full((h, w, 3), 230, np.uint8)
    for _ in range(5):
        x, y = int(rng.integers(0, w - 40)), int(rng.integers(0, h - 40))
        cv2.rectangle(img, (x, y), (x + 40, y + 30), (40, 40, 40), -1)
    return img


def _decode(jpeg: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)


def test_image_size_reads_png_and_jpeg_headers_only():
    img = _picture(300, 200)
    assert image_size(encode_png(img)) == (300, 200)
    assert image_size(encode_jpeg(img, quality=90)) == (300, 200)
    ok, progressive = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
    assert ok and image_size(progressive.tobytes()) == (300, 200)
    assert image_size(b"GIF89a....") is None and image_size(b"") is None
    assert image_size(b"\xff\xd8\xff\xd9") is None  # a JPEG without a frame


def test_a_thumbnail_keeps_the_picture_within_the_bound():
    img = _picture(1000, 600)
    thumb = thumbnail_jpeg(encode_png(img))
    assert thumb is not None and (thumb.width, thumb.height) == (1000, 600)
    small = _decode(thumb.jpeg)
    assert small.shape == (round(600 * RUN_IMAGE_THUMB_PX / 1000), RUN_IMAGE_THUMB_PX, 3)
    expect = cv2.resize(img, small.shape[1::-1], interpolation=cv2.INTER_AREA)
    assert np.abs(small.astype(int) - expect).mean() < 4
    thumb = thumbnail_jpeg(encode_jpeg(img, quality=95))  # decoded at a reduced scale
    assert thumb is not None and (thumb.width, thumb.height) == (1000, 600)
    small = _decode(thumb.jpeg)
    assert small.shape == (round(600 * RUN_IMAGE_THUMB_PX / 1000), RUN_IMAGE_THUMB_PX, 3)
    assert np.abs(small.astype(int) - expect).mean() < 6


def test_only_the_images_the_run_wrote_are_collected(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    outside = tmp_path / "outside.png"
    outside.write_bytes(encode_png(_picture(100, 100, 1)))
    (work / "transformed_image.png").write_bytes(encode_png(_picture(400, 400, 2)))
    (work / "Output_Image.JPG").write_bytes(encode_jpeg(_picture(640, 480, 3), quality=90))
    for name in INPUT_COPY_NAMES:  # the harness's copy of the input
        (work / name).write_bytes(encode_png(_picture(64, 64, 4)))
    os.symlink(outside, work / "a_link.png")  # never followed
    os.mkfifo(work / "a_fifo.png")  # never opened for reading (would block)
    (work / "a_folder.png").mkdir()
    (work / "a_text.jpg").write_text("not an image")
    (work / "notes.txt").write_text("not looked at")
    with open(work / "a_huge.png", "wb") as fh:  # beyond the byte bound (sparse)
        fh.write(encode_png(_picture(60, 60)))
        fh.truncate(MAX_RUN_IMAGE_BYTES + 1)
    bomb = bytearray(encode_png(_picture(64, 64)))
    bomb[16:24] = (20000).to_bytes(4, "big") * 2  # a header promising 20000 x 20000
    (work / "a_bomb.png").write_bytes(bytes(bomb))
    (work / "b_cut.png").write_bytes(encode_png(_picture(200, 200))[:300])  # cut short

    got = collect_run_images(work)
    assert [(i.name, i.width, i.height) for i in got] == [
        ("Output_Image.JPG", 640, 480), ("transformed_image.png", 400, 400)]
    assert all(_decode(i.jpeg) is not None for i in got)


def test_at_most_the_bound_by_name_and_odd_names_are_printable(tmp_path):
    png = encode_png(_picture(80, 60))
    for k in range(MAX_RUN_IMAGES + 3):
        (tmp_path / f"step{k}.png").write_bytes(png)
    got = collect_run_images(tmp_path)
    assert [i.name for i in got] == [f"step{k}.png" for k in range(MAX_RUN_IMAGES)]
    odd = tmp_path / "odd"
    odd.mkdir()
    (odd / "line\nbreak.png").write_bytes(png)
    with open(os.fsencode(odd) + b"/bad\xff.png", "wb") as fh:
        fh.write(png)
    names = sorted(i.name for i in collect_run_images(odd))
    assert names == ["bad\\udcff.png", "line\\nbreak.png"]
    assert all(n.isprintable() for n in names)


def test_a_flooded_folder_is_looked_at_only_so_far(tmp_path):
    for k in range(MAX_RUN_IMAGE_ENTRIES + 50):
        (tmp_path / f"f{k:05d}.txt").write_bytes(b"")
    assert collect_run_images(tmp_path) == ()
    assert collect_run_images(tmp_path / "gone") == ()


# ------------------------------------------------------------------ end to end


@pytest.fixture(scope="module")
def twin8(shared_sets):
    return shared_sets.generated("eyrc", count=8, seed=0, workers=2)


def _card_images(page: str) -> dict[str, list[str]]:
    """Image id -> the data URIs of its card's run images (by their alt text)."""
    found: dict[str, list[str]] = {}
    for name, ident, uri in re.findall(
            r'<img alt="run image (\S+) (\d{6})" src="(data:image/jpeg;base64,[^"]+)">', page):
        assert name == "transformed_image.png"
        found.setdefault(ident, []).append(uri)
    return found


@pytest.mark.integration
@pytest.mark.parametrize("warm", [True, False], ids=["warm", "cold"])
def test_the_failure_card_shows_the_warp_the_script_saved(twin8, tmp_path, warm):
    from arenabench.eval.commands.eval import main as eval_main
    from arenabench.eval.reports.json_report import read_json

    out = tmp_path / "out"
    argv = [str(twin8), "--cmd", f"{sys.executable} {PIPES / 'style_min_area.py'} "
            "--image {image}", "--no-progress", "--workers", "2", "--phase-check", "off",
            "--out", str(out)]
    assert eval_main(argv + ([] if warm else ["--no-warm"])) == 0
    report = read_json(out / "report.json")
    failing = {r.id for r in report.images if not r.passed}
    assert failing and len(failing) < len(report.images)
    page = (out / "report.html").read_text()
    shown = _card_images(page)
    assert set(shown) == failing  # each failure card, one image each; passes have no card
    assert all(len(v) == 1 for v in shown.values())
    assert "the run&#x27;s transformed_image.png (1000 x 1000)" in page
    # it is the script's warp: the image through the ground truth's homography, scaled down
    from arenabench.eval.datasets.reader import load_dataset

    items = load_dataset(twin8).items_by_id(failing)
    for ident, (uri,) in shown.items():
        thumb = _decode(base64.b64decode(uri.split(",", 1)[1]))
        assert thumb.shape == (RUN_IMAGE_THUMB_PX, RUN_IMAGE_THUMB_PX, 3)
        image = cv2.imread(str(items[ident].image_path))
        warp = cv2.warpPerspective(image, np.asarray(items[ident].gt.homography), (1000, 1000))
        expect = cv2.resize(warp, thumb.shape[1::-1], interpolation=cv2.INTER_AREA)
        assert np.abs(thumb.astype(int) - expect).mean() < 8, ident
    # never in report.json: no thumbnail bytes, no key for them
    raw = (out / "report.json").read_text()
    assert "run_images" not in raw and all(u.split(",", 1)[1][:200] not in raw
                                           for v in shown.values() for u in v)
    doc = json.loads(raw)
    assert all(set(img["pred"]) <= {"count", "area", "marker_ids", "obstacles",
                                    "obstacles_space", "homography"} for img in doc["images"])


@pytest.mark.integration
def test_the_card_renders_in_headless_chromium(twin8, tmp_path):
    from browser import console_messages, find_chromium, render_page

    from arenabench.eval.commands.eval import main as eval_main

    chromium = find_chromium()
    if chromium is None:
        pytest.skip("chromium is not installed")
    out = tmp_path / "out"
    assert eval_main([str(twin8), "--cmd", f"{sys.executable} {PIPES / 'style_min_area.py'} "
                      "--image {image}", "--no-progress", "--workers", "2", "--phase-check",
                      "off", "--out", str(out), "--formats", "html"]) == 0
    shot = tmp_path / "shot.png"
    log = render_page(chromium, out / "report.html", shot, tmp_path)
    assert console_messages(log) == []
    assert cv2.imread(str(shot)) is not None


def test_results_kept_in_a_file_keep_their_run_images(tmp_path):
    from arenabench.eval.datasets.result_store import ResultStore
    from arenabench.eval.scoring.results import ImageResult, ImageScore, Prediction, Truth

    thumb = thumbnail_jpeg(encode_png(_picture(500, 500)))
    assert thumb is not None
    from dataclasses import replace

    pred = Prediction(status="ok", count=1, area=2.0, latency_ms=3.0,
                      run_images=(replace(thumb, name="warp.png"),))
    result = ImageResult(id="000000", image="x.png", truth=Truth(count=2, area=2.0),
                         prediction=pred,
                         score=ImageScore(passed=False, category="wrong_count", count_err=-1,
                                          area_rel_err=0.0, area_err_kind="relative",
                                          marker_ids_ok=None))
    store = ResultStore(1, spill=True)
    store.add(0, result)
    (back,) = store.images()
    assert back.prediction.run_images == pred.run_images
    (entry,) = store.images().dicts()
    assert entry == result.to_dict()  # what report.json gets: no thumbnails
