"""Whether this machine can enforce ``grade``'s ``--max-procs``, and what grade invocations in
the tests add where it cannot (one place for every test file).

``grade`` fails closed where the process limit cannot be enforced (root without a writable
pids cgroup: :func:`arenabench.eval.grade.preflight.process_limit`). The tests' own grades are not
about that, so there they pass ``--max-procs 0`` (no process limit); everywhere else they run
with the default limit, as an organiser's would. tests/eval/grade/test_grade_procs.py tests
the refusal
itself.
"""

from __future__ import annotations

import shlex
import sys
from typing import Any

from arenabench.eval.grade.preflight import PreflightError, process_limit
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.limits import DEFAULT_MAX_PROCS


def _problem() -> str | None:
    try:
        process_limit(DEFAULT_MAX_PROCS)
    except PreflightError as exc:
        return str(exc)
    return None


#: Why grade's default ``--max-procs`` cannot be enforced here (``None``: it can).
PROBLEM = _problem()
#: ``max_procs`` of the tests' grades: the default, or 0 where it cannot be enforced.
GRADE_MAX_PROCS = DEFAULT_MAX_PROCS if PROBLEM is None else 0
#: Arguments every ``arenabench grade`` command line of the tests adds.
GRADE_ARGS: tuple[str, ...] = () if PROBLEM is None else ("--max-procs", "0")
#: The tests' Python: it has OpenCV (``python3`` on PATH may not). ``grade --cmd`` refuses
#: ``{python}``, so the tests' grading commands name it.
PYTHON = shlex.quote(sys.executable)
#: The competition's grading command run by :data:`PYTHON`.
PY_CMD = f"{PYTHON} {{submission}}/map.py --image {{image}}"


def grade_settings(*, limits: dict[str, Any] | None = None, **settings: Any) -> RunSettings:
    """``RunSettings(**settings)`` for the tests' ``grade()`` calls, its ``limits``
    (``RunLimits`` fields) with ``max_procs`` :data:`GRADE_MAX_PROCS` unless given."""
    return RunSettings(limits=RunLimits(**{"max_procs": GRADE_MAX_PROCS, **(limits or {})}),
                       **settings)
