"""The phase check's summary of a report (its counts, rates and the words that describe
them), beside the per-image record it summarises
(:class:`~arenabench.eval.scoring.results.PhaseResult`); the check itself is
:mod:`arenabench.eval.phase_check`."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from typing import Any

from arenabench.eval.scoring.results import ImageResult

#: The one sentence every report prints beside the rates.
PHASE_DEPENDENT_MEANING = (
    "phase-dependent: passes at some sub-pixel positions of the boxes and fails at others: on "
    "the hidden tests it would have depended on luck"
)


def phase_summary(results: Sequence[ImageResult]) -> dict[str, Any]:
    """The phase-check keys of a report's summary.

    Returns
    -------
    dict
        ``robust_failure_rate`` and ``phase_dependent_failure_rate`` (fractions of all
        images; ``None`` when no image was phase-checked) and ``phase_check``: ``phases``
        (N), ``checked``, ``robust``, ``phase_dependent``, ``depends_on_open`` (image counts
        by label), ``depends_on`` (open parameter -> images whose verdict rests on it),
        ``none_completed`` (checked images none of whose runs completed: labelled
        ``unchecked``), ``unchecked`` (failing images not checked: the categories outside
        :data:`~arenabench.eval.phase_check.CHECKED_CATEGORIES`), ``runs`` and
        ``not_completed`` (runs tried, and those
        that crashed, timed out, hit a limit or met a harness error), ``meaning`` (one
        sentence); ``None`` when no image was phase-checked.
    """
    checked = [r.phase for r in results if r.phase is not None]
    if not checked:
        return {"robust_failure_rate": None, "phase_dependent_failure_rate": None,
                "phase_check": None}
    n = len(results)
    labels = Counter(p.label for p in checked)
    depends = Counter(name for p in checked if p.label == "depends_on_open"
                      for name in p.depends_on)
    runs = sum(p.total_runs for p in checked)
    return {
        "robust_failure_rate": labels["robust"] / n,
        "phase_dependent_failure_rate": labels["phase_dependent"] / n,
        "phase_check": {"phases": max(p.n for p in checked), "checked": len(checked),
                        "robust": labels["robust"],
                        "phase_dependent": labels["phase_dependent"],
                        "depends_on_open": labels["depends_on_open"],
                        "depends_on": dict(sorted(depends.items())),
                        "none_completed": labels["unchecked"],
                        "unchecked": sum(1 for r in results
                                         if not r.passed and r.phase is None),
                        "runs": runs,
                        "not_completed": runs - sum(p.total_completed for p in checked),
                        "meaning": PHASE_DEPENDENT_MEANING},
    }


def verdict_words(pc: dict[str, Any]) -> list[str]:
    """The phase check's findings beyond robust and phase-dependent, as short clauses for a
    summary line (empty when there are none): images whose verdict rests on an open
    parameter, images none of whose runs completed, runs that did not complete."""
    out = []
    if pc.get("depends_on_open"):
        names = ", ".join(f"{k} {v}" for k, v in (pc.get("depends_on") or {}).items())
        out.append(f"depends on open parameters: {pc['depends_on_open']} ({names})")
    if pc.get("none_completed"):
        out.append(f"unchecked (no run completed): {pc['none_completed']}")
    if pc.get("not_completed"):
        out.append(f"{pc['not_completed']} of {pc.get('runs', 0)} phase runs did not complete "
                   "(crash, timeout, limit or harness error; not counted as failures)")
    return out


def rate_text(value: float | None) -> str:
    """A rate as the reports print it (``-`` when the phase check did not run)."""
    return "-" if value is None or not math.isfinite(value) else f"{100 * value:.1f} %"
