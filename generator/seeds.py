"""Run seeds a submission cannot guess: ``arenabench generate --seed random``.

A generated set is byte-identical for a given seed, so whoever knows (or can enumerate) the
seed can re-render the set and read its answer key. ``--seed random`` draws
:data:`RANDOM_SEED_BITS` bits from the operating system (:func:`secrets.randbits`); ``grade``
grades only a set whose every recorded seed is an integer of at least :data:`GUESSABLE_BELOW`
(:func:`seed_problem`) unless told otherwise.
"""

from __future__ import annotations

import reprlib
import secrets
from typing import Any

#: Bits of a ``--seed random`` seed.
RANDOM_SEED_BITS = 128
#: Seeds below this are guessable (enumerable); ``grade`` refuses sets generated with them.
GUESSABLE_BELOW = 2**64


def random_seed() -> int:
    """A seed of :data:`RANDOM_SEED_BITS` bits from the operating system, at least
    :data:`GUESSABLE_BELOW`."""
    while True:
        seed = secrets.randbits(RANDOM_SEED_BITS)
        if seed >= GUESSABLE_BELOW:
            return seed


def parse_seed(text: str) -> int:
    """``--seed``: an integer >= 0, or ``random`` (:func:`random_seed`).

    Raises
    ------
    ValueError
        For anything else (argparse turns it into one usage line).
    """
    if text.strip().lower() == "random":
        return random_seed()
    value = int(text, 10)
    if value < 0:
        raise ValueError(f"seed must be >= 0, got {text!r}")
    return value


def seed_problem(seed: Any) -> str | None:
    """Why ``seed``, as a file records it (parsed JSON), does not prove a set unguessable, or
    ``None`` when it does: an integer (not a boolean, a float or a string) of at least
    :data:`GUESSABLE_BELOW`. Fails closed: anything else is a problem.

    Returns
    -------
    str or None
        ``"no seed recorded"``, ``"seed '3' is not an integer"``, ``"seed 3 is below 2**64
        (guessable)"``.
    """
    if seed is None:
        return "no seed recorded"
    if type(seed) is not int:
        return f"seed {reprlib.repr(seed)[:80]} is not an integer"
    if seed < GUESSABLE_BELOW:
        return f"seed {seed} is below 2**{GUESSABLE_BELOW.bit_length() - 1} (guessable)"
    return None


def is_guessable(seed: Any) -> bool:
    """Whether ``seed`` (as a file records it) may be enumerable: anything but an integer of
    at least :data:`GUESSABLE_BELOW` (:func:`seed_problem`)."""
    return seed_problem(seed) is not None
