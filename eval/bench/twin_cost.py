"""Bench item 12: what ``arenabench twin`` costs on the published example without a texture
(the twin rectifies one from the image): wall seconds and the command's peak resident memory,
run as a user runs it (a subprocess, its own rusage)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

#: The image (the competition's published example, in the repository's test data) and the
#: floor's size the twin is given.
EXAMPLE = Path(__file__).resolve().parents[2] / "tests" / "data" / "task1c_image.jpg"
ARENA_SIZE = "3.7,3.7"


def twin_cost(scratch: Path, image: Path = EXAMPLE) -> tuple[dict[str, float], dict[str, Any]]:
    """(figures ``twin_example_s`` and ``twin_example_peak_mb``, details) of one twin of
    ``image`` without a texture; no figures where the image is not there (an installed
    package without the repository's test data)."""
    if not image.is_file():
        return {}, {"skipped": f"{image} not found (the repository's test data)"}
    out = scratch / "twin"
    t0 = time.perf_counter()
    with open(scratch / "twin.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "arenabench", "twin", str(image),
                                 "--arena-size", ARENA_SIZE, "--out", str(out),
                                 "--no-progress", "--accept-poor-fit"],
                                stdout=log, stderr=log, stdin=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)  # this command's own peak memory
    seconds = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    details = {"image": str(image), "arena_size": ARENA_SIZE, "exit": code,
               "cpu_s": round(usage.ru_utime + usage.ru_stime, 2)}
    if code != 0:
        details["log_tail"] = (scratch / "twin.log").read_text(errors="replace")[-500:]
        return {}, details
    return {"twin_example_s": seconds, "twin_example_peak_mb": usage.ru_maxrss / 1024.0}, details
