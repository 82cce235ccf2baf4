"""Which folders an interpreter needs, so that the one the organiser names runs in the sandbox.

A command's executable is often a link or a small launcher into a larger installation: a
virtual environment's ``bin/python`` links to its base Python and reads ``pyvenv.cfg``; a
conda environment holds its own libraries; a pyenv shim is a shell script that runs
``~/.pyenv/libexec/pyenv``; an entry-point script starts with ``#!/path/to/python``.
:func:`interpreter_folders` finds every folder such an executable needs, which the bubblewrap
sandbox binds read-only (:mod:`arenabench.eval.runs.sandbox`):

- **venv** (a ``pyvenv.cfg`` next to its ``bin/``): the environment's folder, its base
  installation (``home =`` in ``pyvenv.cfg``), and the folders its site-packages point to
  (plain ``.pth`` lines, editable installs' package folders);
- **conda** (``conda-meta/`` in the prefix): the environment's prefix;
- **pyenv** (a ``shims/`` folder): the pyenv root;
- **system** or anything else: the installation prefix of the executable and of the file its
  links resolve to (nothing under ``/usr``, which the sandbox always shows);
- a ``#!`` script: the above for its interpreter as well.

Nothing of the harness's own Python is added unless the command names it (``{python}``).
"""

from __future__ import annotations

import ast
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

#: Folders never bound as a whole (the sandbox builds them itself, or they hold everything).
TOP_FOLDERS: frozenset[str] = frozenset(
    {"/", "/proc", "/dev", "/sys", "/tmp", "/run", "/var", "/home", "/root", "/mnt", "/opt",
     "/usr", "/etc", "/srv", "/media"})
_BIN_NAMES = ("bin", "sbin", "Scripts", "shims")


@dataclass(frozen=True)
class InterpreterInfo:
    """What an executable needs in the sandbox.

    Parameters
    ----------
    executable : str
        The executable as named (absolute, links not resolved).
    kind : str
        ``"venv"``, ``"conda"``, ``"pyenv"`` or ``"system"`` (of the executable itself, or
        of its ``#!`` interpreter).
    folders : tuple of str
        Resolved folders to bind read-only, outermost first, none inside another.
    """

    executable: str
    kind: str
    folders: tuple[str, ...]


def _prefix(executable: Path) -> Path:
    folder = executable.parent
    return folder.parent if folder.name in _BIN_NAMES else folder


def _pyvenv_home(cfg: Path) -> Path | None:
    try:
        text = cfg.read_text(errors="replace")
    except OSError:
        return None
    m = re.search(r"^\s*home\s*=\s*(.+?)\s*$", text, re.M)
    return Path(m.group(1)) if m else None


def site_packages_sources(prefix: str | os.PathLike[str]) -> set[str]:
    """Folders outside ``prefix`` that its site-packages point to: plain path lines of
    ``.pth`` files and the package folders of editable installs (setuptools'
    ``__editable__`` finders)."""
    out: set[str] = set()
    for site in Path(prefix).glob("lib*/python*/site-packages"):
        for pth in site.glob("*.pth"):
            try:
                lines = pth.read_text(errors="replace").splitlines()
            except OSError:
                continue
            for line in lines:
                line = line.strip()
                if line and not line.startswith(("#", "import")) and os.path.isdir(line):
                    out.add(os.path.realpath(line))
        for finder in site.glob("__editable__*finder.py"):
            try:
                m = re.search(r"^MAPPING[^=]*=\s*(\{.*?\})\s*$", finder.read_text(), re.M)
                mapping = ast.literal_eval(m.group(1)) if m else {}
            except (OSError, ValueError, SyntaxError):
                continue
            out.update(os.path.realpath(v) for v in mapping.values() if os.path.isdir(v))
    return out


def _shebang(path: Path) -> str | None:
    try:
        with open(path, "rb") as fh:
            head = fh.read(256)
    except OSError:
        return None
    if not head.startswith(b"#!"):
        return None
    words = head[2:].split(b"\n", 1)[0].decode(errors="replace").split()
    if not words:
        return None
    if os.path.basename(words[0]) == "env" and len(words) > 1:
        return shutil.which(words[-1])
    return words[0]


def _collect(executable: Path, folders: set[str], seen: set[str]) -> str:
    """Add what ``executable`` needs to ``folders``; returns its kind."""
    key = str(executable)
    if key in seen:
        return "system"
    seen.add(key)
    prefix = _prefix(executable)
    kind = "system"
    if (prefix / "pyvenv.cfg").is_file():
        kind = "venv"
        folders.add(str(prefix))
        home = _pyvenv_home(prefix / "pyvenv.cfg")
        if home is not None:
            base = home.parent if home.name in _BIN_NAMES else home
            folders.add(str(base))
            folders.update(site_packages_sources(base))
    elif (prefix / "conda-meta").is_dir():
        kind = "conda"
        folders.add(str(prefix))
    elif executable.parent.name == "shims":
        kind = "pyenv"
        folders.add(str(prefix))
    elif str(prefix) in TOP_FOLDERS:  # /opt/python3: the folder (or file) itself only
        parent = str(executable.parent)
        folders.add(parent if parent not in TOP_FOLDERS else str(executable))
    else:
        folders.add(str(prefix))
    folders.update(site_packages_sources(prefix))
    real = Path(os.path.realpath(executable))
    if real != executable:
        _collect(real, folders, seen)
    interp = _shebang(real)
    if interp:
        inner = _collect(Path(os.path.abspath(interp)), folders, seen)
        kind = inner if kind == "system" else kind
    return kind


def _within(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip("/") + "/")


def outermost(paths: set[str] | list[str]) -> list[str]:
    """Resolved ``paths`` without :data:`TOP_FOLDERS`, anything under ``/usr`` and any folder
    inside another, outermost first."""
    out: list[str] = []
    for p in sorted({os.path.realpath(p) for p in paths}, key=len):
        if p in TOP_FOLDERS or _within(p, "/usr"):
            continue
        if not any(_within(p, q) for q in out):
            out.append(p)
    return out


def interpreter_folders(executable: str | os.PathLike[str]) -> InterpreterInfo:
    """The folders ``executable`` needs to run (see the module docstring).

    Parameters
    ----------
    executable : path-like
        An absolute path, as named (a venv's ``bin/python`` is a link: not resolved first).
    """
    exe = Path(os.path.abspath(executable))
    folders: set[str] = set()
    kind = _collect(exe, folders, set())
    return InterpreterInfo(executable=str(exe), kind=kind, folders=tuple(outermost(folders)))
