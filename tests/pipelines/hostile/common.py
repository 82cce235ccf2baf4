"""Helpers of the hostile test pipelines (standard library only)."""

import os
import sys
from pathlib import Path

ANSWER = "Aruco ID: [80, 85, 90, 95]\nObstacles: 0\nArea: 0\n"


def answer() -> None:
    """Write a well-formed obstacles.txt (0 obstacles) into the working directory."""
    Path("obstacles.txt").write_text(ANSWER)


def image_arg() -> str:
    """The value after ``--image``."""
    return sys.argv[sys.argv.index("--image") + 1]


def sleeper(marker: str) -> list[str]:
    """Command line of a process that sleeps 600 s with ``marker`` on its command line."""
    return [sys.executable, "-c", "import time; time.sleep(600)", marker]


def daemonize(marker: str) -> None:
    """Double fork + setsid: leave a grandchild that sleeps with ``marker``, stdout kept open."""
    pid = os.fork()
    if pid == 0:
        os.setsid()
        if os.fork() == 0:
            os.execv(sys.executable, sleeper(marker))
        os._exit(0)
    os.waitpid(pid, 0)
