"""Helpers of the tests that run hostile pipelines: find processes by a marker on their
command line, wait for a condition."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path


def processes_with(marker: str) -> list[int]:
    """Live (non-zombie) processes, other than this one, whose command line holds ``marker``."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if marker in cmdline and state not in ("Z", "X"):
            out.append(int(entry.name))
    return out


def wait_for(condition: Callable[[], object], *, timeout: float = 30.0) -> object:
    """Poll ``condition`` every 50 ms until it returns something true; return that (or the
    last falsy value after ``timeout`` seconds)."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(0.05)
