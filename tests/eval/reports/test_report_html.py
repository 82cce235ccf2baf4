"""The HTML report in a real headless browser (Debian's chromium): it renders with no console
errors, references nothing outside itself, and the screenshot is not blank."""

import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import toy_arena
from browser import chromium_or_skip, console_messages, render_page

from arenabench.eval.evaluation import evaluate
from arenabench.eval.reports import write_reports


@pytest.fixture(scope="module")
def chromium() -> str:
    """The chromium binary (skips where missing, fails in CI)."""
    return chromium_or_skip()


@pytest.fixture(scope="module")
def report_page(tmp_path_factory):
    toy = toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toyhtml") / "toy", n=8, seed=9)

    def flaky(image):  # fails in several ways so the page shows failing cases
        r = toy_arena.detect(image)
        if r["count"] == 1:
            raise RuntimeError("flaky pipeline <b>broke</b> & quit")
        if r["count"] == 3:
            return {**r, "count": 2, "area": r["area"] * 0.7}
        return r

    report = evaluate(flaky, toy, workers=2)
    out = tmp_path_factory.mktemp("html")
    write_reports(report, out, formats=("html",))
    return out / "report.html", report


def test_html_report_is_self_contained(report_page):
    page, report = report_page
    text = page.read_text()
    refs = re.findall(r'(?:src|href)\s*=\s*"([^"]*)"', text)
    assert refs and all(r.startswith("data:") for r in refs), refs
    assert "<script" not in text
    # escaped pipeline text, failing cases present with GT and pipeline numbers
    assert "flaky pipeline &lt;b&gt;broke&lt;/b&gt; &amp; quit" in text
    assert "FAIL: crash" in text and "FAIL: wrong_count" in text
    # failures only, each as the image and its rectified frame
    n_failed = report.summary.n - report.summary.n_passed
    assert 0 < n_failed < report.summary.n
    assert text.count("data:image/jpeg;base64,") == 2 * min(12, n_failed)
    assert "- PASS" not in text


@pytest.mark.integration
def test_html_report_renders_in_headless_chromium(chromium, report_page, tmp_path):
    page, _ = report_page
    shot = tmp_path / "report.png"
    log = render_page(chromium, page, shot, tmp_path)
    assert console_messages(log) == []
    image = cv2.imread(str(shot))
    assert image is not None and image.shape[:2] == (2000, 1280)
    # not blank: plenty of non-white pixels and many distinct colours (plots, thumbnails)
    assert (image < 245).any(axis=2).mean() > 0.05
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 200


@pytest.mark.integration
def test_console_error_detection_works(chromium, tmp_path):
    """Positive control: the same check does see a console error and an uncaught exception."""
    bad = tmp_path / "bad.html"
    bad.write_text(
        "<html><body><script>console.error('boom'); undefinedFn();</script>x</body></html>"
    )
    log = render_page(chromium, bad, tmp_path / "bad.png", tmp_path)
    messages = console_messages(log)
    assert any("boom" in m for m in messages) and any("Uncaught" in m for m in messages)


@pytest.fixture(scope="module")
def builtin_pages(tmp_path_factory):
    """The built-in pipeline with tolerance 0 (images with obstacles fail on area, so they are
    thumbnails with the pipeline's contours), and with a loose tolerance (every image passes)."""
    toy = toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toyref") / "toy", n=4, seed=3)
    pages = {}
    for name, tolerance in (("strict", 0.0), ("loose", 0.5)):
        report = evaluate("reference", toy, workers=2, tolerance=tolerance)
        out = tmp_path_factory.mktemp(name)
        write_reports(report, out, formats=("html", "json"))
        pages[name] = (out / "report.html", report)
    return pages


def _colour_pixels(image: np.ndarray) -> dict[str, int]:
    b, g, r = (image[:, :, i].astype(int) for i in range(3))
    return {
        "magenta": int(((r > 180) & (b > 180) & (g < 90)).sum()),
        "green": int(((g > 150) & (r < 90) & (b < 90)).sum()),
    }


@pytest.mark.integration
def test_thumbnails_draw_the_builtin_pipelines_contours(chromium, builtin_pages, report_page,
                                                         tmp_path):
    """In the browser's screenshot: the reference pipeline's outlines (magenta) beside the GT
    (green). Control: a pipeline that reports no polygons shows magenta only in the legend."""
    page, report = builtin_pages["strict"]
    assert all(r.prediction.obstacles is not None for r in report.images)
    assert sum(len(r.prediction.obstacles) for r in report.images if not r.passed) > 0
    shot = _colour_pixels(cv2.imread(str(_shot(chromium, page, tmp_path / "a"))))
    control = _colour_pixels(cv2.imread(str(_shot(chromium, report_page[0], tmp_path / "b"))))
    assert shot["magenta"] > 1000 and shot["magenta"] > 5 * control["magenta"], (shot, control)
    assert shot["green"] > 1000, shot
    text = page.read_text()
    assert "ground truth" in text and "what the pipeline" in text  # the legend


def _shot(chromium: str, page: Path, tmp: Path) -> Path:
    tmp.mkdir()
    shot = tmp / "shot.png"
    assert console_messages(render_page(chromium, page, shot, tmp)) == []
    return shot


def test_no_failures_says_so(builtin_pages):
    page, report = builtin_pages["loose"]
    assert report.summary.n_passed == report.summary.n
    text = page.read_text()
    assert "No failures: every image passed." in text
    assert "data:image/jpeg;base64," not in text


def test_report_json_keeps_the_polygons_compact(builtin_pages):
    import json

    from arenabench.eval.scoring.results import Report

    page, report = builtin_pages["strict"]
    data = json.loads((page.parent / "report.json").read_text())
    preds = [img["pred"] for img in data["images"]]
    assert all(p["obstacles_space"] == "frame" and len(p["homography"]) == 3 for p in preds)
    polys = [poly for p in preds for poly in p["obstacles"]]
    assert polys and all(3 <= len(poly) <= 16 for poly in polys)  # boxes, not raw contours
    again = Report.from_dict(data)
    assert again.images[0].prediction.obstacles == report.images[0].prediction.obstacles


def test_histogram_range_follows_the_data():
    from arenabench.eval.reports.html_report import histogram_range

    assert histogram_range([0.01, -0.02], 0.05) == (0.1, 0)  # twice the tolerance at least
    lim, n_out = histogram_range([0.3, -0.2], 0.05)
    assert lim == pytest.approx(0.315) and n_out == 0
    assert histogram_range([5.0, 0.1], 0.05) == (1.0, 1)  # clipped at 1, and counted


def test_count_confusion_follows_the_data_up_to_an_n_or_more_bin():
    from arenabench.eval.reports.html_report import CONFUSION_COUNTS, count_confusion

    mat, labels = count_confusion([0, 3, 2], [0, 3, None])
    assert labels == ["0", "1", "2", "3"] and mat.shape == (4, 5)  # and a "none" column
    assert mat[0, 0] == mat[3, 3] == mat[2, 4] == 1 and mat.sum() == 3
    # counts no scene holds (refused before a report is made) still give a bounded figure
    top = CONFUSION_COUNTS
    mat, labels = count_confusion([3, 40, 10**30], [10**6, 2**53, 7])
    assert mat.shape == (top + 1, top + 2) and labels[-1] == f"{top}+"
    assert labels[:top] == [str(i) for i in range(top)]
    assert mat[3, top] == mat[top, top] == mat[top, 7] == 1 and mat.sum() == 3
