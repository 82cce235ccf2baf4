"""``arenabench grade``: run many teams' submissions on one (hidden) dataset, rank them.

::

    from arenabench.eval.grade import GradeOptions, grade

    result = grade("hidden/", "submissions/", "out/", options=GradeOptions(), workers=8)
    result.rows[0].team, result.skipped

See :mod:`arenabench.eval.grade.grading` for the output layout and resuming, and
:mod:`arenabench.eval.grade.leaderboard` for the ranking and ``leaderboard.json``.
"""

from __future__ import annotations

from arenabench.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "DEFAULT_COMMAND": "grading",
    "GradeOptions": "grading",
    "GradeResult": "grading",
    "GradeUnit": "grading",
    "grade": "grading",
    "run_unit": "grading",
    "team_command": "grading",
    "LEADERBOARD_JSON_SCHEMA": "leaderboard",
    "LEADERBOARD_SCHEMA": "leaderboard",
    "LeaderboardRow": "leaderboard",
    "rank_rows": "leaderboard",
    "SubmissionsError": "submissions",
    "Team": "submissions",
    "find_teams": "submissions",
    "submission_hash": "submissions",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
