"""Atomic file writes, JSON-safe serialisation and hashing shared by every package.

Nothing half-written is ever left under a final name: data goes to a temporary file in the
same directory, is flushed, then renamed over the target (``os.replace`` is atomic on POSIX).
JSON written through :func:`dumps_json` / :func:`dumps_json_line` is always valid JSON: a
number that is undefined (NaN, an infinity, from whatever a pipeline returned) is ``null``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
import stat
import sys
import tempfile
import time
from collections.abc import Collection, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

#: Decimal places kept for floats in the JSON files arenabench writes (ground truth,
#: coco.json): stable, byte-identical files.
JSON_DECIMALS = 6


#: Temporary files of :func:`atomic_write_bytes` are named ``.<final name>.<random>.tmp``.
TEMP_SUFFIX = ".tmp"


def is_temp_name(name: str) -> bool:
    """Whether ``name`` is a temporary file name of :func:`atomic_write_bytes`."""
    return name.startswith(".") and name.endswith(TEMP_SUFFIX)


def remove_temp_files(folder: str | os.PathLike[str]) -> int:
    """Remove the temporary files a killed writer left directly in ``folder``; call it only
    while holding :func:`lock_folder` on the folder (no other writer is running).

    Returns
    -------
    int
        Number of files removed (0 when ``folder`` does not exist).
    """
    removed = 0
    try:
        entries = list(os.scandir(folder))
    except FileNotFoundError:
        return 0
    for entry in entries:
        if is_temp_name(entry.name) and entry.is_file(follow_symlinks=False):
            try:
                os.unlink(entry.path)
                removed += 1
            except FileNotFoundError:
                pass
    return removed


def _process_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: Read once at import: files get the permissions ``open()`` would give them (mkstemp's are 0600).
_FILE_MODE = 0o666 & ~_process_umask()


@contextlib.contextmanager
def atomic_writer(path: str | os.PathLike[str], *, text: bool = False) -> Iterator[IO[Any]]:
    """A file written piece by piece to a temporary name beside ``path`` (parents created) and
    renamed over ``path`` when the block ends without an exception (else removed).

    Parameters
    ----------
    path : path-like
        Final file name.
    text : bool, keyword-only
        A UTF-8 text file without newline translation (default: binary).
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=TEMP_SUFFIX, dir=target.parent)
    try:
        if text:
            fh = os.fdopen(fd, "w", encoding="utf-8", newline="")
        else:
            fh = os.fdopen(fd, "wb")
        with fh:
            yield fh
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically, creating parent directories
    (:func:`atomic_writer`).

    Parameters
    ----------
    path : path-like
        Final file name.
    data : bytes
        Content to write.

    Returns
    -------
    pathlib.Path
        The final path.
    """
    with atomic_writer(path) as fh:
        fh.write(data)
    return Path(path)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def json_safe(obj: Any) -> Any:
    """A copy of ``obj`` that :func:`json.dumps` accepts with ``allow_nan=False``.

    Non-finite floats become ``None``; NumPy scalars and arrays become Python numbers and
    lists; tuples become lists; mapping keys are kept. Anything else is returned unchanged.
    """
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, (str, int, bool)) or obj is None:
        return obj
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if hasattr(obj, "tolist") and type(obj).__module__ == "numpy":  # array or scalar
        return json_safe(obj.tolist())
    return obj


def dumps_json(obj: Any) -> str:
    """Serialise ``obj`` to canonical JSON text (sorted keys, 2-space indent, trailing newline).

    Canonical output keeps files byte-identical for identical content; undefined numbers
    (NaN, infinities) are written as ``null`` (see :func:`json_safe`).
    """
    return json.dumps(json_safe(obj), indent=2, sort_keys=True, allow_nan=False) + "\n"


def dumps_json_line(obj: Any) -> str:
    """One compact JSON line with sorted keys and a trailing newline (for ``.jsonl`` files);
    undefined numbers are ``null`` as in :func:`dumps_json`."""
    return json.dumps(json_safe(obj), sort_keys=True, allow_nan=False) + "\n"


def atomic_write_json(path: str | os.PathLike[str], obj: Any) -> Path:
    """Write ``obj`` as canonical JSON to ``path`` atomically."""
    return atomic_write_text(path, dumps_json(obj))


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of the regular file at ``path``, read in chunks
    (:class:`NotRegularFileError` for anything else: :func:`open_regular`)."""
    h = hashlib.sha256()
    with open_regular(path) as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


class NotRegularFileError(OSError):
    """A file to read is a FIFO, a device, a socket or a folder (``strerror`` says which)."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    return "a pipe, device or socket"


def open_regular(path: str | os.PathLike[str]) -> IO[bytes]:
    """Open ``path`` for reading, in binary, only if it is a regular file.

    The file is opened without blocking (``O_NONBLOCK``: a FIFO with no writer would
    otherwise block the open, and a read, for ever) and judged by its open descriptor
    (``fstat``), so a file swapped for a FIFO after a check by name is refused too; the
    descriptor is then made blocking again. Symbolic links are followed.

    Raises
    ------
    NotRegularFileError
        For a FIFO, device, socket or folder (``strerror``: ``"not a regular file (...)"``).
    OSError
        When it cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotRegularFileError(0, f"not a regular file ({_kind(mode)})", str(path))
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return os.fdopen(fd, "rb")


def read_regular(path: str | os.PathLike[str], *, limit: int | None = None) -> bytes:
    """The bytes of the regular file at ``path`` (:func:`open_regular`).

    Parameters
    ----------
    limit : int, optional, keyword-only
        Largest size read: a larger file is an ``OSError`` whose ``strerror`` is ``"more
        than the <limit> bytes allowed"`` (nothing more is read).
    """
    with open_regular(path) as fh:
        if limit is None:
            return fh.read()
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise OSError(0, f"more than the {limit} bytes allowed", str(path))
    return data


def rounded(obj: Any, decimals: int = JSON_DECIMALS) -> Any:
    """Round every float in a nested structure (numpy values become Python numbers).

    Parameters
    ----------
    obj : any
        Dicts, lists, tuples, NumPy arrays and scalars, nested; other values pass unchanged.
    decimals : int
        Decimal places kept (default :data:`JSON_DECIMALS`); ``-0.0`` becomes ``0.0``.

    Returns
    -------
    any
        The same structure with lists for tuples and arrays.
    """
    if isinstance(obj, dict):
        return {k: rounded(v, decimals) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [rounded(v, decimals) for v in obj]
    if isinstance(obj, np.ndarray):
        return rounded(obj.tolist(), decimals)
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = round(float(obj), decimals)
        return 0.0 if value == 0 else value
    return obj


class OutputPathError(ValueError):
    """An output path cannot be written; the message is one line (without the path)."""


def _probe_writable(folder: Path) -> None:
    """Create and remove a temporary file in ``folder`` (``os.access`` is wrong for root, for
    read-only mounts and for virtual file systems such as ``/proc``)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".arenabench-probe-", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise OutputPathError(
            f"cannot create files in {folder} ({exc.strerror or type(exc).__name__})"
        ) from None
    os.close(fd)
    os.unlink(tmp)


def _nearest_existing(path: Path) -> Path:
    """``path`` or its nearest existing ancestor; every existing component must be a folder."""
    probe = path
    while not probe.exists() and not probe.is_symlink():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OutputPathError(f"{probe} exists and is not a folder")
    if not probe.exists():  # a dangling symbolic link
        raise OutputPathError(f"{probe} is a broken symbolic link")
    return probe


def check_output_dir(path: str | os.PathLike[str]) -> Path:
    """Check, before any work, that ``path`` is a folder that exists or can be created, and
    that files can be created in it. Nothing is created (the probe file is removed).

    Parameters
    ----------
    path : path-like
        The output folder (``--out``).

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.

    Raises
    ------
    OutputPathError
        One line saying why (a file is in the way, the folder or its nearest existing
        ancestor is not writable, a virtual file system such as ``/proc``).
    """
    target = Path(path)
    if str(path) == "":
        raise OutputPathError("empty path")
    if is_system_folder(target):
        real = os.path.realpath(target)
        what = "is" if real == os.path.abspath(target) else f"leads to {real},"
        raise OutputPathError(f"{what} a system folder (/ or a folder directly in it): name a "
                              "folder of its own")
    _probe_writable(_nearest_existing(target))
    return target


def is_system_folder(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` (symbolic links followed) is ``/`` or a folder directly in it
    (``/usr``, ``/etc``, ``/tmp``, ``/root``...): never an output folder of its own."""
    real = Path(os.path.realpath(path))
    return len(real.parts) <= 2


def check_report_dir(path: str | os.PathLike[str], *, own: Collection[str], what: str,
                     inputs: Sequence[tuple[str, str | os.PathLike[str]]] = ()) -> None:
    """Check, before any work, that the folder ``path`` may receive a command's outputs:
    :func:`check_output_dir`, and the folder is not one of ``inputs`` nor inside one, and it
    is missing, empty, or holds an earlier output of the same command (one of ``own``).

    Parameters
    ----------
    path : path-like
        The output folder (``--out``).
    own : collection of str
        Names of the entries the command writes there (``report.json``, ``teams``...);
        :data:`LOCK_FILE` and temporary files of :func:`atomic_write_bytes` do not count.
    what : str
        The command's outputs in words, for the message (``"'arenabench eval' report"``).
    inputs : sequence of (str, path-like)
        Folders the command reads (``("DATASET", "hidden/")``).

    Raises
    ------
    OutputPathError
        One line saying why (without the path).
    """
    target = check_output_dir(path)
    real = Path(os.path.realpath(target))
    for name, folder in inputs:
        source = Path(os.path.realpath(folder))
        if real == source or source in real.parents:
            where = "is" if real == source else "is inside"
            raise OutputPathError(f"{where} {name} {folder} (inputs are only read)")
    if not real.is_dir():
        return
    try:
        names = sorted(e.name for e in os.scandir(real)
                       if e.name != LOCK_FILE and not is_temp_name(e.name))
    except OSError as exc:
        raise OutputPathError(f"cannot list it ({exc.strerror or exc})") from None
    if names and not set(names) & set(own):
        shown = ", ".join(repr(n) for n in names[:3]) + (", ..." if len(names) > 3 else "")
        raise OutputPathError(f"not empty ({shown}) and holds no earlier {what}: use a new "
                              "or empty folder")


_FD_LINK = re.compile(r"^/(?:proc/self|dev)/fd/(\d+)$")
_STD_LINKS = {"/dev/stdin": 0, "/dev/stdout": 1, "/dev/stderr": 2}


def _link_chain(path: str | os.PathLike[str]) -> list[str]:
    """``path`` (absolute) and every symbolic link hop after it."""
    hops = [os.path.abspath(os.fspath(path))]
    for _ in range(40):  # the kernel's own limit on link chains
        if not os.path.islink(hops[-1]):
            break
        hops.append(os.path.normpath(
            os.path.join(os.path.dirname(hops[-1]), os.readlink(hops[-1]))
        ))
    return hops


def _inherited_fd(path: str | os.PathLike[str]) -> int | None:
    """File descriptor named by ``/dev/stdout``, ``/dev/fd/N`` or ``/proc/self/fd/N``."""
    for hop in _link_chain(path):
        if hop in _STD_LINKS:
            return _STD_LINKS[hop]
        if m := _FD_LINK.match(hop):
            return int(m.group(1))
    return None


def writes_through(path: str | os.PathLike[str]) -> bool:
    """Whether an output path must be opened and written as it is, never replaced by a
    rename: ``-``, an existing non-regular file (device, FIFO, socket), or a link to an
    inherited file descriptor (``/dev/stdout`` -> ``/proc/self/fd/1``, ``/dev/fd/N``), even
    when that descriptor is a regular file."""
    text = os.fspath(path)
    if text == "-":
        return True
    if os.path.exists(text) and not os.path.isfile(text) and not os.path.isdir(text):
        return True
    return _inherited_fd(text) is not None


def check_output_file(path: str | os.PathLike[str], *, allow_special: bool = False) -> Path:
    """Check, before any work, that the file ``path`` can be written (see
    :func:`check_output_dir` for its folder).

    Parameters
    ----------
    path : path-like
        The output file.
    allow_special : bool
        Accept ``-``, a device, a FIFO or a link to an inherited descriptor (see
        :func:`writes_through`), written as they are by :func:`write_output_text`; refused
        by default.

    Raises
    ------
    OutputPathError
        One line saying why.
    """
    target = Path(path)
    if str(path) == "":
        raise OutputPathError("empty path")
    if target.is_dir():
        raise OutputPathError("is a folder, not a file")
    if writes_through(path):
        if not allow_special:
            raise OutputPathError("is not a regular file (a device, pipe or standard stream)")
        if str(path) != "-" and not target.exists():
            raise OutputPathError("is a link to nothing")
        return target
    _probe_writable(_nearest_existing(target.parent))
    return target


def write_output_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to a user-chosen output file.

    ``-`` is standard output; ``/dev/stdout``, ``/dev/fd/N`` and the like are written to the
    inherited descriptor; a device or FIFO (see :func:`writes_through`) is opened and
    written to; none is ever replaced (an atomic rename
    over ``/dev/stdout`` would replace the link or device node); anything else is written
    atomically (:func:`atomic_write_text`), through a symbolic link to its target.
    """
    if os.fspath(path) == "-":
        sys.stdout.write(text)
        sys.stdout.flush()
        return
    if writes_through(path):
        fd = _inherited_fd(path)
        if fd in (1, 2):
            stream = sys.stdout if fd == 1 else sys.stderr
            stream.write(text)
            stream.flush()
        elif fd is not None:  # write at the descriptor's own offset, as a shell would
            data = memoryview(text.encode("utf-8"))
            while data:
                data = data[os.write(fd, data):]
        else:
            with open(path, "a", encoding="utf-8") as fh:
                fh.write(text)
        return
    atomic_write_text(os.path.realpath(path), text)


#: Name of the lock file :func:`lock_folder` keeps in a folder while a run writes into it.
LOCK_FILE = ".arenabench.lock"


class FolderLockedError(RuntimeError):
    """Another process holds the folder's lock; the message says who (pid, host, command)."""


@contextlib.contextmanager
def lock_folder(folder: str | os.PathLike[str], *, command: str = "") -> Iterator[Path]:
    """Hold an exclusive lock on ``folder`` (created) while the ``with`` body runs.

    The lock is :func:`fcntl.flock` on ``folder/.arenabench.lock``, which holds the holder's
    pid, host, start time and ``command``; it is released (and the file removed) on exit,
    and by the kernel when the process dies, so a killed run never leaves a stale lock.

    Raises
    ------
    FolderLockedError
        At once (no waiting) when another process holds it; the message names the holder.
    OSError
        When the folder or the lock file cannot be created.
    """
    import fcntl
    import socket

    root = Path(folder)
    root.mkdir(parents=True, exist_ok=True)
    path = root / LOCK_FILE
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, _FILE_MODE)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                holder = " ".join(os.pread(fd, 4096, 0).decode("utf-8", "replace").split())
            finally:
                os.close(fd)
            raise FolderLockedError(
                f"{root} is being written by another run ({holder or 'holder unknown'})"
            ) from None
        try:  # the holder before us may have removed the file between our open and flock
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        info = (f"pid {os.getpid()} on {socket.gethostname()}, since "
                f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}: {command}\n")
        os.ftruncate(fd, 0)
        os.pwrite(fd, info.encode("utf-8"), 0)
        yield root
    finally:
        try:
            os.unlink(path)
        except FileNotFoundError:
            pass
        os.close(fd)  # releases the flock
