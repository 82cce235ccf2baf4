"""The import rules (docs/architecture.md, "Import rules"), checked on the source of every
module with ``ast``: absolute and relative imports (resolved against the module's own
package), ``from pkg import submodule``, imports inside functions, and
``importlib.import_module("...")`` / ``__import__("...")`` with a literal name.

- The three packages keep their roles: the pipeline package never imports the generator or
  the harness, and the generator never imports the harness.
- No import cycle, lazy imports included: the graph of what each module imports at run time
  (imports under ``if TYPE_CHECKING:`` are for annotations only) has no strongly connected
  component of more than one module.
- Rooms in layers: inside the harness a module imports only from its own room and the rooms
  below it (:data:`LAYERS`), so scoring knows nothing of runs and a report writer nothing of
  grading.
- One door into running untrusted code: outside ``arenabench.eval.runs`` the harness imports
  its package (``from arenabench.eval.runs import CommandPipeline``), never its modules.

The one sanctioned way across is the command dispatcher, ``arenabench.cli``: it names every
sub-command's module as a string in its table and imports only the one that runs, so no
import statement of the core names the generator or the harness (checked here too, and at
run time below)."""

import ast
import functools
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


def _is_type_checking(node: ast.AST) -> bool:
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _nodes(tree: ast.AST, *, runtime: bool):
    """Every node of ``tree``; with ``runtime``, none under ``if TYPE_CHECKING:``."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if runtime and _is_type_checking(child):
                todo += child.orelse  # the else branch runs
                continue
            todo.append(child)


def imported_names(source: str, current: str, is_pkg: bool = False, *,
                   runtime: bool = False) -> list[tuple[int, str]]:
    """Every module name the source imports, as (line, absolute dotted name).

    ``from a.b import c`` yields both ``a.b`` and ``a.b.c`` (``c`` may be a submodule). With
    ``runtime``, imports under ``if TYPE_CHECKING:`` are left out.
    """
    found: list[tuple[int, str]] = []
    for node in _nodes(_tree(source), runtime=runtime):
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


@functools.cache
def _tree(source: str) -> ast.AST:
    """``source`` parsed, once per text (the tests read the trees, never change them)."""
    return ast.parse(source)


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


def _modules() -> dict[str, tuple[Path, bool]]:
    """Every module of the three packages: name -> (source file, is a package)."""
    found = {}
    for folder in PACKAGES:
        for path in sorted((ROOT / folder).rglob("*.py")):
            name, is_pkg = module_name(path)
            found[name] = (path, is_pkg)
    return found


def _runtime_targets(source: str, current: str, is_pkg: bool,
                     known: set[str], *, typed: bool = False) -> set[str]:
    """The project's modules that importing ``current`` runs (see :func:`import_graph`); with
    ``typed``, also those it imports for annotations only (under ``if TYPE_CHECKING:``)."""
    own = {".".join(current.split(".")[:k]) for k in range(1, current.count(".") + 1 + is_pkg)}
    targets: set[str] = set()

    def enclosing(name: str) -> None:  # the packages Python imports on the way to ``name``
        parts = name.split(".")
        targets.update(".".join(parts[:k]) for k in range(1, len(parts))
                       if ".".join(parts[:k]) not in own)

    for node in _nodes(_tree(source), runtime=not typed):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module, node.level, current, is_pkg)
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                if sub in known:  # a submodule
                    names.append(sub)
                else:  # a name the module ``base`` defines: it runs, own package or not
                    names.append(base)
                    targets.add(base)
        elif isinstance(node, ast.Call) and node.args:
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            first = node.args[0]
            if called in ("import_module", "__import__") and isinstance(first, ast.Constant):
                names = [str(first.value)]
        for name in names:
            enclosing(name)
            if name not in own:
                targets.add(name)
    return {t for t in targets if t in known and t != current}


def import_graph(modules: dict[str, tuple[str, bool]], *,
                 typed: bool = False) -> dict[str, set[str]]:
    """module -> the project's modules it imports at run time, from ``{name: (source,
    is_pkg)}``. Importing ``a.b.c`` runs ``a/__init__`` and ``a/b/__init__`` first: those
    packages are edges too, except a module's own enclosing packages, which Python is already
    importing when it gets there; a name imported from one of them (``from . import NAME``,
    not a submodule) is an edge, since it needs that package's ``__init__`` run first."""
    known = set(modules)
    return {name: _runtime_targets(source, name, is_pkg, known, typed=typed)
            for name, (source, is_pkg) in modules.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, targets = work[-1]
            for w in targets:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    component = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        component.append(w)
                        if w == v:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


@functools.cache
def _sources() -> dict[str, tuple[str, bool]]:
    """Every module's source and whether it is a package, read once per session."""
    return {name: (path.read_text(), is_pkg) for name, (path, is_pkg) in _modules().items()}


@functools.cache
def _project_graph() -> dict[str, set[str]]:
    """The project's import graph, built once per session (callers that change it copy it)."""
    return import_graph(_sources())


def test_no_module_imports_itself_round_a_cycle():
    found = cycles(_project_graph())
    graph = _project_graph()
    described = ["; ".join(f"{m} -> {sorted(graph[m] & set(c))}" for m in c) for c in found]
    assert not found, "import cycles:\n" + "\n".join(described)


def test_no_cycle_even_through_imports_for_annotations():
    """A module that needs another's type names what it uses (a protocol of its own), so the
    graph with ``if TYPE_CHECKING:`` imports counted has no cycle either."""
    graph = import_graph(_sources(), typed=True)
    found = cycles(graph)
    described = ["; ".join(f"{m} -> {sorted(graph[m] & set(c))}" for m in c) for c in found]
    assert not found, "import cycles through type-only imports:\n" + "\n".join(described)


def test_the_typed_graph_counts_imports_for_annotations():
    source = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .limits import X\n"
    known = {"arenabench.eval.runs.limits", "arenabench.eval.runs.cold"}
    name = "arenabench.eval.runs.cold"
    assert _runtime_targets(source, name, False, known) == set()
    assert _runtime_targets(source, name, False, known, typed=True) == {
        "arenabench.eval.runs.limits"}


@pytest.mark.parametrize("lazy", [False, True], ids=["top-level", "in-a-function"])
def test_the_cycle_check_catches_an_added_cycle(lazy):
    graph = dict(_project_graph())
    assert not cycles(graph)
    name = "arenabench.eval.scoring.metrics"
    source, is_pkg = _sources()[name]
    extra = "from arenabench.eval.evaluation import evaluate\n"
    if lazy:
        extra = "def _late():\n    " + extra
    # each module's edges come from its own source alone: rebuild the one changed
    graph[name] = _runtime_targets(source + "\n" + extra, name, is_pkg, set(graph))
    found = cycles(graph)
    assert any({"arenabench.eval.scoring.metrics", "arenabench.eval.evaluation"} <= set(c)
               for c in found), found


def test_type_checking_imports_are_not_run_time_edges():
    source = ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .a import A\n"
              "else:\n    from .b import B\n")
    names = {n for _, n in imported_names(source, "arenabench.eval.x", runtime=True)}
    assert "arenabench.eval.a" not in names and "arenabench.eval.b" in names
    assert "arenabench.eval.a" in {n for _, n in imported_names(source, "arenabench.eval.x")}


#: the package that runs untrusted code: its modules import each other; everything else goes
#: through its door (the names its ``__init__`` exports)
RUNS = "arenabench.eval.runs"


def test_running_untrusted_code_has_one_door():
    offences = []
    for name, (path, is_pkg) in _modules().items():
        if name == RUNS or name.startswith(RUNS + "."):
            continue
        for line, imported in imported_names(path.read_text(), name, is_pkg):
            if imported.startswith(RUNS + ".") and imported.removeprefix(RUNS + ".") in (
                    _runs_modules()):
                offences.append(f"{path.relative_to(ROOT)}:{line}: imports {imported}")
    assert not offences, "\n".join(offences)


def _runs_modules() -> set[str]:
    return {p.stem for p in (ROOT / "eval" / "runs").glob("*.py") if p.stem != "__init__"}


def test_the_door_exports_what_it_says():
    import importlib

    runs = importlib.import_module(RUNS)
    assert runs.__all__ and all(hasattr(runs, name) for name in runs.__all__)


@pytest.mark.parametrize(
    "source, current, is_pkg, expected",
    [
        ("from ...eval import metrics", "arenabench.generator.dataset.make", False,
         {"arenabench.eval", "arenabench.eval.metrics"}),
        ("from . import eval", "arenabench", True, {"arenabench", "arenabench.eval"}),
        ("from .records import X", "arenabench.eval.sweep.task", False,
         {"arenabench.eval.sweep.records", "arenabench.eval.sweep.records.X"}),
        ("def f():\n    import arenabench.eval.scoring.metrics", "arenabench.detect", False,
         {"arenabench.eval.scoring.metrics"}),
        ("import importlib\nimportlib.import_module('arenabench.generator.commands.generate')",
         "arenabench.x", False, {"importlib", "arenabench.generator.commands.generate"}),
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


#: The rooms of the generator and of the harness, lowest first: a module imports only from its
#: own room and the rooms below it (docs/architecture.md, "Import rules"). A top-level module of
#: ``eval/`` is a room of its own; the core is below everything, the generator below every room
#: of the harness; the generator's package (its lazy exports) sits with its commands, on top.
LAYERS = (
    ("arenabench",),
    ("arenabench.generator.assets",), ("arenabench.generator.parameters",),
    ("arenabench.generator.model",), ("arenabench.generator.truth",),
    ("arenabench.generator.rendering",), ("arenabench.generator.dataset",),
    ("arenabench.generator.fitting",),
    ("arenabench.generator.commands", "arenabench.generator"),
    ("arenabench.eval.scoring",), ("arenabench.eval.datasets",), ("arenabench.eval.pipelines",),
    ("arenabench.eval.runs",), ("arenabench.eval.evaluation", "arenabench.eval.phase_check"),
    ("arenabench.eval.reports",), ("arenabench.eval.sweep",), ("arenabench.eval.grade",),
    ("arenabench.eval.bench",),
    ("arenabench.eval.commands", "arenabench.eval.pytest_plugin", "arenabench.eval"),
)


def layer_of(module: str) -> int:
    """The index in :data:`LAYERS` of the room ``module`` belongs to (its longest prefix)."""
    best, found = -1, None
    for i, room in enumerate(LAYERS):
        for prefix in room:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, found = len(prefix), i
    if found is None:
        raise ValueError(f"{module} is in no room of LAYERS")
    return found


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every ``a -> b`` of ``graph`` where ``b``'s room is above ``a``'s."""
    return sorted(f"{a} -> {b}" for a, targets in graph.items() for b in targets
                  if layer_of(b) > layer_of(a))


def test_a_room_imports_only_the_rooms_below_it():
    assert upward_imports(_project_graph()) == []


def test_the_layer_check_catches_an_import_of_a_room_above():
    graph = {k: set(v) for k, v in _project_graph().items()}
    graph["arenabench.eval.scoring.metrics"].add("arenabench.eval.runs")
    assert upward_imports(graph) == ["arenabench.eval.scoring.metrics -> arenabench.eval.runs"]


def test_every_module_is_in_a_room():
    for module in _project_graph():
        layer_of(module)
