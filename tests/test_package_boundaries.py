"""The three packages keep their roles (docs/architecture.md, "Import rules"): the pipeline
package never imports the generator or the harness, and the generator never imports the
harness. Checked on the source of every module with ``ast``: absolute and relative imports
(resolved against the module's own package), ``from pkg import submodule``, imports inside
functions, and ``importlib.import_module("...")`` / ``__import__("...")`` with a literal name.

The one sanctioned way across is the command dispatcher, ``arenabench.cli``: it names every
sub-command's module as a string in its table and imports only the one that runs, so no
import statement of the core names the generator or the harness (checked here too, and at
run time below)."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: source folder -> the package its modules belong to
PACKAGES = {
    "src/arenabench": "arenabench",
    "generator": "arenabench.generator",
    "eval": "arenabench.eval",
}

#: source folder -> packages its modules must not import
RULES = {
    "src/arenabench": ("arenabench.generator", "arenabench.eval"),
    "generator": ("arenabench.eval",),
}


def module_name(path: Path) -> tuple[str, bool]:
    """(dotted module name, is a package ``__init__``) of a source file."""
    for folder, package in PACKAGES.items():
        base = ROOT / folder
        if path.is_relative_to(base):
            parts = list(path.relative_to(base).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            if is_pkg:
                parts = parts[:-1]
            return ".".join([package, *parts]), is_pkg
    raise ValueError(f"{path} is in none of {sorted(PACKAGES)}")


def _resolve(module: str | None, level: int, current: str, is_pkg: bool) -> str:
    """Absolute name of ``from <level dots><module> import ...`` inside module ``current``."""
    if level == 0:
        return module or ""
    package = current.split(".") if is_pkg else current.split(".")[:-1]
    if level - 1 > len(package) - 1:
        raise ValueError(f"relative import beyond the top package in {current}")
    base = package[: len(package) - (level - 1)]
    return ".".join([*base, module] if module else base)


def imported_names(source: str, current: str, is_pkg: bool = False) -> list[tuple[int, str]]:
    """Every module name the source imports, as (line, absolute dotted name).

    ``from a.b import c`` yields both ``a.b`` and ``a.b.c`` (``c`` may be a submodule).
    """
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module, node.level, current, is_pkg)
            found.append((node.lineno, base))
            found += [(node.lineno, f"{base}.{a.name}") for a in node.names if a.name != "*"]
        elif isinstance(node, ast.Call) and node.args:
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            first = node.args[0]
            if name in ("import_module", "__import__") and isinstance(first, ast.Constant) and (
                isinstance(first.value, str)
            ):
                found.append((node.lineno, first.value))
    return found


def _banned(name: str, banned: tuple[str, ...]) -> bool:
    return any(name == b or name.startswith(b + ".") for b in banned)


@pytest.mark.parametrize("folder", sorted(RULES))
def test_no_forbidden_imports(folder):
    banned = RULES[folder]
    files = sorted((ROOT / folder).rglob("*.py"))
    assert files, f"no Python files under {folder}"
    offences = []
    for path in files:
        current, is_pkg = module_name(path)
        for line, name in imported_names(path.read_text(), current, is_pkg):
            if _banned(name, banned):
                offences.append(f"{path.relative_to(ROOT)}:{line}: imports {name}")
    assert not offences, "\n".join(offences)


#: module -> modules it must not import, even lazily: running a command (external), containing
#: it (sandbox) and reading its answer (predictions) form a tree under the in-process adapters
#: (pipelines), not a circle
WITHIN_EVAL = {
    "arenabench.eval.runs.command": ("arenabench.eval.pipelines",),
    "arenabench.eval.pipelines": ("arenabench.eval.runs.command",
                                  "arenabench.eval.runs.sandbox"),
    "arenabench.eval.runs.predictions": ("arenabench.eval.pipelines",
                                         "arenabench.eval.runs.command",
                                         "arenabench.eval.runs.sandbox"),
    "arenabench.eval.runs.sandbox": ("arenabench.eval.pipelines", "arenabench.eval.runs.command",
                                     "arenabench.eval.runs.predictions"),
}


@pytest.mark.parametrize("module", sorted(WITHIN_EVAL))
def test_external_and_pipelines_do_not_import_each_other(module):
    path = ROOT / "eval" / (module.removeprefix("arenabench.eval.").replace(".", "/") + ".py")
    assert module_name(path) == (module, False)
    offences = [f"{path.relative_to(ROOT)}:{line}: imports {name}"
                for line, name in imported_names(path.read_text(), module)
                if _banned(name, WITHIN_EVAL[module])]
    assert not offences, "\n".join(offences)


@pytest.mark.parametrize(
    "source, current, is_pkg, expected",
    [
        ("from ..eval import metrics", "arenabench.generator.make", False,
         {"arenabench.eval", "arenabench.eval.metrics"}),
        ("from . import eval", "arenabench", True, {"arenabench", "arenabench.eval"}),
        ("from .records import X", "arenabench.eval.sweep.task", False,
         {"arenabench.eval.sweep.records", "arenabench.eval.sweep.records.X"}),
        ("def f():\n    import arenabench.eval.scoring.metrics", "arenabench.detect", False,
         {"arenabench.eval.scoring.metrics"}),
        ("import importlib\nimportlib.import_module('arenabench.generator.generate_cli')",
         "arenabench.x", False, {"importlib", "arenabench.generator.generate_cli"}),
        ("from arenabench import generator", "arenabench.x", False,
         {"arenabench", "arenabench.generator"}),
    ],
)
def test_the_checker_sees_relative_lazy_and_dynamic_imports(source, current, is_pkg, expected):
    assert {name for _, name in imported_names(source, current, is_pkg)} == expected


def test_module_names_follow_the_package_dir_mapping():
    assert module_name(ROOT / "eval/sweep/task.py") == ("arenabench.eval.sweep.task", False)
    assert module_name(ROOT / "generator/__init__.py") == ("arenabench.generator", True)
    assert module_name(ROOT / "src/arenabench/pipeline/detection.py") == (
        "arenabench.pipeline.detection", False)


def test_importing_the_pipeline_and_the_cli_loads_neither_generator_nor_renderer():
    code = (
        "import sys, arenabench.pipeline, arenabench.detect, arenabench.imageio, arenabench.cli;"
        "bad=[m for m in sys.modules if m.startswith(('arenabench.generator','arenabench.eval',"
        "'pyrender','OpenGL'))]; print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
