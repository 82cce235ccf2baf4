"""Command templates (``eval``/``sweep`` ``--cmd``, ``grade --cmd``, ``check --python``): the
placeholders each command accepts, declared once, and the one function that fills them.

A template is split into arguments without a shell (:func:`shlex.split`); in each argument
``{name}`` is a placeholder and ``{{`` / ``}}`` a literal brace (Python's format-string
syntax, read with :meth:`string.Formatter.parse`; a placeholder takes no format spec,
conversion, attribute or index). A placeholder the command does not accept, an empty one
(``{}``) or an unmatched brace is a usage error naming it (with "did you mean"):
:func:`template_problem`.

:func:`fill` fills one argument in a single pass: a value put in is never searched for
placeholders again, so a team folder named ``x{image}y`` stays that name. A value that goes
into a template filled later (``grade`` puts the team folder into the command, the image
is filled per run) is put in with :func:`escape`.
"""

from __future__ import annotations

import shlex
import string
from collections.abc import Collection, Mapping

#: Every placeholder, with what it becomes (docs/commands.md lists them).
PLACEHOLDERS: dict[str, str] = {
    "image": "the path of the image's private copy, in the run's own folder",
    "python": "the Python interpreter running arenabench",
    "competition_python": "the competition's Python environment (its numpy and OpenCV), made "
                          "once into arenabench's cache (arenabench.eval.runs.competition_env)",
    "submission": "the team folder's absolute path",
}
#: The competition environment's interpreter (filled before any run:
#: :func:`arenabench.eval.runs.competition_env.resolve_competition_python`).
COMPETITION_PYTHON = "competition_python"
#: The placeholders of ``eval --cmd``, ``sweep --cmd`` and ``check --python``.
RUN_PLACEHOLDERS: tuple[str, ...] = ("image", "python", COMPETITION_PYTHON)
#: The placeholders of ``grade --cmd``: not ``{python}``, see :data:`GRADE_REFUSED`.
GRADE_PLACEHOLDERS: tuple[str, ...] = ("image", "submission", COMPETITION_PYTHON)
#: Placeholders ``grade --cmd`` refuses, and why.
GRADE_REFUSED: dict[str, str] = {
    "python": "{python} is arenabench's own Python (its OpenCV and numpy, and arenabench "
              "importable by every team): name the interpreter the teams run with, e.g. "
              "python3 or /path/to/teams-venv/bin/python",
}
#: The placeholder every command template needs (or ``--image-name``).
IMAGE = "image"

_FORMATTER = string.Formatter()


class TemplateError(ValueError):
    """A template argument that is not a valid template; the message is one line."""


def _parts(arg: str) -> list[tuple[str, str | None]]:
    """``(literal text, placeholder name or None)`` pairs of one argument.

    Raises
    ------
    TemplateError
        An unmatched brace, or a placeholder with a format spec or conversion.
    """
    try:
        parsed = list(_FORMATTER.parse(arg))
    except ValueError as exc:
        raise TemplateError(f"{arg!r}: {exc} (write {{{{ and }}}} for a literal brace)") from None
    out: list[tuple[str, str | None]] = []
    for literal, name, spec, conversion in parsed:
        if name is not None and (spec or conversion):
            shown = "{" + name + (f"!{conversion}" if conversion else "") + (
                f":{spec}" if spec else "") + "}"
            raise TemplateError(f"{arg!r}: placeholder {shown} takes no format spec or "
                                "conversion (write {{ and }} for a literal brace)")
        out.append((literal, name))
    return out


def placeholders(arg: str) -> list[str]:
    """The placeholder names of one template argument, in order (``TemplateError`` as
    :func:`fill`)."""
    return [name for _, name in _parts(arg) if name is not None]


def fill(arg: str, values: Mapping[str, str], *, partial: bool = False) -> str:
    """One template argument with each placeholder replaced by its value and ``{{`` / ``}}``
    by a brace, in one pass (a value is never searched for placeholders).

    Parameters
    ----------
    arg : str
        One argument of a template.
    values : mapping
        Placeholder name -> its value.
    partial : bool, keyword-only
        Fill only the placeholders of ``values`` and give a template back: the other
        placeholders stay, the values and the literal text are :func:`escape` d (``grade``
        fills ``{submission}`` per team, the image later).

    Raises
    ------
    TemplateError
        For a placeholder without a value (unless ``partial``), or an argument that is not
        a valid template.
    """
    out = []
    for literal, name in _parts(arg):
        out.append(escape(literal) if partial else literal)
        if name is None:
            continue
        if name in values:
            out.append(escape(values[name]) if partial else values[name])
        elif partial:
            out.append("{" + name + "}")
        else:
            raise TemplateError(f"{arg!r}: unknown placeholder {{{name}}}")
    return "".join(out)


def replace_placeholder(arg: str, name: str, text: str) -> str:
    """One template argument with placeholder ``name`` replaced by ``text``, itself template
    text (:func:`escape` a path first; ``"{python}"`` puts another placeholder there); the
    other placeholders and the escaped braces stay as they are (``TemplateError`` as
    :func:`fill`)."""
    out = []
    for literal, found in _parts(arg):
        out.append(escape(literal))
        if found is not None:
            out.append(text if found == name else "{" + found + "}")
    return "".join(out)


def escape(text: str) -> str:
    """``text`` as literal template text: :func:`fill` gives it back unchanged."""
    return text.replace("{", "{{").replace("}", "}}")


def template_problem(template: str, accepted: Collection[str], *,
                     refused: Mapping[str, str] | None = None) -> str | None:
    """Why ``template`` is not a valid command template for a command accepting the
    placeholders ``accepted``, as one line (``None`` when it is valid). A template that
    cannot be split into arguments (unbalanced quotes) is left to the runner's own error.

    Parameters
    ----------
    template : str
        The command line.
    accepted : collection of str
        Placeholder names (without braces) the command accepts.
    refused : mapping, optional
        Placeholder name -> why the command refuses it (``grade``: :data:`GRADE_REFUSED`).
    """
    from arenabench.suggest import did_you_mean

    try:
        args = shlex.split(template)
    except ValueError:
        return None
    known = ", ".join("{" + a + "}" for a in accepted)
    for arg in args:
        try:
            names = placeholders(arg)
        except TemplateError as exc:
            return str(exc)
        for name in names:
            if name in accepted:
                continue
            if refused and name in refused:
                return refused[name]
            if name == "":
                return (f"{arg!r}: empty placeholder {{}} (placeholders: {known}; write {{{{ "
                        "and }} for a literal brace)")
            hint = did_you_mean("{" + name + "}", ["{" + a + "}" for a in accepted])
            return (f"unknown placeholder {{{name}}}{hint} in {arg!r} (placeholders: {known}; "
                    "write {{ and }} for a literal brace)")
    return None
