"""The three packages keep their roles: the pipeline never imports the generator or the harness,
and the generator never imports the harness. Checked on the source (every import statement)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

RULES = {
    # folder: import prefixes it must not use
    "src/arenabench": ("arenabench.generator", "arenabench.eval"),
    "generator": ("arenabench.eval",),
}


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
    return found


@pytest.mark.parametrize("folder", sorted(RULES))
def test_no_forbidden_imports(folder):
    banned = RULES[folder]
    files = sorted((ROOT / folder).rglob("*.py"))
    assert files, f"no Python files under {folder}"
    offences = [
        f"{path.relative_to(ROOT)}:{line}: imports {name}"
        for path in files
        for line, name in _imports(path)
        if name.startswith(banned)
    ]
    assert not offences, "\n".join(offences)


def test_importing_the_pipeline_loads_neither_generator_nor_renderer():
    import subprocess
    import sys

    code = (
        "import sys, arenabench.pipeline, arenabench.detect, arenabench.imageio;"
        "bad=[m for m in sys.modules if m.startswith(('arenabench.generator','arenabench.eval',"
        "'pyrender','OpenGL'))]; print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
