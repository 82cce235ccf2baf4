""""Did you mean ...?" hints for mistyped names (commands, parameter keys, presets, pipelines)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def did_you_mean(name: str, known: Iterable[str], *, n: int = 3) -> str:
    """A hint naming the known names closest to ``name``, or ``""`` when none is close.

    Parameters
    ----------
    name : str
        What the user typed.
    known : iterable of str
        The valid names.
    n : int, keyword-only
        Most suggestions to give.

    Returns
    -------
    str
        ``" (did you mean 'x'?)"`` or ``" (did you mean 'x' or 'y'?)"``, or ``""``.
    """
    known = list(dict.fromkeys(known))
    close = difflib.get_close_matches(name, known, n=n, cutoff=0.6)
    if close:  # only the ones about as close as the best
        def ratio(k: str) -> float:
            return difflib.SequenceMatcher(None, name, k).ratio()

        best = ratio(close[0])
        close = [k for k in close if ratio(k) >= best - 0.1]
    if not close:
        # a dotted key typed without its section ("tilt_deg" for "camera.tilt_deg")
        close = [k for k in known if k.rsplit(".", 1)[-1] == name][:n]
    if not close:
        return ""
    quoted = [repr(c) for c in close]
    text = quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]
    return f" (did you mean {text}?)"
