"""Typed records to and from their JSON form, field by field: the one mechanism for a record
whose JSON keys are its fields.

:func:`to_plain` gives a dataclass's fields in declaration order (a nested record as its own
plain form, tuples as lists, dicts copied); :func:`from_plain` reads such a mapping back,
converting each value to its field's annotated type (``int``, ``float``, ``bool``, ``str``,
``tuple[...]`` from a list, ``dict[str, X]``, a nested record, ``X | None``), a missing key
taking the field's default. A record whose JSON form is not its fields (renamed, nested or
left-out keys: ``report.json``'s images, the detection result) keeps its own ``to_dict``.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Mapping
from typing import Any, TypeVar

T = TypeVar("T")


def to_plain(record: Any) -> dict[str, Any]:
    """``record``'s fields in declaration order, as JSON values.

    Raises
    ------
    TypeError
        When ``record`` is not a dataclass instance.
    """
    if not dataclasses.is_dataclass(record) or isinstance(record, type):
        raise TypeError(f"record must be a dataclass instance, got {type(record).__name__}")
    return {f.name: _plain(getattr(record, f.name)) for f in dataclasses.fields(record)}


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_plain(value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def from_plain(cls: type[T], data: Mapping[str, Any], **given: Any) -> T:
    """The record of class ``cls`` that ``data`` (a :func:`to_plain` form) describes.

    Parameters
    ----------
    cls : type
        A dataclass.
    data : mapping
        Its fields by name; a field missing here takes its default (or a value in ``given``).
    **given
        Values taken as they are, over ``data`` (a field an older form lacked, computed).

    Raises
    ------
    ValueError
        When a field without a default is missing, or a value cannot be converted.
    """
    hints = _hints(cls)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        if f.name in given:
            values[f.name] = given[f.name]
        elif f.name in data:
            try:
                values[f.name] = _typed(hints[f.name], data[f.name])
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{cls.__name__}.{f.name}: {exc}") from None
        elif (f.default is dataclasses.MISSING
              and f.default_factory is dataclasses.MISSING):
            raise ValueError(f"{cls.__name__}: field {f.name!r} missing")
    return cls(**values)


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _typed(hint: Any, value: Any) -> Any:
    """``value`` converted to type ``hint``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _typed(inner[0], value) if len(inner) == 1 else value
    if hint in (int, float, str, bool):
        if isinstance(value, bool) and hint is not bool:
            raise TypeError(f"a boolean where {hint.__name__} belongs")
        return hint(value)
    if dataclasses.is_dataclass(hint):
        return from_plain(hint, value)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_typed(args[0], v) for v in value)
        return tuple(_typed(a, v) for a, v in zip(args, value, strict=True)) if args else (
            tuple(value))
    if origin is list:
        return [_typed(args[0], v) for v in value] if args else list(value)
    if origin is dict:
        return {k: _typed(args[1], v) for k, v in value.items()} if args else dict(value)
    return value
