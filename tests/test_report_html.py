"""The HTML report in a real headless browser (Debian's chromium): it renders with no console
errors, references nothing outside itself, and the screenshot is not blank."""

import os
import re
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
import toy_arena

from arenabench.eval.reports import write_reports
from arenabench.eval.runner import evaluate

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-logging=stderr",
    "--v=0",
    "--window-size=1280,2000",
]


def _find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser"):
        if path := shutil.which(name):
            return path
    return None


@pytest.fixture(scope="module")
def chromium() -> str:
    """The chromium binary. Never installs anything: `make test` installs chromium when
    system installs are allowed (tools/ensure-system-deps.sh: ARENABENCH_INSTALL_SYSTEM_DEPS=1
    or CI=true, as root). Skips when it is missing, except in CI, where that is a failure."""
    path = _find_chromium()
    if path:
        return path
    why = (
        "chromium is not installed: sudo apt-get install -y chromium (or run `make test` as "
        "root with ARENABENCH_INSTALL_SYSTEM_DEPS=1)"
    )
    if os.environ.get("CI") == "true":
        pytest.fail(f"{why}; in CI `make test` should have installed it")
    pytest.skip(why)


def _render(chromium: str, page: Path, shot: Path, tmp: Path) -> str:
    proc = subprocess.run(
        [
            chromium,
            *CHROMIUM_FLAGS,
            f"--user-data-dir={tmp / 'profile'}",
            f"--screenshot={shot}",
            page.resolve().as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stderr


def _console_messages(log: str) -> list[str]:
    return [line for line in log.splitlines() if ":CONSOLE" in line or "Uncaught" in line]


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
    assert text.count("data:image/jpeg;base64,") == min(12, report.summary.n)


@pytest.mark.slow
def test_html_report_renders_in_headless_chromium(chromium, report_page, tmp_path):
    page, _ = report_page
    shot = tmp_path / "report.png"
    log = _render(chromium, page, shot, tmp_path)
    assert _console_messages(log) == []
    image = cv2.imread(str(shot))
    assert image is not None and image.shape[:2] == (2000, 1280)
    # not blank: plenty of non-white pixels and many distinct colours (plots, thumbnails)
    assert (image < 245).any(axis=2).mean() > 0.05
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 200


@pytest.mark.slow
def test_console_error_detection_works(chromium, tmp_path):
    """Positive control: the same check does see a console error and an uncaught exception."""
    bad = tmp_path / "bad.html"
    bad.write_text(
        "<html><body><script>console.error('boom'); undefinedFn();</script>x</body></html>"
    )
    log = _render(chromium, bad, tmp_path / "bad.png", tmp_path)
    messages = _console_messages(log)
    assert any("boom" in m for m in messages) and any("Uncaught" in m for m in messages)
