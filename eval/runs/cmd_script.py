"""The script a ``--cmd`` template names must exist before any image runs.

A mistyped script (``python3 mapp.py --image {image}``) would otherwise fail every image the
same way, and the run's message would name the path inside the sandbox, not what was typed.
"""

from __future__ import annotations

import os
import shlex
from pathlib import Path

from arenabench.cmdtemplate import TemplateError, fill, placeholders

from .warm_target import PYTHON_NAME

#: Most entries of the script's folder looked at for a "did you mean".
_MAX_LISTED = 1000


def _runs_python(program: str) -> bool:
    return program in ("{python}", "{competition_python}") or bool(
        PYTHON_NAME.fullmatch(os.path.basename(program)))


def missing_script_problem(template: str, *, base_dir: str | os.PathLike[str]) -> str | None:
    """Why the script ``template`` runs does not exist, as one line naming it as typed, or
    ``None``.

    A script argument is one that ends in ``.py``, or the first argument after a Python
    interpreter (``python``, ``python3``, ``python3.X``, ``{python}``) that is not an option;
    one holding a placeholder is filled per run and not checked. Relative paths are resolved
    from ``base_dir`` (as :class:`~arenabench.eval.runs.pipeline.CommandPipeline` does).
    """
    try:
        args = shlex.split(template)
    except ValueError:  # unbalanced quotes: the runner's own error says so
        return None
    if not args:
        return None
    python = _runs_python(args[0])
    for i, arg in enumerate(args[1:], 1):
        try:
            if placeholders(arg):
                continue
            text = fill(arg, {})
        except TemplateError:
            return None  # the template's own error is reported elsewhere
        if not text or text.startswith("-"):
            continue
        if not (text.endswith(".py") or (python and i == 1)):
            continue
        path = Path(base_dir, text)
        if path.exists():
            continue
        where = "" if os.path.isabs(text) else f" (relative to {base_dir})"
        return f"script {text!r} does not exist{where}{_similar(path)}"
    return None


def _similar(path: Path) -> str:
    from itertools import islice

    from arenabench.suggest import did_you_mean

    try:
        with os.scandir(path.parent) as it:
            names = [e.name for e in islice(it, _MAX_LISTED)]
    except OSError:
        return ""
    return did_you_mean(path.name, names)
