"""Exit statuses are declared once (:class:`arenabench.exitcodes.ExitCode`): every number has
one meaning, and no command module returns a bare number."""

from __future__ import annotations

import ast
import importlib.util
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from paths import ROOT

from arenabench.cli import COMMANDS
from arenabench.exitcodes import ExitCode
from arenabench.interrupts import exit_code

#: Where the commands' modules live besides those :data:`COMMANDS` names.
DISPATCH = ("arenabench.cli",)


def _source(module: str) -> Path:
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin, module
    return Path(spec.origin)


def bare_exit_statuses(source: str) -> list[str]:
    """``line: code`` of each ``return N`` (or ``return A if C else B`` with a number),
    ``sys.exit(N)``, ``SystemExit(N)`` and ``os._exit(N)`` with a literal integer."""
    found = []
    for node in ast.walk(ast.parse(source)):
        value = None
        if isinstance(node, ast.Return) and node.value is not None:
            value = node.value
        elif isinstance(node, ast.Call) and ast.unparse(node.func) in (
                "sys.exit", "SystemExit", "os._exit", "exit") and node.args:
            value = node.args[0]
        if value is None:
            continue
        branches = [value.body, value.orelse] if isinstance(value, ast.IfExp) else [value]
        if any(isinstance(b, ast.Constant) and type(b.value) is int for b in branches):
            found.append(f"{node.lineno}: {ast.unparse(node)}")
    return found


@pytest.mark.parametrize("module", sorted({m for m, _ in COMMANDS.values()} | set(DISPATCH)))
def test_no_command_module_returns_a_bare_number(module):
    path = _source(module)
    # every function of the module: a helper that hands a status on to main returns an
    # ExitCode too (counts and sizes are computed, never a bare literal)
    offences = [f"{path.relative_to(ROOT)}:{line}"
                for line in bare_exit_statuses(path.read_text())]
    assert not offences, "\n".join(offences)


def test_the_checker_sees_each_form_of_a_bare_status():
    code = ("def main():\n    if a:\n        return 2\n    if b:\n        sys.exit(1)\n"
            "    return 0 if c else ExitCode.FAILED\n")
    assert len(bare_exit_statuses(code)) == 3
    assert bare_exit_statuses("def main():\n    return ExitCode.OK\n") == []


def test_each_status_has_one_meaning_and_signals_are_128_plus_their_number():
    assert len({int(c) for c in ExitCode}) == len(ExitCode)
    assert ExitCode.INTERRUPTED == exit_code(signal.SIGINT) == 128 + signal.SIGINT
    assert ExitCode.TERMINATED == exit_code(signal.SIGTERM) == 128 + signal.SIGTERM
    assert ExitCode.BROKEN_PIPE == 128 + signal.SIGPIPE


def test_every_status_is_in_the_reference_docs():
    text = (ROOT / "docs" / "commands.md").read_text()
    table = text[text.index("| Exit status |"):]
    for code in ExitCode:
        assert f"| {int(code)} | `{code.name}`" in table, code


@pytest.mark.parametrize("argv, expected", [
    ([], ExitCode.USAGE),
    (["--version"], ExitCode.OK),
    (["detect", "--image", "/no/such/image.png"], ExitCode.USAGE),
])
def test_commands_exit_with_the_declared_statuses(argv, expected):
    proc = subprocess.run([sys.executable, "-m", "arenabench", *argv], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == expected, proc.stderr
