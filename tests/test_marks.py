"""``marks.slow_but``: the inner loop keeps the cases named, every other case is marked slow."""

import pytest
from marks import slow_but


def _slow(case) -> bool:
    return any(m.name == "slow" for m in getattr(case, "marks", ()))


def test_every_case_but_the_named_ones_is_slow():
    cases = slow_but(["a", "b", "c"], "b")
    assert [_slow(c) for c in cases] == [True, False, True]
    assert cases[1] == "b"  # a kept case is passed on as given
    assert [c.values for c in (cases[0], cases[2])] == [("a",), ("c",)]


def test_tuples_and_params_keep_their_values_marks_and_ids():
    other = pytest.mark.skipif(False, reason="kept")
    cases = slow_but([(1, "x"), pytest.param(2, "y", marks=other, id="two"), (3, "z")], (3, "z"))
    assert cases[0].values == (1, "x") and _slow(cases[0])
    assert cases[1].id == "two" and _slow(cases[1])
    assert [m.name for m in cases[1].marks] == ["skipif", "slow"]
    assert cases[2] == (3, "z")
    assert not _slow(slow_but([pytest.param(5, id="five")], "five")[0])


def test_a_fast_case_that_is_not_there_is_an_error():
    with pytest.raises(ValueError, match="'d'"):
        slow_but(["a", "b"], "a", "d")


def test_the_first_cases_can_be_kept_by_position():
    cases = slow_but([("a", 1), ("b", 2), ("c", 3)], first=2)
    assert cases[:2] == [("a", 1), ("b", 2)] and _slow(cases[2])
