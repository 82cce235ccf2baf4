"""Which cases of a parametrized test the inner loop (the ``unit`` tier) runs.

``make test-fast`` runs the ``unit`` tier; ``make test`` (and CI) runs ``integration`` too
(tests/tiers.py). A family of cases that each start processes, render scenes or run a command
end to end keeps one or two representatives in the inner loop and marks the rest
``integration``::

    @pytest.mark.parametrize("name", integration_but(sorted(liar.ANSWERS), "nan_area"))
    @pytest.mark.parametrize(("args", "needle"), integration_but([...], first=2))
"""

from __future__ import annotations

from collections.abc import Iterable

import pytest


def integration_but(values: Iterable[object], *fast: object, first: int = 0) -> list[object]:
    """``values`` for ``pytest.mark.parametrize``, every one but those in ``fast`` (and the
    ``first`` ones) marked ``integration``.

    Parameters
    ----------
    values : iterable
        The cases: single values, tuples (several argument names) or ``pytest.param`` objects
        (their own marks and id kept).
    *fast : object
        The cases the inner loop runs: a value as given in ``values`` (for a
        ``pytest.param``, its id or its value).
    first : int, keyword-only
        The cases the inner loop runs, by position: the first ``first`` (for long lists of
        tuples that a value would repeat).

    Raises
    ------
    ValueError
        When a case named in ``fast`` is not among ``values`` (a renamed case would otherwise
        leave the inner loop without a representative, silently).
    """
    param_set = type(pytest.param(None))
    out: list[object] = []
    seen: set[int] = set()
    for position, value in enumerate(values):
        if isinstance(value, param_set):
            keys = [value.id, value.values, value.values[0] if len(value.values) == 1 else None]
        else:
            keys = [value]
        hit = [i for i, f in enumerate(fast) if f is not None and f in keys]
        seen.update(hit)
        if hit or position < first:
            out.append(value)
        elif isinstance(value, param_set):
            out.append(pytest.param(*value.values, marks=(*value.marks, pytest.mark.integration),
                                    id=value.id))
        else:
            args = value if isinstance(value, tuple) else (value,)
            out.append(pytest.param(*args, marks=pytest.mark.integration))
    missing = [f for i, f in enumerate(fast) if i not in seen]
    if missing:
        raise ValueError(f"integration_but: fast case(s) {missing!r} not among the values")
    return out
