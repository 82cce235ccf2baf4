"""The leaderboard of a grading run: one row per team, ranked, and its JSON form.

Ranking (best first): pass rate (higher), then count exact rate (higher), then the median
``|area_rel_err|`` (lower; a team that never answered comes after any that did), then the
median latency (lower), then the team name, so the order is total and deterministic. Only the
last two keys depend on wall-clock time, and only for teams equal on the first three.

``leaderboard.json`` (schema ``arenabench.leaderboard/1``; :data:`LEADERBOARD_JSON_SCHEMA`
is its JSON Schema)::

    {"schema": "arenabench.leaderboard/1",
     "dataset": {"path": ..., "manifest_sha256": ..., "n": 200},
     "options": {the grading options: command, output, tolerance, area_reference, run},
     "ranking": ["pass_rate desc", "count_exact_rate desc", ...],
     "categories": ["markers_not_found", "wrong_count", ...],
     "teams": [{"rank": 1, "team": "alpha", "n": 200, "n_passed": 198, "pass_rate": 0.99,
                "pass_rate_ci95": [0.96, 1.0], "count_exact_rate": 0.995,
                "count_mae": 0.005, "area_rel_err_median": 0.012,
                "latency_ms_median": 412.0, "failures": {"crash": 2, ...},
                "robust_failure_rate": 0.005, "phase_dependent_failure_rate": 0.005,
                "report": "teams/alpha/report.html", "submission_sha256": ...}, ...]}

Every key is always present; ``area_rel_err_median``, ``count_mae`` and
``latency_ms_median`` are ``null`` when undefined (no answer at all);
``robust_failure_rate`` and ``phase_dependent_failure_rate`` (the phase check,
docs/phase-check.md) are ``null`` when no failure of the team was phase-checked.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from ..records import CATEGORIES, Summary

LEADERBOARD_SCHEMA = "arenabench.leaderboard/1"

#: The ranking keys, in order, as written into ``leaderboard.json``.
RANKING: tuple[str, ...] = (
    "pass_rate desc",
    "count_exact_rate desc",
    "area_rel_err_median asc (null last)",
    "latency_ms_median asc (null last)",
    "team asc",
)

@dataclass(frozen=True)
class LeaderboardRow:
    """One team's line of the leaderboard.

    Parameters
    ----------
    team : str
        The team (its submission folder's name).
    summary : Summary
        The team's evaluation summary.
    report : str
        Path of the team's report, relative to the leaderboard's folder.
    submission_sha256 : str
        Fingerprint of the submission that was graded.
    rank : int
        1-based position (0 until ranked).
    """

    team: str
    summary: Summary
    report: str
    submission_sha256: str
    rank: int = 0

    @property
    def area_rel_err_median(self) -> float | None:
        """Median ``|area_rel_err|`` over the answered images (``None`` without answers)."""
        return _finite(self.summary.area_rel_err.get("median"))

    @property
    def latency_ms_median(self) -> float | None:
        """Median latency in ms (``None`` without images)."""
        return _finite(self.summary.latency_ms.get("median"))

    def sort_key(self) -> tuple[Any, ...]:
        """The ranking key (see the module docstring)."""
        area, latency = self.area_rel_err_median, self.latency_ms_median
        return (
            -self.summary.pass_rate,
            -self.summary.count_exact_rate,
            math.inf if area is None else area,
            math.inf if latency is None else latency,
            self.team,
        )

    def to_dict(self, categories: Sequence[str] = CATEGORIES) -> dict[str, Any]:
        """JSON form (an entry of ``leaderboard.json["teams"]``)."""
        s = self.summary
        return {
            "rank": self.rank,
            "team": self.team,
            "n": s.n,
            "n_passed": s.n_passed,
            "pass_rate": s.pass_rate,
            "pass_rate_ci95": [float(v) for v in s.pass_rate_ci95],
            "count_exact_rate": s.count_exact_rate,
            "count_mae": _finite(s.count_mae),
            "area_rel_err_median": self.area_rel_err_median,
            "latency_ms_median": self.latency_ms_median,
            "failures": {c: int(s.failures.get(c, 0)) for c in categories},
            "robust_failure_rate": _finite(s.robust_failure_rate),
            "phase_dependent_failure_rate": _finite(s.phase_dependent_failure_rate),
            "report": self.report,
            "submission_sha256": self.submission_sha256,
        }


def _finite(value: Any) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def rank_rows(rows: Iterable[LeaderboardRow]) -> list[LeaderboardRow]:
    """Rows sorted best first, with ``rank`` set to 1, 2, ... (no shared ranks)."""
    ordered = sorted(rows, key=LeaderboardRow.sort_key)
    return [replace(r, rank=i) for i, r in enumerate(ordered, 1)]


def categories_of(rows: Iterable[LeaderboardRow]) -> tuple[str, ...]:
    """The failure categories to list: the known ones, then any other found in a summary."""
    extra = sorted({c for r in rows for c in r.summary.failures} - set(CATEGORIES))
    return (*CATEGORIES, *extra)


def leaderboard_dict(
    rows: Sequence[LeaderboardRow],
    *,
    dataset: Mapping[str, Any],
    options: Mapping[str, Any],
) -> dict[str, Any]:
    """The JSON document of ``leaderboard.json`` (rows must be ranked already)."""
    categories = categories_of(rows)
    return {
        "schema": LEADERBOARD_SCHEMA,
        "dataset": dict(dataset),
        "options": dict(options),
        "ranking": list(RANKING),
        "categories": list(categories),
        "teams": [r.to_dict(categories) for r in rows],
    }


_NUM_OR_NULL = {"type": ["number", "null"]}
_RATE = {"type": "number", "minimum": 0, "maximum": 1}

#: JSON Schema (draft 2020-12) of ``leaderboard.json``.
LEADERBOARD_JSON_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "arenabench.leaderboard/1",
    "title": "arenabench grade leaderboard",
    "type": "object",
    "required": ["schema", "dataset", "options", "ranking", "categories", "teams"],
    "properties": {
        "schema": {"const": LEADERBOARD_SCHEMA},
        "dataset": {
            "type": "object",
            "required": ["path", "manifest_sha256", "n"],
            "properties": {
                "path": {"type": "string"},
                "manifest_sha256": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
                "n": {"type": "integer", "minimum": 1},
            },
        },
        "options": {"type": "object"},
        "ranking": {"type": "array", "items": {"type": "string"}},
        "categories": {"type": "array", "items": {"type": "string"}},
        "teams": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["rank", "team", "n", "n_passed", "pass_rate", "pass_rate_ci95",
                             "count_exact_rate", "count_mae", "area_rel_err_median",
                             "latency_ms_median", "failures", "report", "submission_sha256"],
                "properties": {
                    "rank": {"type": "integer", "minimum": 1},
                    "team": {"type": "string"},
                    "n": {"type": "integer", "minimum": 0},
                    "n_passed": {"type": "integer", "minimum": 0},
                    "pass_rate": _RATE,
                    "pass_rate_ci95": {"type": "array", "items": _RATE,
                                       "minItems": 2, "maxItems": 2},
                    "count_exact_rate": _RATE,
                    "count_mae": _NUM_OR_NULL,
                    "area_rel_err_median": _NUM_OR_NULL,
                    "latency_ms_median": _NUM_OR_NULL,
                    "failures": {"type": "object",
                                 "additionalProperties": {"type": "integer", "minimum": 0}},
                    "robust_failure_rate": {"type": ["number", "null"], "minimum": 0,
                                            "maximum": 1},
                    "phase_dependent_failure_rate": {"type": ["number", "null"], "minimum": 0,
                                                     "maximum": 1},
                    "report": {"type": "string"},
                    "submission_sha256": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
                },
            },
        },
    },
}
