"""The test tiers, declared once: their markers, what belongs in each, and their budgets; and
the pytest plugin that applies them (loaded by tests/conftest.py: ``pytest_plugins``).

Every test belongs to exactly one tier. A test carries the marker of its tier
(``@pytest.mark.integration``, ``@pytest.mark.acceptance``, or a module's ``pytestmark``);
one with neither is a ``unit`` test (this plugin marks it, so ``-m unit`` selects it too).
``make test-fast`` runs ``unit``, ``make test`` runs ``unit`` and ``integration`` in parallel,
``make acceptance`` runs ``acceptance``; ``.ci/run`` runs ``make test`` then ``make acceptance``.

A budget is a figure on an idle 2-core machine, read from the JUnit durations each run writes
(``build/test-results/TIER.xml``; ``tools/test_durations.py`` prints them). It is no timed
test: a run prints the tests over their tier's per-test budget at its end, and a test over it
moves to the next tier (or gets faster); the tier's wall budget is what ``make`` targets keep
to, as measured in docs/measurements.md.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import pytest


@dataclass(frozen=True)
class Tier:
    """One tier of the test suite.

    Attributes
    ----------
    name : str
        Its marker's name.
    holds : str
        What belongs in it (the marker's help text).
    test_budget_s : float
        The most one test of it (setup, call and teardown) should take on an idle 2-core
        machine.
    wall_budget_s : float
        The most the whole tier should take, wall-clock, on an idle 2-core machine.
    """

    name: str
    holds: str
    test_budget_s: float
    wall_budget_s: float


#: The tiers, fastest first. ``unit`` is the default: a test carrying no tier marker is one.
TIERS: tuple[Tier, ...] = (
    Tier("unit", "pure functions, one render or a command run in process; well under a second "
         "each (the default: no marker)", test_budget_s=1.0, wall_budget_s=60.0),
    Tier("integration", "real processes, sandboxes, pools, Dask, a browser, a command end to "
         "end, many renders: a second or more each", test_budget_s=60.0, wall_budget_s=660.0),
    Tier("acceptance", "measurements against bounds: the twin's acceptance, blind round trips, "
         "competition-style tallies, the generator-pipeline check", test_budget_s=600.0,
         wall_budget_s=1500.0),
)
#: The tier of a test that names none.
DEFAULT = TIERS[0].name
BY_NAME: dict[str, Tier] = {tier.name: tier for tier in TIERS}


def slowest(names: set[str] | list[str]) -> str:
    """The slowest of the tiers named (``DEFAULT`` when none is): a test marked for two tiers
    (a module's and a case's own) belongs to the slower."""
    order = [tier.name for tier in TIERS]
    named = [name for name in names if name in BY_NAME]
    return max(named, key=order.index) if named else DEFAULT


# ------------------------------------------------------------------- the plugin's hooks


def pytest_addoption(parser):
    parser.addoption(
        "--tier", action="append", choices=list(BY_NAME), default=[],
        help="run only the tests of this tier (repeatable; tests/tiers.py): a test's tier is "
             "the slowest it is marked for, so a module's marker and a case's never both match")


def pytest_configure(config):
    for tier in TIERS:
        config.addinivalue_line("markers", f"{tier.name}: {tier.holds}")
    config.pluginmanager.register(BudgetReport(), "arenabench-tier-budgets")


def tier_of(item: pytest.Item) -> str:
    """A test's tier: the slowest tier among its markers (its own, its class's, its module's),
    ``unit`` when it has none."""
    return slowest({mark.name for mark in item.iter_markers()})


@pytest.hookimpl(tryfirst=True)  # before ``-m`` deselects: ``-m unit`` sees the default
def pytest_collection_modifyitems(config, items):
    wanted = set(config.getoption("--tier"))
    kept, dropped = [], []
    for item in items:
        tier = tier_of(item)
        if item.get_closest_marker(tier) is None:
            item.add_marker(tier)
        item.user_properties.append(("tier", tier))  # in the JUnit file, beside its time
        (kept if not wanted or tier in wanted else dropped).append(item)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept


class BudgetReport:
    """Each test's seconds (setup, call and teardown added up) and tier, as this process sees
    the reports (under xdist the controller sees every worker's), and at the end, per tier,
    the tests over its per-test budget. One per pytest run (:func:`pytest_configure`)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.tier: dict[str, str] = {}

    def pytest_runtest_logreport(self, report):
        self.seconds[report.nodeid] += report.duration
        # the markers travel with the report (from an xdist worker too) as keywords
        self.tier[report.nodeid] = slowest([name for name in BY_NAME if name in report.keywords])

    def pytest_terminal_summary(self, terminalreporter, config):
        if hasattr(config, "workerinput") or not self.seconds:  # a worker: the controller says
            return
        terminalreporter.section("tiers: seconds per test against each tier's budget")
        for tier in TIERS:
            mine = {n: s for n, s in self.seconds.items() if self.tier.get(n) == tier.name}
            if not mine:
                continue
            over = sorted(((s, n) for n, s in mine.items() if s > tier.test_budget_s),
                          reverse=True)
            terminalreporter.write_line(
                f"{tier.name}: {len(mine)} tests, {sum(mine.values()):.0f} s of test time; "
                f"{len(over)} over the {tier.test_budget_s:g} s budget of one test")
            for seconds, nodeid in over[:10]:
                terminalreporter.write_line(f"    {seconds:7.1f} s  {nodeid}")
            if len(over) > 10:
                terminalreporter.write_line(f"    ... {len(over) - 10} more")
