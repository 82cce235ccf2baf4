"""How the tests and the docs are kept, checked on their text: the tests mirror the packages,
no test reaches into a module's private state or edits ``sys.path``, and no code, test or
reference page names an issue number (the history lives in CHANGELOG.md and
docs/measurements.md)."""

import ast
import re
from pathlib import Path

import pytest
from paths import ROOT, TESTS

#: Test folders and the package each mirrors.
MIRRORS = {
    "core": "src/arenabench",
    "generator": "generator",
    **{f"generator/{room}": f"generator/{room}" for room in (
        "parameters", "model", "truth", "rendering", "dataset", "fitting", "commands")},
    "eval": "eval",
    **{f"eval/{room}": f"eval/{room}" for room in (
        "scoring", "runs", "datasets", "commands", "reports", "sweep", "grade", "bench")},
}
#: Tests of the repository as a whole, kept at the top of tests/.
TOP_LEVEL = {"test_import_graph.py", "test_lint.py", "test_clirun.py", "test_marks.py",
             "test_system_deps.py", "test_hygiene.py", "test_default_facts.py"}
ISSUE = re.compile(r"\b[Ii]ssues? #?\d+\b")


def _test_files() -> list[Path]:
    return sorted(p for p in TESTS.rglob("test_*.py") if "pipelines" not in p.parts)


def test_every_test_module_sits_in_the_folder_of_the_package_it_tests():
    misplaced = []
    for path in _test_files():
        folder = path.parent.relative_to(TESTS).as_posix()
        if folder == "." and path.name in TOP_LEVEL:
            continue
        if folder not in MIRRORS:
            misplaced.append(path.relative_to(TESTS).as_posix())
    assert misplaced == []


@pytest.mark.parametrize("folder", sorted(MIRRORS))
def test_each_test_folder_mirrors_a_package_that_exists(folder):
    assert (ROOT / MIRRORS[folder] / "__init__.py").is_file()
    assert list((TESTS / folder).glob("test_*.py")), f"tests/{folder} holds no tests"


def private_state_reads(source: str) -> list[str]:
    """``module._NAME`` reads and ``setattr(module, "_name", ...)`` patches in ``source``,
    where ``module`` is a name bound by an import (not ``self`` or a local object)."""
    tree = ast.parse(source)
    modules = {alias.asname or alias.name.split(".")[0]
               for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))
               for alias in node.names}
    found = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in modules and re.fullmatch(r"_[A-Z][A-Z0-9_]*", node.attr)):
            found.append(f"{node.value.id}.{node.attr}")
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "setattr" and len(node.args) >= 2
                and isinstance(node.args[0], ast.Name) and node.args[0].id in modules
                and isinstance(node.args[1], ast.Constant)
                and str(node.args[1].value).startswith("_")):
            found.append(f"setattr({node.args[0].id}, {node.args[1].value!r})")
    return found


def test_no_test_reads_or_patches_a_modules_private_state():
    found = {p.relative_to(TESTS).as_posix(): hits for p in _test_files()
             if (hits := private_state_reads(p.read_text()))}
    assert found == {}


def test_the_private_state_check_sees_a_read_and_a_patch():
    source = ("from arenabench.eval.runs import sandbox\n"
              "x = sandbox._CGROUP_PARENT\n"
              "monkeypatch.setattr(sandbox, '_warned_once', [])\n"
              "self._static = None\n")
    assert private_state_reads(source) == ["sandbox._CGROUP_PARENT",
                                           "setattr(sandbox, '_warned_once')"]


def test_no_test_or_script_edits_sys_path():
    edits = [p.relative_to(TESTS).as_posix() for p in TESTS.rglob("*.py")
             if re.search(r"sys\.path\.(insert|append)\(", p.read_text())
             and p.name != "test_hygiene.py"]
    assert edits == []


def test_no_issue_numbers_in_code_tests_or_reference_docs():
    places = [*ROOT.joinpath("src").rglob("*.py"), *ROOT.joinpath("generator").rglob("*.py"),
              *ROOT.joinpath("eval").rglob("*.py"), *TESTS.rglob("*.py"),
              ROOT / "README.md", ROOT / "CONTRIBUTING.md",
              *(p for p in ROOT.joinpath("docs").glob("*.md") if p.name != "measurements.md")]
    hits = [f"{p.relative_to(ROOT)}:{n}" for p in places if p.name != "test_hygiene.py"
            for n, line in enumerate(p.read_text(errors="replace").splitlines(), 1)
            if ISSUE.search(line)]
    assert hits == []
