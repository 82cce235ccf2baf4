"""JSON Schemas of the files arenabench writes, shipped as package data.

``gt.schema.json`` describes one ground-truth file (schema ``arenabench.gt/1``); its maxima
are limits of :mod:`arenabench.limits` (``tests/core/test_gt_quickcheck.py`` checks that they
agree). JSON Schema accepts NaN and infinities as ``number`` and ``3.0`` as ``integer``;
:func:`gt_problem` also refuses any non-finite number, wherever it is, a count or marker id
written with a fraction or exponent, and a marker id listed twice.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from functools import cache
from importlib import resources
from typing import Any

#: Value of the ``schema`` field of every ground-truth file.
GT_SCHEMA = "arenabench.gt/1"
#: File name of the ground-truth schema in this package.
GT_SCHEMA_FILE = "gt.schema.json"


@cache
def gt_schema() -> dict[str, Any]:
    """The ground-truth JSON Schema (parsed once)."""
    text = resources.files(__package__).joinpath(GT_SCHEMA_FILE).read_text(encoding="utf-8")
    return json.loads(text)


def _inline_refs(node: Any, defs: dict[str, Any]) -> Any:
    """``node`` with every local ``{"$ref": "#/$defs/NAME"}`` replaced by its definition
    (the schema has no recursive definitions); resolving references is a large part of
    jsonschema's time per record."""
    if isinstance(node, dict):
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.startswith("#/$defs/") and len(node) == 1:
            return _inline_refs(defs[ref.removeprefix("#/$defs/")], defs)
        return {k: _inline_refs(v, defs) for k, v in node.items() if k != "$defs"}
    if isinstance(node, list):
        return [_inline_refs(v, defs) for v in node]
    return node


@cache
def _gt_validator() -> Any:
    import jsonschema

    schema = gt_schema()
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(_inline_refs(schema, schema.get("$defs", {})))


@cache
def _quick_gt_check() -> Any:
    from .quickcheck import compile_check

    schema = gt_schema()
    return compile_check(_inline_refs(schema, schema.get("$defs", {})))


def dotted(path: Any) -> str:
    """``area.visible_px`` / ``markers[2].id`` from a sequence of keys and indices."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _non_finite(obj: Any, path: tuple = ()) -> Iterator[tuple[tuple, float]]:
    if isinstance(obj, float):
        if not math.isfinite(obj):
            yield path, obj
    elif isinstance(obj, dict):
        for key, value in obj.items():
            yield from _non_finite(value, (*path, key))
    elif isinstance(obj, list):
        for i, value in enumerate(obj):
            yield from _non_finite(value, (*path, i))


def _one_line(text: str, limit: int = 200) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


#: Integer fields that must be written as JSON integers (``3``, not ``3.0`` or ``3e0``, which
#: JSON Schema's ``integer`` accepts): a fraction or an exponent is not what the generator
#: writes, so it is a hand-edited or damaged file.
_WRITTEN_AS_INTEGERS = ("count", "components")


def _rules_problem(gt: dict[str, Any]) -> str | None:
    """The rules JSON Schema cannot state, on a record the schema accepts: the integer
    fields written as integers, and each marker id once."""
    for key in _WRITTEN_AS_INTEGERS:
        if type(gt.get(key)) is float:
            return f"{key}: {gt[key]!r} is not an integer (written with a fraction or exponent)"
    seen: dict[int, int] = {}
    for i, marker in enumerate(gt.get("markers") or ()):
        mid = marker["id"]
        if type(mid) is float:
            return (f"markers[{i}].id: {mid!r} is not an integer (written with a fraction or "
                    "exponent)")
        if mid in seen:
            return f"markers[{i}].id: {mid} repeats markers[{seen[mid]}].id (each marker once)"
        seen[mid] = i
    return None


def gt_problem(gt: Any) -> str | None:
    """The first problem of a parsed ground-truth record, or ``None`` when it is valid.

    Valid: the schema holds (:func:`gt_schema`: types, bounds), every number is finite, the
    integer fields are written as integers and no marker id repeats.

    Parameters
    ----------
    gt : Any
        The parsed JSON (``json.loads`` turns ``NaN``, ``Infinity`` and ``1e400`` into
        non-finite floats).

    Returns
    -------
    str or None
        One line such as ``area.visible_px: nan is not a finite number`` or
        ``count: -1 is less than the minimum of 0``.
    """
    quick = _quick_gt_check()  # valid files are answered without jsonschema (quickcheck.py)
    try:
        if quick is not None and quick(gt):
            return _rules_problem(gt)
    except RecursionError:
        return "nested too deeply"
    import jsonschema

    try:
        for path, value in _non_finite(gt):
            where = dotted(path) or "(root)"
            return f"{where}: {value!r} is not a finite number"
        error = jsonschema.exceptions.best_match(_gt_validator().iter_errors(gt))
    except RecursionError:
        return "nested too deeply"
    if error is None:
        return _rules_problem(gt)
    where = dotted(error.absolute_path)
    return _one_line(f"{where}: {error.message}" if where else error.message)
