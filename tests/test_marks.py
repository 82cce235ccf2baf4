"""``marks.integration_but``: the inner loop keeps the cases named, every other case is marked
``integration``; a test's tier is the slowest it is marked for."""

import pytest
from marks import integration_but


def _integration(case) -> bool:
    return any(m.name == "integration" for m in getattr(case, "marks", ()))


def test_every_case_but_the_named_ones_is_integration():
    cases = integration_but(["a", "b", "c"], "b")
    assert [_integration(c) for c in cases] == [True, False, True]
    assert cases[1] == "b"  # a kept case is passed on as given
    assert [c.values for c in (cases[0], cases[2])] == [("a",), ("c",)]


def test_tuples_and_params_keep_their_values_marks_and_ids():
    other = pytest.mark.skipif(False, reason="kept")
    cases = integration_but([(1, "x"), pytest.param(2, "y", marks=other, id="two"), (3, "z")],
                            (3, "z"))
    assert cases[0].values == (1, "x") and _integration(cases[0])
    assert cases[1].id == "two" and _integration(cases[1])
    assert [m.name for m in cases[1].marks] == ["skipif", "integration"]
    assert cases[2] == (3, "z")
    assert not _integration(integration_but([pytest.param(5, id="five")], "five")[0])


def test_a_fast_case_that_is_not_there_is_an_error():
    with pytest.raises(ValueError, match="'d'"):
        integration_but(["a", "b"], "a", "d")


def test_the_first_cases_can_be_kept_by_position():
    cases = integration_but([("a", 1), ("b", 2), ("c", 3)], first=2)
    assert cases[:2] == [("a", 1), ("b", 2)] and _integration(cases[2])


def test_a_test_belongs_to_the_slowest_tier_it_is_marked_for():
    from tiers import DEFAULT, TIERS, slowest

    names = [tier.name for tier in TIERS]
    assert names[0] == DEFAULT == slowest([]) == slowest(["parametrize", "skipif"])
    assert slowest(["integration"]) == "integration"
    assert slowest(["acceptance", "integration"]) == slowest(["integration", "acceptance"])
    assert slowest(["integration", "acceptance"]) == "acceptance"


def test_every_tier_is_a_registered_marker_with_a_budget(pytestconfig):
    from tiers import TIERS

    registered = {line.split(":")[0] for line in pytestconfig.getini("markers")}
    assert {tier.name for tier in TIERS} <= registered
    budgets = [tier.test_budget_s for tier in TIERS]
    assert budgets == sorted(budgets) and all(tier.wall_budget_s > 0 for tier in TIERS)


def test_tier_selection_runs_each_test_once_across_the_tiers(pytester):
    """``--tier`` keeps a test of a module marked integration with a case marked acceptance
    out of the integration run: the two runs together hold each test once."""
    pytester.makepyfile(test_mixed="""
        import pytest
        pytestmark = pytest.mark.integration

        def test_plain():
            pass

        @pytest.mark.acceptance
        def test_measured():
            pass
    """, test_bare="def test_unit():\n    pass\n")
    ran = {}
    for tier in ("unit", "integration", "acceptance"):
        result = pytester.runpytest("-p", "tiers", "--tier", tier, "-p", "no:cacheprovider",
                                    "-v")
        ran[tier] = sorted(line.split("::")[1].split()[0] for line in result.outlines
                           if "PASSED" in line)
    assert ran == {"unit": ["test_unit"], "integration": ["test_plain"],
                   "acceptance": ["test_measured"]}
