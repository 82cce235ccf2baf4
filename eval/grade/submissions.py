"""Teams' submission folders: finding them and fingerprinting their content.

``SUBMISSIONS/`` holds one folder per team; the folder's name is the team's name. A team
entry that is a symbolic link to a folder is graded as its target (the team keeps the link's
name). A submission is only ever read: its fingerprint is a SHA-256 over every entry's
relative path and content, computed without following symbolic links, without recursion (a
folder nested thousands deep is fine), without opening anything that is not a regular file (a
FIFO or device file in a hostile submission cannot block the grader), and without reading a
file larger than :data:`HASH_CONTENT_MAX` (such a file, e.g. a 1 TiB sparse one, counts by its
size and modification time instead of its bytes).
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
#: Largest file whose bytes are hashed; a larger one counts by size and mtime.
HASH_CONTENT_MAX = 256 * 1024**2
#: Most entries a submission may hold (more: :class:`SubmissionsError`, one line).
MAX_ENTRIES = 200_000


class SubmissionsError(ValueError):
    """``SUBMISSIONS`` cannot be graded (the message names the folder and the problem)."""


@dataclass(frozen=True)
class Team:
    """One team's submission.

    Parameters
    ----------
    name : str
        The folder's name (a symbolic link's own name).
    path : pathlib.Path
        Absolute, resolved path of the folder (a symbolic link's target), the path the
        command names and the sandbox shows.
    """

    name: str
    path: Path

    @property
    def shown(self) -> str:
        """The name as a log line shows it: as is when printable, else escaped (a name with a
        newline never forges a line of its own)."""
        return self.name if self.name.isprintable() else repr(self.name)

    def problem(self, submissions: Path) -> str | None:
        """Why this folder is not graded (checked before anything of it is read), or
        ``None``: a name that is not printable text (a newline, an escape sequence), or a
        link to a system folder (``/``, ``/etc``) or to a folder that holds the submissions."""
        if not self.name.isprintable():
            return (f"the folder's name {self.name!r} holds a character that is not printable: "
                    "rename it")
        if self.path == Path("/") or self.path.parent == Path("/"):
            return f"it is a link to the system folder {self.path}, not a submission"
        if self.path == submissions or self.path in submissions.parents:
            return f"it is a link to {self.path}, which holds the submissions"
        return None


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
    try:
        base = Path(root).resolve()
    except RuntimeError:  # Python < 3.13: a symbolic link loop
        raise SubmissionsError(f"{root}: SUBMISSIONS folder is a symbolic link loop") from None
    if not base.is_dir():
        raise SubmissionsError(f"{base}: SUBMISSIONS folder does not exist or is not a folder")
    teams = [
        Team(name=entry.name, path=Path(os.path.realpath(base / entry.name)))
        for entry in os.scandir(base)
        if not entry.name.startswith(".") and entry.is_dir(follow_symlinks=True)
    ]
    if not teams:
        raise SubmissionsError(f"{base}: no team folders (one folder per team expected)")
    return tuple(sorted(teams, key=lambda t: t.name))


def _file_digest(path: str, st: os.stat_result) -> tuple[str, str]:
    if st.st_size > HASH_CONTENT_MAX:
        return "big", f"{st.st_size}:{st.st_mtime_ns}"
    h = hashlib.sha256()
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped since the lstat
            return "special", "?"
        left = HASH_CONTENT_MAX
        while left > 0 and (chunk := fh.read(min(_CHUNK, left))):
            h.update(chunk)
            left -= len(chunk)
    return "file", h.hexdigest()


def submission_hash(folder: str | os.PathLike[str]) -> str:
    """Deterministic SHA-256 of a submission folder: file names and contents.

    Each entry contributes its path relative to ``folder`` (POSIX separators) and: for a
    regular file, the SHA-256 of its bytes (of at most :data:`HASH_CONTENT_MAX` bytes: a larger
    file contributes its size and mtime); for a symbolic link, its target text (never
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

    Raises
    ------
    SubmissionsError
        When the folder holds more than :data:`MAX_ENTRIES` entries.
    """
    root = os.path.realpath(folder)
    entries: list[tuple[str, str, str]] = []
    stack = [""]  # relative folders still to list: iterative, no recursion limit
    while stack:
        rel_dir = stack.pop()
        try:
            with os.scandir(os.path.join(root, rel_dir) if rel_dir else root) as it:
                listed = list(it)
        except OSError as exc:
            entries.append((rel_dir or ".", "error", type(exc).__name__))
            continue
        for entry in listed:
            if len(entries) >= MAX_ENTRIES:
                raise SubmissionsError(f"{root}: more than {MAX_ENTRIES} entries: not a "
                                       "competition submission")
            rel = f"{rel_dir}/{entry.name}" if rel_dir else entry.name
            try:
                st = entry.stat(follow_symlinks=False)
                if stat.S_ISDIR(st.st_mode):
                    if entry.name not in IGNORED_NAMES:
                        stack.append(rel)
                elif stat.S_ISLNK(st.st_mode):
                    entries.append((rel, "link", os.readlink(entry.path)))
                elif stat.S_ISREG(st.st_mode):
                    entries.append((rel, *_file_digest(entry.path, st)))
                else:
                    entries.append((rel, "special", stat.filemode(st.st_mode)[0]))
            except OSError as exc:  # vanished or unreadable: still deterministic
                entries.append((rel, "error", type(exc).__name__))
    h = hashlib.sha256(b"arenabench.submission/1\n")
    for rel, kind, value in sorted(entries):
        h.update(f"{kind}\0{rel}\0{value}\n".encode("utf-8", "surrogateescape"))
    return h.hexdigest()
