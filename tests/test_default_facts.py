"""The default preset and the default area reference are declared once
(:data:`arenabench.generator.parameters.presets.DEFAULT_PRESET`,
:data:`arenabench.gtrecord.DEFAULT_AREA_REFERENCE`): no module of the three packages spells
either as a default of its own."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

from arenabench.generator.parameters.presets import DEFAULT_PRESET
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("src/arenabench", "generator", "eval")
#: Keywords that name a preset or an area reference in a call.
NAMING_KEYWORDS = ("default", "preset", "area_reference")


@functools.cache
def _tree(source: str) -> ast.AST:
    """``source`` parsed, once per text (both literals are looked for in the same trees)."""
    return ast.parse(source)


def literal_defaults(source: str, literal: str) -> list[str]:
    """``line: code`` of each place ``literal`` is a default: of a parameter, of a dataclass
    field (a class-level annotated value), a ``default=`` / ``preset=`` / ``area_reference=``
    keyword, or the fallback of ``mapping.get(key, literal)``."""

    def is_it(node: ast.AST | None) -> bool:
        return isinstance(node, ast.Constant) and node.value == literal

    found = []
    for node in ast.walk(_tree(source)):
        hits: list[ast.AST] = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            hits = [d for d in (*node.args.defaults, *node.args.kw_defaults) if is_it(d)]
        elif isinstance(node, ast.ClassDef):
            hits = [s for s in node.body if isinstance(s, ast.AnnAssign) and is_it(s.value)]
        elif isinstance(node, ast.Call):
            hits = [k for k in node.keywords if k.arg in NAMING_KEYWORDS and is_it(k.value)]
            if (isinstance(node.func, ast.Attribute) and node.func.attr == "get"
                    and len(node.args) == 2 and is_it(node.args[1])):
                hits.append(node)
        found += [f"{h.lineno}: {ast.unparse(h)}" for h in hits]
    return found


def _modules() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


@pytest.mark.parametrize("literal", [DEFAULT_PRESET, DEFAULT_AREA_REFERENCE])
def test_no_module_restates_a_declared_default(literal):
    offences = [f"{path.relative_to(ROOT)}:{hit}" for path in _modules()
                for hit in literal_defaults(path.read_text(encoding="utf-8"), literal)]
    assert not offences, "\n".join(offences)


def test_the_checker_sees_each_form_of_a_default():
    code = ("def f(a='eyrc', *, b='eyrc'):\n    return d.get('preset', 'eyrc')\n"
            "class C:\n    preset: str = 'eyrc'\n"
            "p.add_argument('--preset', default='eyrc')\ng(preset='eyrc')\n")
    assert len(literal_defaults(code, "eyrc")) == 6
    # the declaration itself, a table keyed by the name and a docstring are no defaults
    assert literal_defaults("DEFAULT_PRESET = 'eyrc'\nFILES = {'eyrc': 1}\n"
                            "def f():\n    '''f(preset=\"eyrc\")'''\n", "eyrc") == []
