"""A fast yes/no check of a parsed JSON document against a JSON Schema, for reading big sets.

:mod:`jsonschema` takes about 10 ms for one ground-truth file (it builds a validator object
per keyword and node); 100,000 files would take minutes before the first image runs. The
check here compiles the schema once into nested Python functions that answer only *whether*
a document is valid, and also whether every number in it is finite (the rule
:func:`arenabench.schemas.gt_problem` adds), in well under a millisecond. Where it says no,
the caller asks :mod:`jsonschema` for the one-line message, so messages are unchanged.

Only the keywords the shipped schemas use are compiled (:data:`KEYWORDS`, with local
``$ref`` already inlined); :func:`compile_check` returns ``None`` for a schema with any other
keyword, and the caller then validates with :mod:`jsonschema` alone.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from typing import Any

#: Keywords :func:`compile_check` understands (the others are annotations it ignores).
KEYWORDS = frozenset({"type", "const", "enum", "required", "properties",
                      "additionalProperties", "items", "minItems", "maxItems",
                      "minimum", "maximum"})
ANNOTATIONS = frozenset({"title", "description", "$schema", "$id", "$comment"})

Check = Callable[[Any], bool]


def all_finite(obj: Any) -> bool:
    """Whether every float in nested lists and dicts is finite."""
    if isinstance(obj, float):
        return math.isfinite(obj)
    if isinstance(obj, dict):
        obj = obj.values()
    elif not isinstance(obj, list):
        return True
    for v in obj:
        if type(v) is float:
            if not math.isfinite(v):
                return False
        elif isinstance(v, (dict, list)) and not all_finite(v):
            return False
    return True


def _is_type(x: Any, name: str) -> bool:
    """JSON Schema's type test (as :mod:`jsonschema`: booleans are not numbers, a float
    with an integral value is an integer)."""
    if name == "object":
        return isinstance(x, dict)
    if name == "array":
        return isinstance(x, list)
    if name == "string":
        return isinstance(x, str)
    if name == "boolean":
        return isinstance(x, bool)
    if name == "null":
        return x is None
    if isinstance(x, bool):
        return False
    if name == "number":
        return isinstance(x, (int, float))
    if name == "integer":
        return isinstance(x, int) or (isinstance(x, float) and x.is_integer())
    raise KeyError(name)


_PY_TYPES = {"object": (dict,), "array": (list,), "string": (str,), "boolean": (bool,),
             "null": (type(None),), "number": (int, float)}


def _type_test(names: tuple[str, ...]) -> Check:
    """The type test of ``names``, specialised (the common single types as one ``type()``)."""
    if "integer" not in names:  # bool is a type of its own: not a number here
        types = frozenset(t for n in names for t in _PY_TYPES[n])
        return lambda x: type(x) in types
    if names == ("integer",):
        return lambda x: type(x) is int or (type(x) is float and x.is_integer())
    return lambda x: any(_is_type(x, n) for n in names)


def _json_equal(a: Any, b: Any) -> bool:
    """Equality as JSON Schema defines it (``true`` is not ``1``)."""
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_json_equal(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_json_equal(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b

def compile_check(schema: Any) -> Check | None:
    """A function ``doc -> bool``: whether ``doc`` is valid against ``schema`` (local
    references inlined) and holds only finite numbers; ``None`` when the schema uses a
    keyword outside :data:`KEYWORDS`."""
    try:
        return _compile(schema)
    except _Unsupported:
        return None


class _Unsupported(Exception):
    pass


def _number_leaf(node: Any) -> Check | None:
    """One function for the commonest node, a number or integer with optional bounds."""
    if not isinstance(node, dict) or node.get("type") not in ("number", "integer") or (
            set(node) - ANNOTATIONS - {"type", "minimum", "maximum"}):
        return None
    lo, hi = node.get("minimum", -math.inf), node.get("maximum", math.inf)
    integer = node["type"] == "integer"
    isfinite = math.isfinite

    def check(x: Any) -> bool:
        t = type(x)
        if t is float:
            return isfinite(x) and lo <= x <= hi and (not integer or x.is_integer())
        return t is int and lo <= x <= hi

    return check


def _number_array(node: Any) -> Check | None:
    """One function for an array of bounded numbers with optional length limits."""
    if not isinstance(node, dict) or node.get("type") != "array" or (
            set(node) - ANNOTATIONS - {"type", "items", "minItems", "maxItems"}):
        return None
    leaf = _number_leaf(node.get("items"))
    if leaf is None:
        return None
    lo, hi = node.get("minItems", 0), node.get("maxItems", math.inf)

    def check(x: Any) -> bool:
        return type(x) is list and lo <= len(x) <= hi and all(map(leaf, x))

    return check


def _compile(node: Any) -> Check:
    special = _number_leaf(node) or _number_array(node)
    if special is not None:
        return special
    if node is True or node == {}:
        return all_finite
    if node is False:
        return lambda x: False
    if not isinstance(node, dict):
        raise _Unsupported(node)
    unknown = set(node) - KEYWORDS - ANNOTATIONS
    if unknown:
        raise _Unsupported(sorted(unknown))
    return _all_of(_value_tests(node) + _member_tests(node))


def _value_tests(node: dict) -> list[Check]:
    """The tests of the value itself: type, const, enum, bounds, lengths, required keys."""
    tests: list[Check] = []
    if "type" in node:
        names = node["type"] if isinstance(node["type"], list) else [node["type"]]
        for name in names:
            _is_type(None, name)  # an unknown type name: KeyError, not supported
        tests.append(_type_test(tuple(names)))
    if "const" in node:
        tests.append(lambda x, c=node["const"]: _json_equal(x, c))
    if "enum" in node:
        tests.append(lambda x, e=tuple(node["enum"]): any(_json_equal(x, v) for v in e))
    for key, op in (("minimum", operator.ge), ("maximum", operator.le)):
        if key in node:
            tests.append(lambda x, b=node[key], op=op: not _is_type(x, "number") or op(x, b))
    if "minItems" in node:
        tests.append(lambda x, n=node["minItems"]: not isinstance(x, list) or len(x) >= n)
    if "maxItems" in node:
        tests.append(lambda x, n=node["maxItems"]: not isinstance(x, list) or len(x) <= n)
    if "required" in node:
        tests.append(lambda x, r=tuple(node["required"]):
                     not isinstance(x, dict) or all(k in x for k in r))
    return tests


def _member_tests(node: dict) -> list[Check]:
    """The tests of what the value holds (an object's members, an array's items) and that a
    number is finite, for the types the node allows."""
    tests: list[Check] = []
    names = node.get("type")
    kinds = set(names if isinstance(names, list) else [names]) if names else None
    if kinds is None or "object" in kinds:
        props = {k: _compile(v) for k, v in node.get("properties", {}).items()}
        extra = (_compile(node["additionalProperties"]) if "additionalProperties" in node
                 else all_finite)

        def members(x: Any) -> bool:
            if type(x) is not dict:
                return True
            get = props.get
            for key, value in x.items():
                if not get(key, extra)(value):
                    return False
            return True

        tests.append(members)
    if kinds is None or "array" in kinds:
        item = _compile(node["items"]) if "items" in node else all_finite
        tests.append(lambda x: type(x) is not list or all(map(item, x)))
    if kinds is None or kinds & {"number", "integer"}:
        tests.append(lambda x: type(x) is not float or math.isfinite(x))
    return tests


def _all_of(tests: list[Check]) -> Check:
    """One check that passes when every test does (the first failing one ends it)."""
    if len(tests) == 1:
        return tests[0]
    if len(tests) == 2:
        first, second = tests
        return lambda x: first(x) and second(x)

    def check(x: Any) -> bool:
        for t in tests:
            if not t(x):
                return False
        return True

    return check
