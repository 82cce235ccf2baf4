"""A real headless browser for the HTML tests (Debian's chromium): find it, render a page to a
screenshot, read the console messages it logged."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

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


def find_chromium() -> str | None:
    """The chromium binary on PATH, or ``None``."""
    for name in ("chromium", "chromium-browser"):
        if path := shutil.which(name):
            return path
    return None


def chromium_or_skip() -> str:
    """The chromium binary. Never installs anything: `make test` installs chromium when
    system installs are allowed (tools/ensure-system-deps.sh: ARENABENCH_INSTALL_SYSTEM_DEPS=1
    or CI=true, as root). Skips when it is missing, except in CI, where that is a failure."""
    path = find_chromium()
    if path:
        return path
    why = (
        "chromium is not installed: sudo apt-get install -y chromium (or run `make test` as "
        "root with ARENABENCH_INSTALL_SYSTEM_DEPS=1)"
    )
    if os.environ.get("CI") == "true":
        pytest.fail(f"{why}; in CI `make test` should have installed it")
    pytest.skip(why)


def render_page(chromium: str, page: Path, shot: Path, tmp: Path) -> str:
    """Render ``page`` to the screenshot ``shot``; chromium's log (stderr)."""
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


def console_messages(log: str) -> list[str]:
    """The page's console messages and uncaught errors in chromium's log."""
    return [line for line in log.splitlines() if ":CONSOLE" in line or "Uncaught" in line]
