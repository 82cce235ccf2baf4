"""The leaderboard of a grading run: one row per team, ranked, and its JSON form.

Ranking (best first): pass rate (higher), then count exact rate (higher), then the median
``|area_rel_err|`` (lower; a team that never answered comes after any that did). Nothing that
depends on wall-clock time ranks: teams equal on those three keys share a rank (shown as a
tie, "2=") and are listed by name, so the same submissions get the same ranks every run.
Latency is reported, never ranked on; a timed-out image has no latency (``null``).

``leaderboard.json`` (schema ``arenabench.leaderboard/1``; :data:`LEADERBOARD_JSON_SCHEMA`
is its JSON Schema)::

    {"schema": "arenabench.leaderboard/1",
     "dataset": {"path": ..., "manifest_sha256": ..., "n": 200},
     "options": {the grading options: command, output, tolerance, area_reference, run},
     "ranking": ["pass_rate desc", "count_exact_rate desc", ...], "tie_order": "team asc",
     "complete": true, "images_done": 1200, "images_total": 1200,
     "sandbox": {the preflight: sandbox mode, limits, interpreter and module versions seen
                 inside the sandbox, whether arenabench is importable there, how --max-procs
                 is enforced ("process_limit")},
     "categories": ["markers_not_found", "wrong_count", ...],
     "unfinished": [{"team": "gamma", "images_done": 37, "images_total": 200}],
     "teams": [{"rank": 1, "tied": false, "team": "alpha", "n": 200, "n_passed": 198,
                "pass_rate": 0.99,
                "pass_rate_ci95": [0.96, 1.0], "count_exact_rate": 0.995,
                "count_mae": 0.005, "area_rel_err_median": 0.012,
                "latency_ms_median": 412.0, "failures": {"crash": 2, ...},
                "robust_failure_rate": 0.005, "phase_dependent_failure_rate": 0.005,
                "report": "teams/alpha/report.html", "submission_sha256": ...}, ...]}

``unfinished`` (empty unless the grade was interrupted) lists the teams not graded, with how
many of their images ran (their results are kept: the same command resumes from there).
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

from arenabench.eval.scoring.metric_registry import METRIC, Metric
from arenabench.eval.scoring.results import CATEGORIES, Summary

LEADERBOARD_SCHEMA = "arenabench.leaderboard/1"

#: The ranking keys, in order, as written into ``leaderboard.json``.
RANKING: tuple[str, ...] = (
    "pass_rate desc",
    "count_exact_rate desc",
    "area_rel_err_median asc (null last)",
)
#: The phase check's counts a leaderboard entry carries (``phase_check``, when it ran):
#: images labelled depends-on-open and unchecked (no run completed), runs tried and runs that
#: did not complete (docs/phase-check.md).
PHASE_CHECK_COUNTS = ("depends_on_open", "none_completed", "runs", "not_completed")
#: The summary metrics of a team's row, under their flat keys (:attr:`Metric.key`:
#: ``area_rel_err_median``); ``null`` when undefined.
LEADERBOARD_METRICS: tuple[Metric, ...] = tuple(METRIC[n] for n in (
    "pass_rate", "count_exact_rate", "count_mae", "area_rel_err.median", "latency_ms.median",
    "robust_failure_rate", "phase_dependent_failure_rate",
))
#: How teams equal on every :data:`RANKING` key are listed (they share a rank).
TIE_ORDER = "team asc"

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
        1-based rank (0 until ranked); teams equal on every ranking key share it.
    tied : bool
        Whether another team shares the rank.
    """

    team: str
    summary: Summary
    report: str
    submission_sha256: str
    rank: int = 0
    tied: bool = False

    @property
    def area_rel_err_median(self) -> float | None:
        """Median ``|area_rel_err|`` over the answered images (``None`` without answers)."""
        return _finite(self.summary.area_rel_err.get("median"))

    @property
    def latency_ms_median(self) -> float | None:
        """Median latency in ms (``None`` without images)."""
        return _finite(self.summary.latency_ms.get("median"))

    def rank_key(self) -> tuple[float, ...]:
        """The ranking key (:data:`RANKING`): equal keys share a rank."""
        area = self.area_rel_err_median
        return (-self.summary.pass_rate, -self.summary.count_exact_rate,
                math.inf if area is None else area)

    def sort_key(self) -> tuple[Any, ...]:
        """The listing order: :meth:`rank_key`, then :data:`TIE_ORDER`."""
        return (*self.rank_key(), self.team)

    def to_dict(self, categories: Sequence[str] = CATEGORIES) -> dict[str, Any]:
        """JSON form (an entry of ``leaderboard.json["teams"]``)."""
        s = self.summary
        d = s.to_dict()
        return {
            "rank": self.rank,
            "tied": self.tied,
            "team": self.team,
            "n": s.n,
            "n_passed": s.n_passed,
            "pass_rate_ci95": [float(v) for v in s.pass_rate_ci95],
            **{m.key: _finite(m.value(d)) for m in LEADERBOARD_METRICS},
            "failures": {c: int(s.failures.get(c, 0)) for c in categories},
            **({} if s.phase_check is None else {"phase_check": {
                k: s.phase_check.get(k, 0) for k in PHASE_CHECK_COUNTS}}),
            "report": self.report,
            "submission_sha256": self.submission_sha256,
        }


def _finite(value: Any) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def rank_rows(rows: Iterable[LeaderboardRow]) -> list[LeaderboardRow]:
    """Rows sorted best first, ranked 1, 2, 2, 4, ... (equal :meth:`~LeaderboardRow.rank_key`
    share a rank and are ``tied``; listed by name)."""
    ordered = sorted(rows, key=LeaderboardRow.sort_key)
    keys = [r.rank_key() for r in ordered]
    out = []
    for i, r in enumerate(ordered):
        first = keys.index(keys[i])
        tied = keys.count(keys[i]) > 1
        out.append(replace(r, rank=first + 1, tied=tied))
    return out


def categories_of(rows: Iterable[LeaderboardRow]) -> tuple[str, ...]:
    """The failure categories to list: the known ones, then any other found in a summary."""
    extra = sorted({c for r in rows for c in r.summary.failures} - set(CATEGORIES))
    return (*CATEGORIES, *extra)


def leaderboard_dict(
    rows: Sequence[LeaderboardRow],
    *,
    dataset: Mapping[str, Any],
    options: Mapping[str, Any],
    images_done: int | None = None,
    images_total: int | None = None,
    sandbox: Mapping[str, Any] | None = None,
    unfinished: Sequence[Mapping[str, Any]] = (),
) -> dict[str, Any]:
    """The JSON document of ``leaderboard.json`` (rows must be ranked already).

    ``images_done`` of ``images_total`` (team-image runs) say how much of the grading ran;
    ``complete`` is false when fewer ran (an interrupted grade), and ``unfinished`` names the
    teams not graded then, each with ``images_done`` of ``images_total`` (its images whose
    results are kept for the next run). ``sandbox`` is what the preflight saw
    (:mod:`arenabench.eval.grade.preflight`).
    """
    categories = categories_of(rows)
    total = sum(r.summary.n for r in rows) if images_total is None else int(images_total)
    done = total if images_done is None else int(images_done)
    return {
        "schema": LEADERBOARD_SCHEMA,
        "dataset": dict(dataset),
        "options": dict(options),
        "ranking": list(RANKING),
        "tie_order": TIE_ORDER,
        "complete": done >= total,
        "images_done": done,
        "images_total": total,
        "sandbox": dict(sandbox) if sandbox is not None else None,
        "categories": list(categories),
        "teams": [r.to_dict(categories) for r in rows],
        "unfinished": [{"team": str(u["team"]), "images_done": int(u["images_done"]),
                        "images_total": int(u["images_total"])} for u in unfinished],
    }


_NUM_OR_NULL = {"type": ["number", "null"]}
_RATE = {"type": "number", "minimum": 0, "maximum": 1}

#: JSON Schema (draft 2020-12) of ``leaderboard.json``.
LEADERBOARD_JSON_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "arenabench.leaderboard/1",
    "title": "arenabench grade leaderboard",
    "type": "object",
    "required": ["schema", "dataset", "options", "ranking", "tie_order", "complete",
                 "images_done", "images_total", "sandbox", "categories", "teams"],
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
        "tie_order": {"type": "string"},
        "complete": {"type": "boolean"},
        "images_done": {"type": "integer", "minimum": 0},
        "images_total": {"type": "integer", "minimum": 0},
        "sandbox": {"type": ["object", "null"]},
        "categories": {"type": "array", "items": {"type": "string"}},
        "unfinished": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["team", "images_done", "images_total"],
                "properties": {
                    "team": {"type": "string"},
                    "images_done": {"type": "integer", "minimum": 0},
                    "images_total": {"type": "integer", "minimum": 0},
                },
            },
        },
        "teams": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["rank", "tied", "team", "n", "n_passed", "pass_rate", "pass_rate_ci95",
                             "count_exact_rate", "count_mae", "area_rel_err_median",
                             "latency_ms_median", "failures", "report", "submission_sha256"],
                "properties": {
                    "rank": {"type": "integer", "minimum": 1},
                    "tied": {"type": "boolean"},
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
                    "phase_check": {"type": "object", "properties": {
                        k: {"type": "integer", "minimum": 0} for k in PHASE_CHECK_COUNTS}},
                    "report": {"type": "string"},
                    "submission_sha256": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
                },
            },
        },
    },
}
