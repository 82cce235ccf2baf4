"""Read the JUnit files a test run writes (build/test-results/*.xml): where the time went.

    .venv/bin/python tools/test_durations.py                        # every file there
    .venv/bin/python tools/test_durations.py build/test-results/test.xml --top 40

Prints, for each file given, the tests by tier (count and seconds of test time: setup, call
and teardown, as pytest's junitxml records them with ``junit_duration_report = total``), the
test modules that took longest, and the slowest tests. Test time is summed over the workers,
so with N workers the wall time is roughly the total divided by N (the run's own last line
says the wall time).
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

RESULTS = Path("build/test-results")


def cases(path: Path) -> list[dict]:
    """Each test case of a JUnit file: its id, module, tier, seconds and outcome."""
    out = []
    for case in ET.parse(path).getroot().iter("testcase"):
        props = {p.get("name"): p.get("value") for p in case.iter("property")}
        module = case.get("classname", "").split(".")
        # classname is module.path[.Class]: the module ends at the first part named test_*
        cut = next((i for i, part in enumerate(module) if part.startswith("test_")),
                   len(module) - 1)
        outcome = ("failed" if case.find("failure") is not None or case.find("error") is not None
                   else "skipped" if case.find("skipped") is not None else "passed")
        out.append({"id": f"{case.get('classname')}::{case.get('name')}",
                    "module": "/".join(module[:cut + 1]) + ".py",
                    "tier": props.get("tier", "?"), "seconds": float(case.get("time", 0)),
                    "outcome": outcome})
    return out


def report(path: Path, top: int) -> None:
    found = cases(path)
    print(f"{path}: {len(found)} tests, {sum(c['seconds'] for c in found):.0f} s of test time")
    by_tier: dict[str, list[float]] = defaultdict(list)
    by_module: dict[str, float] = defaultdict(float)
    for c in found:
        by_tier[c["tier"]].append(c["seconds"])
        by_module[c["module"]] += c["seconds"]
    for tier, seconds in sorted(by_tier.items()):
        print(f"  tier {tier}: {len(seconds)} tests, {sum(seconds):.0f} s")
    outcomes: dict[str, int] = defaultdict(int)
    for c in found:
        outcomes[c["outcome"]] += 1
    print("  " + ", ".join(f"{n} {what}" for what, n in sorted(outcomes.items())))
    print(f"  the {min(top, len(by_module))} slowest modules:")
    for module, seconds in sorted(by_module.items(), key=lambda kv: -kv[1])[:top]:
        print(f"    {seconds:8.1f} s  {module}")
    print(f"  the {min(top, len(found))} slowest tests:")
    for c in sorted(found, key=lambda c: -c["seconds"])[:top]:
        print(f"    {c['seconds']:8.1f} s  [{c['tier']}]  {c['id']}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="test_durations", description=__doc__.split("\n")[0])
    parser.add_argument("files", nargs="*", type=Path,
                        help=f"JUnit files (default: {RESULTS}/*.xml)")
    parser.add_argument("--top", type=int, default=25, help="rows of each list (default 25)")
    args = parser.parse_args(argv)
    files = args.files or sorted(RESULTS.glob("*.xml"))
    if not files:
        print(f"test_durations: no JUnit file given and none in {RESULTS}", file=sys.stderr)
        return 2
    for path in files:
        if not path.is_file():
            print(f"test_durations: {path}: no such file", file=sys.stderr)
            return 2
        report(path, args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
