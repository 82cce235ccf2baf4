"""Run seeds a submission cannot guess: ``arenabench generate --seed random``.

A generated set is byte-identical for a given seed, so whoever knows (or can enumerate) the
seed can re-render the set and read its answer key. ``--seed random`` draws
:data:`RANDOM_SEED_BITS` bits from the operating system (:func:`secrets.randbits`); ``grade``
refuses a generated set whose seed is below :data:`GUESSABLE_BELOW` unless told otherwise.
"""

from __future__ import annotations

import secrets

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


def is_guessable(seed: int) -> bool:
    """Whether ``seed`` is small enough to enumerate."""
    return int(seed) < GUESSABLE_BELOW
