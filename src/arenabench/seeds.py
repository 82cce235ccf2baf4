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
#: The largest seed any command takes: every seed fits in the bits of a random one.
MAX_SEED = 2**RANDOM_SEED_BITS - 1


def random_seed() -> int:
    """A seed of :data:`RANDOM_SEED_BITS` bits from the operating system, at least
    :data:`GUESSABLE_BELOW`."""
    while True:
        seed = secrets.randbits(RANDOM_SEED_BITS)
        if seed >= GUESSABLE_BELOW:
            return seed


def check_seed(seed: object, *, name: str = "seed") -> int:
    """``seed`` as an int when it is an integer in [0, :data:`MAX_SEED`].

    Raises
    ------
    ValueError
        ``"<name> must be an integer in [0, 2**128 - 1], got <seed>"`` (the value shortened).
    """
    import numbers

    if (isinstance(seed, bool) or not isinstance(seed, numbers.Integral)
            or not 0 <= int(seed) <= MAX_SEED):
        shown = repr(seed) if len(repr(seed)) <= 50 else repr(seed)[:40] + "..."
        raise ValueError(f"{name} must be an integer in [0, 2**{RANDOM_SEED_BITS} - 1], got "
                         f"{shown}")
    return int(seed)


def parse_seed(text: str, *, allow_random: bool = True, name: str = "--seed") -> int:
    """``--seed``: an integer in [0, :data:`MAX_SEED`] written in plain ASCII decimal, or
    (``allow_random``) ``random`` (:func:`random_seed`).

    Raises
    ------
    ValueError
        For anything else, one line naming ``name`` (argparse turns it into one usage line).
    """
    from arenabench.plain_numbers import plain_number

    if allow_random and text.strip().lower() == "random":
        return random_seed()
    try:
        value = plain_number(text, "int")
    except ValueError:
        either = "'random' nor " if allow_random else ""
        raise ValueError(f"{name}: not {either}an integer in [0, 2**{RANDOM_SEED_BITS} - 1]: "
                         f"{text[:50]!r}") from None
    return check_seed(value, name=name)


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
