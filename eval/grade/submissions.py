"""Teams' submission folders: finding them and fingerprinting their content.

``SUBMISSIONS/`` holds one folder per team; the folder's name is the team's name. A
submission is only ever read: its fingerprint is a SHA-256 over every entry's relative path
and content, computed without following symbolic links and without opening anything that is
not a regular file (a FIFO or device file in a hostile submission cannot block the grader).
"""

from __future__ import annotations

import hashlib
import os
import stat
from dataclasses import dataclass
from pathlib import Path

#: Entries that Python itself leaves next to a team's code; not part of the submission.
IGNORED_NAMES: frozenset[str] = frozenset({"__pycache__", ".pytest_cache"})
_CHUNK = 1 << 20


class SubmissionsError(ValueError):
    """``SUBMISSIONS`` cannot be graded (the message names the folder and the problem)."""


@dataclass(frozen=True)
class Team:
    """One team's submission.

    Parameters
    ----------
    name : str
        The folder's name.
    path : pathlib.Path
        Absolute path of the folder.
    """

    name: str
    path: Path


def find_teams(root: str | os.PathLike[str]) -> tuple[Team, ...]:
    """Every team folder in ``root``, sorted by name.

    Hidden entries (names starting with ``.``) and plain files are not teams.

    Parameters
    ----------
    root : path-like
        The ``SUBMISSIONS`` folder.

    Raises
    ------
    SubmissionsError
        When ``root`` is not a folder or holds no team folder.
    """
    base = Path(root).resolve()
    if not base.is_dir():
        raise SubmissionsError(f"{base}: SUBMISSIONS folder does not exist or is not a folder")
    teams = [
        Team(name=entry.name, path=base / entry.name)
        for entry in os.scandir(base)
        if not entry.name.startswith(".") and entry.is_dir(follow_symlinks=True)
    ]
    if not teams:
        raise SubmissionsError(f"{base}: no team folders (one folder per team expected)")
    return tuple(sorted(teams, key=lambda t: t.name))


def _file_digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def submission_hash(folder: str | os.PathLike[str]) -> str:
    """Deterministic SHA-256 of a submission folder: file names and contents.

    Each entry contributes its path relative to ``folder`` (POSIX separators) and: for a
    regular file, the SHA-256 of its bytes; for a symbolic link, its target text (never
    followed); for anything else (FIFO, socket, device), its type only. Entries are taken in
    sorted order; empty folders and :data:`IGNORED_NAMES` do not count, nor do permissions
    or times. The folder may itself be a symbolic link to the submission.

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    str
        64 hex digits.
    """
    root = os.path.realpath(folder)
    entries: list[tuple[str, str, str]] = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        rel_dir = os.path.relpath(dirpath, root)
        dirnames[:] = [d for d in dirnames if d not in IGNORED_NAMES]
        names = list(filenames) + [d for d in dirnames if os.path.islink(os.path.join(dirpath, d))]
        for name in names:
            full = os.path.join(dirpath, name)
            rel = name if rel_dir == "." else f"{rel_dir}/{name}".replace(os.sep, "/")
            try:
                st = os.lstat(full)
                if stat.S_ISLNK(st.st_mode):
                    entries.append((rel, "link", os.readlink(full)))
                elif stat.S_ISREG(st.st_mode):
                    entries.append((rel, "file", _file_digest(full)))
                else:
                    entries.append((rel, "special", stat.filemode(st.st_mode)[0]))
            except OSError as exc:  # vanished or unreadable: still deterministic
                entries.append((rel, "error", type(exc).__name__))
    h = hashlib.sha256(b"arenabench.submission/1\n")
    for rel, kind, value in sorted(entries):
        h.update(f"{kind}\0{rel}\0{value}\n".encode("utf-8", "surrogateescape"))
    return h.hexdigest()
