"""Reading the files a finished run left, without following links or blocking (a run's
folder holds whatever the command made there: a link to a harness file, a FIFO, a folder)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from arenabench.competition import OBSTACLES_FILE, OutputFormatError


def read_small(path: Path, limit: int, *, name: str = OBSTACLES_FILE) -> bytes:
    """Read a regular file of at most ``limit`` bytes without following links or blocking.

    Raises
    ------
    OutputFormatError
        When it is not a regular file or is larger than ``limit`` (the message names the file
        as ``name``).
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as exc:
        raise OutputFormatError(f"{name} cannot be read: {exc.strerror}") from None
    st = os.fstat(fd)  # before fdopen, which refuses a directory with IsADirectoryError
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise OutputFormatError(f"{name} is {kind}")
    with os.fdopen(fd, "rb") as fh:
        if st.st_size > limit:
            raise OutputFormatError(
                f"{name} is {st.st_size} bytes, more than the {limit} allowed"
            )
        return fh.read(limit + 1)[:limit]
