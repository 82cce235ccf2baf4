"""What a warm run executes: the script or module a command runs with a Python interpreter
(``PYTHON FILE.py ...`` or ``PYTHON -m MODULE ...``), read off its arguments."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

#: An interpreter's program name: ``python``, ``python3``, ``python3.11``.
PYTHON_NAME = re.compile(r"python(\d+(\.\d+)*)?")
_MODULE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")


@dataclass(frozen=True)
class WarmTarget:
    """What a warm run executes: a script file or a module (exactly one is set)."""

    script: str | None = None
    module: str | None = None


def warm_target(argv: list[str]) -> WarmTarget | None:
    """The script or module that ``argv`` (the command's resolved arguments, before
    ``{image}`` substitution) runs with a Python interpreter, or ``None`` when it is not
    ``PYTHON FILE.py ...`` or ``PYTHON -m MODULE ...``."""
    if len(argv) < 2:
        return None
    if argv[0] != "{python}" and not PYTHON_NAME.fullmatch(os.path.basename(argv[0])):
        return None
    if argv[1] == "-m" and len(argv) > 2 and _MODULE_NAME.fullmatch(argv[2]):
        return WarmTarget(module=argv[2])
    script = argv[1]
    if script.endswith(".py") and "{" not in script and os.path.isabs(script) and \
            os.path.isfile(script):
        return WarmTarget(script=script)
    return None
