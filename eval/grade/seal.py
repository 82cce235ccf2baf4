"""Seals on what ``grade`` keeps between runs (a team's partial results, its state): an HMAC
with a key kept outside ``--out``, so that a file edited by hand is never trusted.

The key is 32 random bytes in the cache (:func:`arenabench.usercache.cache_dir`, file
:data:`KEY_FILE`, mode 0600), made on first use. Whoever can write the output folder but not
the organiser's cache cannot forge a result: a line or state whose seal does not match is
ignored (its image runs again, its team is graded again). An output folder moved to another
machine or user is graded again from the start (fail closed).
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import os
import secrets
from typing import Any

from arenabench.fileio import dumps_json
from arenabench.usercache import cache_dir

#: The key's file in the cache.
KEY_FILE = "grade-seal.key"
#: The key's length in bytes.
KEY_BYTES = 32
#: The field of a sealed record that holds its seal.
SEAL = "seal"


@functools.lru_cache(maxsize=1)
def _key() -> bytes:
    path = cache_dir() / KEY_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        pass
    else:
        with os.fdopen(fd, "wb") as fh:
            fh.write(secrets.token_bytes(KEY_BYTES))
    key = path.read_bytes()
    if len(key) != KEY_BYTES:
        raise OSError(f"{path}: not a seal key of {KEY_BYTES} bytes (remove it: grade makes "
                      "a new one, and grades every team again)")
    return key


def seal(doc: dict[str, Any]) -> str:
    """The seal of ``doc`` (its canonical JSON, without a ``seal`` field)."""
    body = {k: v for k, v in doc.items() if k != SEAL}
    return hmac.new(_key(), dumps_json(body).encode(), hashlib.sha256).hexdigest()


def sealed(doc: dict[str, Any]) -> dict[str, Any]:
    """``doc`` with its seal."""
    return {**doc, SEAL: seal(doc)}


def intact(doc: Any) -> bool:
    """Whether ``doc`` is a mapping whose seal matches it."""
    return (isinstance(doc, dict) and isinstance(doc.get(SEAL), str)
            and hmac.compare_digest(doc[SEAL], seal(doc)))
