"""Atomic file writes, hashing and float rounding for JSON, shared by every package.

Nothing half-written is ever left under a final name: data goes to a temporary file in the
same directory, is flushed, then renamed over the target (``os.replace`` is atomic on POSIX).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

#: Decimal places kept for floats in the JSON files arenabench writes (ground truth,
#: coco.json): stable, byte-identical files.
JSON_DECIMALS = 6


def _process_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: Read once at import: files get the permissions ``open()`` would give them (mkstemp's are 0600).
_FILE_MODE = 0o666 & ~_process_umask()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically, creating parent directories.

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
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def dumps_json(obj: Any) -> str:
    """Serialise ``obj`` to canonical JSON text (sorted keys, 2-space indent, trailing newline).

    Canonical output keeps files byte-identical for identical content.
    """
    return json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n"


def atomic_write_json(path: str | os.PathLike[str], obj: Any) -> Path:
    """Write ``obj`` as canonical JSON to ``path`` atomically."""
    return atomic_write_text(path, dumps_json(obj))


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of the file at ``path``, read in chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


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
