"""A team's command: the default template, the environment every team's run gets, and the
template with the team's folder put in."""

from __future__ import annotations

import os
import shlex
from pathlib import Path

from arenabench.cmdtemplate import fill

#: The competition's command; ``{submission}`` is the team folder's absolute path.
DEFAULT_COMMAND = "python3 {submission}/map.py --image {image}"


#: Variables every team's command gets on top of ``RunSettings.env``: Python must not write
#: ``__pycache__`` into a submission (submissions are read-only inputs).
TEAM_ENV: dict[str, str] = {"PYTHONDONTWRITEBYTECODE": "1"}


def team_command(template: str, submission: str | os.PathLike[str]) -> str:
    """``template`` with ``{submission}`` replaced by the folder's absolute path, argument by
    argument (paths with spaces or quotes stay one argument); the other placeholders stay,
    and the path is put in as literal text (:func:`arenabench.cmdtemplate.escape`): a team
    folder named ``x{image}y`` keeps its name when the image is filled in."""
    values = {"submission": str(Path(submission).absolute())}
    return shlex.join(fill(arg, values, partial=True) for arg in shlex.split(template))
