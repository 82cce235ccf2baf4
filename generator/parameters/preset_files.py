"""Preset files: a scene preset kept in a TOML (or JSON) file, read, validated and written.

A preset file holds the parameters of ``arenabench presets --params`` (the dotted names of
:data:`arenabench.generator.parameters.params.PARAMS`), each a value in the forms ``--set`` takes
(a value,
a range ``"lo:hi"`` or ``[lo, hi]``, a list for colours and ids), plus what the preset is and
where its values came from. The format is documented in docs/formats.md ("Preset files")::

    schema = "arenabench.preset/1"

    [preset]
    name = "my-arena"                      # what GT files and dataset.json record
    description = "our lab's arena, seen by the ceiling camera"
    evidence = "fitted by `arenabench twin` on lab.jpg"   # free text, or a table

    [camera]
    fov_deg = 68.75
    tilt_deg = "0:2"                       # a range: "lo:hi" or [0.0, 2.0]

    [open."lighting.azimuth_deg"]          # not pinned by the evidence: the range it allows
    range = [0.0, 360.0]
    reason = "east and west faces not visible"

    [open."camera.fov_deg"]                # open, but the evidence pins a trade: at the
    range = [68.3, 70.6]                   # range's ends, other parameters take these values
    moves_with = {"camera.altitude_m" = [3.19, 3.06]}
    reason = "the markers fit as well over this span of fields of view"

Public API (everything a command or another module needs; the rest is private):

- :func:`load_preset_file` (path -> :class:`ResolvedPreset`): read and validate a file; every
  problem is a :class:`PresetFileError` (a ``ValueError``) of one line naming the file, the
  key and the value.
- :func:`preset_hash`: 10 hex digits naming a preset's parameters.
- :func:`write_preset_file`, :func:`preset_to_toml`, :func:`preset_to_json`,
  :func:`preset_document`: write a preset (every parameter after the defaults, with the
  ``[preset]`` and ``[open]`` tables) that :func:`load_preset_file` reads back to the same
  :class:`ResolvedPreset`, so generating from the file gives the same bytes as from the
  preset it was written from.
- :class:`ResolvedPreset`, :class:`OpenParam`: a preset after validation and defaults.

The ``--preset NAME|FILE`` rule and the built-in presets are
:func:`arenabench.generator.parameters.presets.resolve_preset` and
:func:`~arenabench.generator.parameters.presets.builtin_preset`.
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from arenabench.fileio import atomic_write_text, dumps_json, read_regular, sha256_bytes
from arenabench.generator.assets import texture_store
from arenabench.generator.parameters.param_values import (
    ALIASES,
    canonical_key,
    format_value,
    resolve_params,
    validate_value,
)
from arenabench.generator.parameters.params import PARAMETERS, PARAMS, Range, Value
from arenabench.limits import MAX_PRESET_FILE_BYTES, cut
from arenabench.suggest import did_you_mean

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: The ``schema`` key of every preset file this version reads and writes.
PRESET_SCHEMA = "arenabench.preset/1"
#: Keys of the ``[preset]`` table.
PRESET_KEYS = ("name", "description", "evidence")
#: Keys of an ``[open]`` entry: the range (numbers) or the values it allows, what moves with
#: it, and why.
OPEN_KEYS = ("range", "values", "moves_with", "reason")
#: Top-level keys that are not parameter sections.
RESERVED_KEYS = ("schema", "preset", "open")
#: A preset name: what GT files, dataset.json and cache folder names record.
NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
#: The sections parameters live in (``camera`` of ``camera.tilt_deg``), aliases' included.
SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(
    name.split(".", 1)[0] for name in (*PARAMETERS, *ALIASES)))


class PresetFileError(ValueError):
    """A preset file that cannot be used: the message is one line naming the file, the key
    and the value."""


@dataclass(frozen=True)
class OpenParam:
    """A parameter the evidence does not pin: the values it still allows, and why.

    Attributes
    ----------
    name : str
        The parameter (canonical name).
    reason : str
        Why the evidence leaves it open ("east and west faces not visible").
    range : Range or None
        The range it allows (numeric parameters).
    values : tuple or None
        The values it allows (any parameter), when not a range.
    moves_with : tuple of (str, tuple of float)
        Parameters the evidence ties to this one: their values when this one is at
        ``range.lo`` and at ``range.hi`` (a range), or at each of ``values`` in turn. The image
        pins the trade, not either parameter: a field of view and the altitude that keeps the
        floor's image, or a light's azimuth and the elevation, intensity and ambient that keep
        the faces seen. A variant sets them too, and they are never varied on their own.
    """

    name: str
    reason: str
    range: Range | None = None
    values: tuple[Value, ...] | None = None
    moves_with: tuple[tuple[str, tuple[float, ...]], ...] = ()

    def __post_init__(self) -> None:
        if (self.range is None) == (self.values is None):
            raise ValueError(f"open {self.name}: give a range or values, not both or neither")
        for name, at in self.moves_with:
            if len(at) != len(self._points()):
                raise ValueError(f"open {self.name}: moves_with {name} needs one value per "
                                 f"{'end of the range' if self.range else 'value'}")

    def _points(self) -> tuple[Value, ...]:
        """What :attr:`moves_with` lists values for: the range's ends, or the values."""
        return (self.range.lo, self.range.hi) if self.range is not None else tuple(
            self.values or ())

    def at(self, value: Value) -> dict[str, float]:
        """The values of :attr:`moves_with` when this parameter is at ``value`` (an end of the
        range, or one of the values; ``{}`` when nothing moves with it)."""
        if not self.moves_with:
            return {}
        points = self._points()
        if value not in points:
            raise ValueError(f"open {self.name}: {value!r} is not "
                             + ("an end of its range" if self.range is not None else
                                "one of its values") + f" {list(points)}")
        k = points.index(value)
        return {name: at[k] for name, at in self.moves_with}

    def allows(self, value: Value) -> bool:
        """Whether the preset's ``value`` (a fixed value or a :class:`Range`) lies inside."""
        if self.range is not None:
            lo, hi = (value.lo, value.hi) if isinstance(value, Range) else (value, value)
            return self.range.lo <= lo and hi <= self.range.hi
        return not isinstance(value, Range) and value in self.values  # type: ignore[operator]

    def to_dict(self) -> dict[str, Any]:
        """The entry as a preset file holds it."""
        out: dict[str, Any] = {}
        if self.range is not None:
            out["range"] = _file_value(self.range)
        else:
            out["values"] = [_file_value(v) for v in self.values or ()]
        if self.moves_with:
            out["moves_with"] = {name: list(ends) for name, ends in self.moves_with}
        out["reason"] = self.reason
        return out


@dataclass(frozen=True)
class ResolvedPreset:
    """A preset after validation and defaults: what generating from it needs.

    Attributes
    ----------
    name : str
        What GT files and ``dataset.json`` record as the preset.
    params : dict
        Every parameter of :data:`~arenabench.generator.parameters.params.PARAMS`, validated
        (:func:`arenabench.generator.parameters.presets.resolve`): a fixed value or a
        :class:`Range`.
    description : str
        One line saying what the preset is.
    evidence : str or dict
        Where its values came from: free text, or a table of texts (or numbers, lists and
        tables of them).
    open : dict
        Parameter name -> :class:`OpenParam`: what the evidence leaves open.
    source : Path or None
        The file it was read from (``None``: a built-in preset given in code).
    """

    name: str
    params: dict[str, Value]
    description: str = ""
    evidence: str | dict[str, Any] = ""
    open: dict[str, OpenParam] = field(default_factory=dict)
    source: Path | None = None

    @property
    def poor_fit(self) -> str | None:
        """A twin's preset whose fit is poor: the line that says so, its verdict cut to one
        line (``arenabench twin`` records ``verdict`` in the evidence); else ``None``."""
        verdict = self.evidence.get("verdict") if isinstance(self.evidence, dict) else None
        if not isinstance(verdict, str) or not verdict.startswith("poor"):
            return None
        return (f"warning: preset {self.name} is a twin whose fit is poor "
                f"({cut(verdict)}): its scenes are a guess at that arena, not a twin "
                "to be held to")

    def document(self) -> dict[str, Any]:
        """The preset file's content (:func:`preset_document`)."""
        return preset_document(self.params, name=self.name, description=self.description,
                               evidence=self.evidence, open=self.open)


# ------------------------------------------------------------------------------- reading


def load_preset_file(path: str | os.PathLike[str]) -> ResolvedPreset:
    """Read and validate a preset file (TOML; JSON when it ends in ``.json`` or starts with
    ``{``).

    Parameters
    ----------
    path : path-like
        The file. A ``dataset.json`` (schema ``arenabench.dataset/1``) gives the preset its
        set was generated from (``preset_definition``).

    Returns
    -------
    ResolvedPreset
        Every parameter after the defaults; ``source`` is ``path``.

    Raises
    ------
    PresetFileError
        One line naming the file and what is wrong with it: not a regular file, unreadable,
        not TOML or JSON, too large, or a key, value, type, range or ``[open]`` entry that is
        not valid (the key and the value named).
    """
    p = Path(path)
    where = str(p)
    try:
        data = read_regular(p, limit=MAX_PRESET_FILE_BYTES)
    except OSError as exc:
        raise PresetFileError(f"preset file {where}: cannot read it: "
                              f"{exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise PresetFileError(f"preset file {where}: not UTF-8 text") from None
    doc = _parse(text, where, as_json=p.suffix.lower() == ".json"
                 or (p.suffix.lower() != ".toml" and text.lstrip().startswith("{")))
    if doc.get("schema") == _DATASET_SCHEMA:  # a set's dataset.json: the preset it records
        inner = doc.get("preset_definition")
        if not isinstance(inner, dict):
            raise PresetFileError(
                f"preset file {where}: this dataset.json records no preset_definition (made "
                "by an older arenabench): give the preset by name or by its file")
        doc = inner
    return preset_from_document(doc, where=where, base=p.parent, source=p)


#: dataset.json's schema (a set's dataset.json can stand for the preset it was made from).
_DATASET_SCHEMA = "arenabench.dataset/1"


def _parse(text: str, where: str, *, as_json: bool) -> dict[str, Any]:
    kind = "JSON" if as_json else "TOML"
    try:
        doc = (json.loads(text, parse_constant=_no_constant) if as_json
               else tomllib.loads(text))
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, TOMLDecodeError
        why = "nested too deeply" if isinstance(exc, RecursionError) else exc
        raise PresetFileError(f"preset file {where}: not valid {kind}: "
                              f"{' '.join(str(why).split())}") from None
    if not isinstance(doc, dict):
        raise PresetFileError(f"preset file {where}: must hold a {kind} "
                              f"{'object' if as_json else 'table'}, got {type(doc).__name__}")
    return doc


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number a preset file may hold")


def preset_from_document(doc: Mapping[str, Any], *, where: str, base: Path | None = None,
                         source: Path | None = None) -> ResolvedPreset:
    """Validate a preset file's parsed content (see :func:`load_preset_file`).

    Parameters
    ----------
    doc : mapping
        The parsed TOML or JSON.
    where : str, keyword-only
        How messages name the file.
    base : Path, keyword-only
        Folder that relative paths in the file (a texture image) are relative to; default:
        the working directory.
    source : Path, keyword-only
        Recorded as :attr:`ResolvedPreset.source`.

    Raises
    ------
    PresetFileError
        One line naming ``where``, the key and the value.
    """
    ctx = _Context(where, base or Path.cwd())
    schema = doc.get("schema")
    if schema is None:
        raise ctx.error(f"no schema key: a preset file starts with schema = "
                        f"{_literal(PRESET_SCHEMA)}")
    if schema != PRESET_SCHEMA:
        raise ctx.error(f"schema = {_literal(schema)}: this arenabench reads "
                        f"{_literal(PRESET_SCHEMA)}")
    meta = doc.get("preset", {})
    if not isinstance(meta, dict):
        raise ctx.fail("preset", meta, "must be a table ([preset] with name, description, "
                       "evidence)")
    for key in meta:
        if key not in PRESET_KEYS:
            raise ctx.fail(f"preset.{key}", meta[key], "unknown key of [preset]"
                           f"{did_you_mean(key, PRESET_KEYS)} (keys: {', '.join(PRESET_KEYS)})")
    name = _name(ctx, meta, source)
    description = meta.get("description", "")
    if not isinstance(description, str):
        raise ctx.fail("preset.description", description, "must be a string")
    evidence = meta.get("evidence", "")
    if not isinstance(evidence, (str, dict)):
        raise ctx.fail("preset.evidence", evidence, "must be a string or a table")
    _check_plain(ctx, "preset.evidence", evidence)
    given: dict[str, Value] = {}
    spelled: dict[str, str] = {}
    for top, value in doc.items():
        if top in RESERVED_KEYS:
            continue
        for key, raw in _flatten(ctx, top, value):
            canonical = canonical_key(key)
            if canonical in given:
                raise ctx.fail(key, raw, f"given twice (also as {spelled[canonical]})")
            given[canonical] = _param_value(ctx, canonical, raw, spelled_as=key)
            spelled[canonical] = key
    try:
        params = resolve_params(given)
    except ValueError as exc:
        missing = str(exc).removeprefix("preset lacks parameters: ").split(", ")
        shown = ", ".join(missing[:6]) + (f" and {len(missing) - 6} more"
                                          if len(missing) > 6 else "")
        raise ctx.error(f"missing parameters: {shown} (a preset file gives every parameter "
                        "without a neutral value; 'arenabench presets --show eyrc --format "
                        "toml' writes a complete one to start from)") from None
    open_ = _open_table(ctx, doc.get("open", {}), params)
    return ResolvedPreset(name=name, params=params, description=description,
                          evidence=evidence, open=open_, source=source)


@dataclass(frozen=True)
class _Context:
    """Where a preset file's problems are reported (``"preset file X"``), and what its
    relative paths mean."""

    where: str
    base: Path
    what: str = "preset file "

    def error(self, message: str) -> PresetFileError:
        return PresetFileError(f"{self.what}{self.where}: {' '.join(message.split())}")

    def fail(self, key: str, value: Any, why: str) -> PresetFileError:
        return self.error(f"{key} = {_shown(value)}: {why}")


def _name(ctx: _Context, meta: dict[str, Any], source: Path | None) -> str:
    if "name" in meta:
        name = meta["name"]
        if not isinstance(name, str) or not NAME_RE.fullmatch(name):
            raise ctx.fail("preset.name", name, "a preset name is 1 to 64 letters, digits, "
                           "'.', '_' or '-', starting with a letter or digit")
        return name
    stem = source.stem if source is not None else ""
    if not NAME_RE.fullmatch(stem):
        raise ctx.error(f"no [preset] name, and the file's name {stem!r} is not a preset "
                        "name: add name = \"...\" to [preset]")
    return stem


def _check_plain(ctx: _Context, key: str, value: Any, depth: int = 0) -> None:
    """Refuse what JSON cannot hold (TOML dates and times) in free-form values."""
    if depth > 16:
        raise ctx.fail(key, value, "nested too deeply")
    if isinstance(value, dict):
        for k, v in value.items():
            _check_plain(ctx, f"{key}.{k}", v, depth + 1)
    elif isinstance(value, list):
        for v in value:
            _check_plain(ctx, key, v, depth + 1)
    elif isinstance(value, float) and not math.isfinite(value):
        raise ctx.fail(key, value, "not a finite number")
    elif not isinstance(value, (str, int, float, bool)):
        raise ctx.fail(key, value, f"a {type(value).__name__} (write it as a string)")


def _is_param(key: str) -> bool:
    return canonical_key(key) in PARAMETERS


def _flatten(ctx: _Context, top: str, value: Any) -> list[tuple[str, Any]]:
    """The ``(dotted name, raw value)`` pairs under top-level key ``top``: a section table
    (``[camera]``), dotted keys (``camera.tilt_deg = 4``, the same), or a quoted dotted name
    (``"camera.tilt_deg" = 4``, JSON's ``{"camera.tilt_deg": 4}``)."""
    if _is_param(top):
        return [(top, value)]
    if not isinstance(value, dict):
        if "." in top:
            raise ctx.fail(top, value, "unknown parameter"
                           f"{did_you_mean(top, [*PARAMETERS, *ALIASES])} (list them: "
                           "arenabench presets --params)")
        raise ctx.fail(top, value, "unknown key"
                       f"{did_you_mean(top, [*RESERVED_KEYS, *SECTIONS])} (a preset file "
                       f"holds schema, [preset], [open] and the parameter sections "
                       f"{', '.join(SECTIONS)})")
    if "." not in top and top not in SECTIONS:
        raise ctx.error(f"unknown table [{top}]{did_you_mean(top, [*RESERVED_KEYS, *SECTIONS])}"
                        f" (sections: {', '.join(SECTIONS)})")
    out: list[tuple[str, Any]] = []
    for sub, raw in value.items():
        key = f"{top}.{sub}"
        if _is_param(key):
            out.append((key, raw))
        elif isinstance(raw, dict) and any(k.startswith(key + ".")
                                           for k in (*PARAMETERS, *ALIASES)):
            out.extend(_flatten(ctx, key, raw))
        else:
            raise ctx.fail(key, raw, "unknown parameter"
                           f"{did_you_mean(key, [*PARAMETERS, *ALIASES])} (list them: "
                           "arenabench presets --params)")
    return out


_KIND_FORMS = {
    "float": 'a number, a range "lo:hi" or [lo, hi]',
    "int": 'an integer, a range "lo:hi" or [lo, hi]',
    "bool": "true or false",
    "str": "a string",
    "rgb": "three integers [r, g, b] (or \"r,g,b\")",
    "ids": "four integers [nw, ne, se, sw] (or \"nw,ne,se,sw\")",
    "size": "two numbers [width, height] (or \"w,h\")",
    "file": "a file's path (relative to this file)",
}


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _param_value(ctx: _Context, key: str, raw: Any, *, spelled_as: str,
                 fixed_only: bool = False) -> Value:
    """``raw`` (a parsed TOML/JSON value) as parameter ``key``'s value, validated as ``--set``
    validates it (:func:`arenabench.generator.parameters.param_values.validate_value`)."""
    spec = PARAMETERS[key]
    forms = _KIND_FORMS.get(spec.kind, "a value")
    if fixed_only and spec.numeric:
        forms = "a number" if spec.kind == "float" else "an integer"

    def bad(why: str) -> PresetFileError:
        return ctx.fail(spelled_as, raw, why)

    if isinstance(raw, dict):
        return _raise(bad(f"a table where a value belongs (write {forms})"))
    if spec.numeric:
        value = _numeric_form(raw, forms, fixed_only=fixed_only)
    else:
        value = _form_of_kind(ctx, spec.kind, raw, forms)
    if isinstance(value, _Misfit):
        raise bad(value.why)
    try:
        return validate_value(key, value)
    except ValueError as exc:
        why = str(exc).removeprefix(f"--set {key}: ").removeprefix("--set: ")
        raise bad(why) from None


class _Misfit:
    """A value in the wrong form for its parameter, and what is wrong with it."""

    def __init__(self, why: str) -> None:
        self.why = why


def _numeric_form(raw: Any, forms: str, *, fixed_only: bool) -> Any:
    """A number, a range (``"lo:hi"`` or ``[lo, hi]``, unless ``fixed_only``), or a misfit."""
    if isinstance(raw, str) and ":" in raw and not fixed_only:
        return tuple(raw.split(":", 1))
    if isinstance(raw, list) and not fixed_only:
        if len(raw) != 2 or not all(_number(v) for v in raw):
            return _Misfit("a range is two numbers [lo, hi]")
        return tuple(raw)
    if not _number(raw):
        what = "a string" if isinstance(raw, str) else f"a {_toml_type(raw)}"
        return _Misfit(f"{what} where a number belongs (write {forms})")
    return raw


def _form_of_kind(ctx: _Context, kind: str, raw: Any, forms: str) -> Any:
    """``raw`` in the TOML form a non-numeric kind takes (a file: its texture reference),
    or a misfit."""
    if kind == "bool" and not isinstance(raw, bool):
        return _Misfit(f"a {_toml_type(raw)} where true or false belongs")
    if kind == "str" and not isinstance(raw, str):
        return _Misfit(f"a {_toml_type(raw)} where a string belongs")
    if kind in ("rgb", "ids", "size"):
        kinds = (int,) if kind != "size" else (int, float)
        if isinstance(raw, list):
            if not all(isinstance(v, kinds) and not isinstance(v, bool) for v in raw):
                return _Misfit(f"expected {forms}")
        elif not isinstance(raw, str):
            return _Misfit(f"a {_toml_type(raw)} where {forms} belongs")
    if kind == "file":
        if not isinstance(raw, str):
            return _Misfit(f"a {_toml_type(raw)} where {forms} belongs")
        try:
            return _texture_ref(ctx, raw)
        except ValueError as exc:
            return _Misfit(str(exc))
    return raw


def _texture_ref(ctx: _Context, raw: str) -> str:
    """An image file named in a preset file, as its reference (read into the texture cache):
    a path relative to the file's folder, or a reference whose copy lies there
    (``textures/<sha256>.png``) or in the cache."""
    if not raw:
        return ""
    if texture_store.is_ref(raw):
        return texture_store.import_ref(raw, ctx.base, where=str(ctx.base / raw))
    path = Path(raw).expanduser()
    return texture_store.import_texture(path if path.is_absolute() else ctx.base / path)


def _raise(exc: Exception) -> Any:
    raise exc


def _toml_type(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, (int, float)):
        return "number"
    if isinstance(value, list):
        return "list"
    if isinstance(value, dict):
        return "table"
    if isinstance(value, str):
        return "string"
    return type(value).__name__


def _open_table(ctx: _Context, table: Any, params: dict[str, Value]) -> dict[str, OpenParam]:
    """The ``[open]`` entries, validated: a known parameter each, a range (numbers) or values,
    a reason, and the preset's own value inside what they allow."""
    if not isinstance(table, dict):
        raise ctx.fail("open", table, "must be a table: [open.\"PARAM\"] with range = [lo, hi]"
                       " (or values = [...]) and reason = \"...\"")
    entries: list[tuple[str, Any]] = []
    for top, value in table.items():
        if _is_param(top) or not (isinstance(value, dict) and top in SECTIONS
                                  and not set(value) & set(OPEN_KEYS)):
            entries.append((top, value))
        else:  # [open.camera] tilt_deg = {...}: a section of entries
            entries.extend((f"{top}.{sub}", v) for sub, v in value.items())
    out: dict[str, OpenParam] = {}
    for spelled, entry in entries:
        key = canonical_key(spelled)
        if key in out:
            raise ctx.fail(f"open.{spelled}", entry, "given twice")
        out[key] = _open_entry(ctx, spelled, entry, params)
    _check_leaders(ctx, out)
    return out


def _open_entry(ctx: _Context, spelled: str, entry: Any,
                params: dict[str, Value]) -> OpenParam:
    """One ``[open]`` entry, validated."""
    where = f"open.{spelled}"
    key = canonical_key(spelled)
    if key not in PARAMETERS:
        raise ctx.fail(where, entry, "unknown parameter"
                       f"{did_you_mean(spelled, [*PARAMETERS, *ALIASES])} (list them: "
                       "arenabench presets --params)")
    if not isinstance(entry, dict):
        raise ctx.fail(where, entry, "an [open] entry is a table: range = [lo, hi] (or "
                       "values = [...]) and reason = \"...\"")
    for k in entry:
        if k not in OPEN_KEYS:
            raise ctx.fail(f"{where}.{k}", entry[k], "unknown key of an [open] entry"
                           f"{did_you_mean(k, OPEN_KEYS)} (keys: {', '.join(OPEN_KEYS)})")
    reason = entry.get("reason")
    if not isinstance(reason, str) or not reason.strip():
        raise ctx.fail(where, entry, "needs a reason = \"...\" (why the evidence does not "
                       "pin it)")
    if ("range" in entry) == ("values" in entry):
        raise ctx.fail(where, entry, "needs range = [lo, hi] or values = [...], one of "
                       "them")
    if "range" in entry:
        item = _open_range(ctx, where, key, entry, params, reason.strip())
    else:
        item = _open_values(ctx, where, key, entry, params, reason.strip())
    if not item.allows(params[key]):
        raise ctx.fail(where, entry, f"the preset's own {key} = "
                       f"{_shown(_file_value(params[key]))} is not among what it allows")
    return item


def _open_range(ctx: _Context, where: str, key: str, entry: dict, params: dict[str, Value],
                reason: str) -> OpenParam:
    """An ``[open]`` entry with ``range = [lo, hi]`` (a numeric parameter)."""
    raw = entry["range"]
    if not PARAMETERS[key].numeric:
        raise ctx.fail(f"{where}.range", raw, f"{key} is not a number: give values = [...]")
    if not (isinstance(raw, list) or (isinstance(raw, str) and ":" in raw)):
        raise ctx.fail(f"{where}.range", raw, 'a range is [lo, hi] or "lo:hi"')
    value = _param_value(ctx, key, raw, spelled_as=f"{where}.range")
    if not isinstance(value, Range):
        raise ctx.fail(f"{where}.range", raw, "a range of one value: an open "
                       "parameter allows more than one")
    moves = _moves_with(ctx, where, key, entry.get("moves_with", {}), params, 2)
    return OpenParam(key, reason, range=value, moves_with=moves)


def _open_values(ctx: _Context, where: str, key: str, entry: dict, params: dict[str, Value],
                 reason: str) -> OpenParam:
    """An ``[open]`` entry with ``values = [...]`` (two or more, each once)."""
    raw = entry["values"]
    if not isinstance(raw, list) or len(raw) < 2:
        raise ctx.fail(f"{where}.values", raw, "a list of at least two values")
    values = tuple(_param_value(ctx, key, v, spelled_as=f"{where}.values", fixed_only=True)
                   for v in raw)
    if len(set(values)) != len(values):
        raise ctx.fail(f"{where}.values", raw, "a value is listed twice")
    moves = _moves_with(ctx, where, key, entry.get("moves_with", {}), params, len(values))
    return OpenParam(key, reason, values=values, moves_with=moves)


def _check_leaders(ctx: _Context, out: dict[str, OpenParam]) -> None:
    """A parameter moves with one other at most, and a follower leads none."""
    leaders: dict[str, str] = {}
    for key, item in out.items():
        for name, _ in item.moves_with:
            if name in leaders:
                raise ctx.fail(f"open.{key}.moves_with", name, "already moves with "
                               f"{leaders[name]}: a parameter moves with one other at most")
            if out.get(name) is not None and out[name].moves_with:
                raise ctx.fail(f"open.{key}.moves_with", name, "has a moves_with of its own: "
                               "name every parameter of the trade in one entry")
            leaders[name] = key


def _moves_with(ctx: _Context, where: str, key: str, table: Any, params: dict[str, Value],
                count: int) -> tuple[tuple[str, tuple[float, ...]], ...]:
    """An ``[open]`` entry's ``moves_with`` table, validated: other numeric parameters the
    preset holds fixed, each with ``count`` numbers (at the range's low and high end, or at
    each of the entry's values)."""
    points = "the range's low end, then at its high end" if count == 2 else (
        f"each of the {count} values, in their order")
    if not isinstance(table, dict):
        raise ctx.fail(f"{where}.moves_with", table, 'a table: {"PARAM" = [at lo, at hi]} (or '
                       "one value per listed value)")
    out = []
    for spelled, raw in table.items():
        at = f"{where}.moves_with.{spelled}"
        name = canonical_key(spelled)
        if name not in PARAMETERS:
            raise ctx.fail(at, raw, "unknown parameter"
                           f"{did_you_mean(spelled, [*PARAMETERS, *ALIASES])}")
        if name == key:
            raise ctx.fail(at, raw, "the entry's own parameter")
        if not PARAMETERS[name].numeric:
            raise ctx.fail(at, raw, f"{name} is not a number")
        if isinstance(params[name], Range):
            raise ctx.fail(at, raw, f"the preset draws {name} per scene (a range): only a "
                           "fixed value can move with another")
        if not isinstance(raw, list) or len(raw) != count:
            raise ctx.fail(at, raw, f"{count} numbers: the value at {points}")
        out.append((name, tuple(float(_param_value(ctx, name, v, spelled_as=at,
                                                   fixed_only=True)) for v in raw)))
    return tuple(sorted(out))


# --------------------------------------------------------------------------- the --preset rule


# ------------------------------------------------------------------------------- writing


def preset_hash(params: Mapping[str, Value]) -> str:
    """10 hex digits of the SHA-256 of ``params`` as a preset file's sections hold them (the
    same parameters, the same digits)."""
    text = dumps_json(_param_sections(params))
    return sha256_bytes(text.encode("utf-8"))[:10]


def _file_value(value: Value) -> Any:
    """A parameter value as a preset file holds it: a range as ``[lo, hi]``, a tuple as a
    list, anything else as it is."""
    if isinstance(value, Range):
        return [value.lo, value.hi]
    if isinstance(value, tuple):
        return list(value)
    return value


def _split(name: str) -> tuple[str, str]:
    section, _, rest = name.partition(".")
    return section, rest


def _param_sections(params: Mapping[str, Value]) -> dict[str, dict[str, Any]]:
    """``{section: {key: file value}}`` in the order of :data:`PARAMS`."""
    out: dict[str, dict[str, Any]] = {}
    for spec in PARAMS:
        if spec.name in params:
            section, rest = _split(spec.name)
            out.setdefault(section, {})[rest] = _file_value(params[spec.name])
    return out


def _complete(params: Mapping[str, Value]) -> dict[str, Value]:
    """Every parameter after the defaults, validated (a ``ValueError`` names the problem)."""
    return resolve_params(dict(params))


def _open_params(open: Mapping[str, OpenParam | Mapping[str, Any]] | None,
                 params: dict[str, Value]) -> dict[str, OpenParam]:
    """``open`` as :class:`OpenParam` entries (a mapping entry is validated as a file's)."""
    out: dict[str, OpenParam] = {}
    raw: dict[str, Any] = {}
    for key, entry in (open or {}).items():
        if isinstance(entry, OpenParam):
            out[canonical_key(key)] = entry
        else:
            raw[key] = dict(entry)
    if raw:
        out.update(_open_table(_Context("open", Path.cwd(), what=""), raw, params))
    for key, entry in out.items():
        if key not in PARAMETERS or not entry.allows(params[key]):
            raise ValueError(f"open {key}: not a parameter, or the preset's value is not "
                             "among what it allows")  # an OpenParam made in code
        for name, _ in entry.moves_with:
            if (name not in PARAMETERS or not PARAMETERS[name].numeric or name == key
                    or isinstance(params[name], Range)):
                raise ValueError(f"open {key}: moves_with {name}: not another numeric "
                                 "parameter the preset holds fixed")
    # the file's own checks (one leader per parameter, no chains) on the written form
    _open_table(_Context("open", Path.cwd(), what=""),
                {k: v.to_dict() for k, v in out.items()}, params)
    return out


def preset_document(params: Mapping[str, Value], *, name: str, description: str = "",
                    evidence: str | Mapping[str, Any] = "",
                    open: Mapping[str, OpenParam | Mapping[str, Any]] | None = None,
                    ) -> dict[str, Any]:
    """A preset file's content (what :func:`preset_to_json` writes).

    Parameters
    ----------
    params : mapping
        Parameter name -> value (a :class:`Range` for a range); parameters left out get their
        neutral values. Every value is validated.
    name : str, keyword-only
        The preset's name (:data:`NAME_RE`).
    description : str, keyword-only
        One line.
    evidence : str or mapping, keyword-only
        Where the values came from: text, or a table.
    open : mapping, keyword-only
        Parameter -> :class:`OpenParam` (or a mapping ``{"range": [lo, hi] | "values":
        [...], "reason": "..."}`` as in a file).

    Returns
    -------
    dict
        ``{"schema", "preset": {"name", "description"[, "evidence"]}, <section>: {<key>:
        value}, ...[, "open": {<param>: {...}}]}``: every parameter, sections in the order of
        :data:`~arenabench.generator.parameters.params.PARAMS`.

    Raises
    ------
    ValueError
        Naming the bad name, parameter, value or entry.
    """
    if not NAME_RE.fullmatch(str(name)):
        raise ValueError(f"preset name {name!r}: 1 to 64 letters, digits, '.', '_' or '-', "
                         "starting with a letter or digit")
    complete = _complete(params)
    meta: dict[str, Any] = {"name": str(name), "description": str(description)}
    if evidence:
        meta["evidence"] = evidence if isinstance(evidence, str) else dict(evidence)
    doc: dict[str, Any] = {"schema": PRESET_SCHEMA, "preset": meta,
                           **_param_sections(complete)}
    opened = _open_params(open, complete)
    if opened:
        doc["open"] = {k: v.to_dict() for k, v in opened.items()}
    return doc


def _literal(value: Any) -> str:
    """A TOML literal of ``value`` (arrays and tables inline), escaped by ``tomli_w``."""
    import tomli_w

    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_literal(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_literal(v)}" for k, v in value.items()) + " }"
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


def _shown(value: Any) -> str:
    """``value`` as messages show it (a TOML literal; ``?`` for what TOML cannot write)."""
    try:
        text = _literal(value)
    except (TypeError, ValueError):
        text = repr(value)
    return cut(text)


def _key(key: str) -> str:
    """A TOML key, quoted when it must be."""
    import tomli_w

    return tomli_w.dumps({key: 0})[: -len(" = 0\n")]


def preset_to_toml(params: Mapping[str, Value], *, name: str, description: str = "",
                   evidence: str | Mapping[str, Any] = "",
                   open: Mapping[str, OpenParam | Mapping[str, Any]] | None = None,
                   ) -> str:
    """A preset file in TOML: :func:`preset_document` laid out for people (one table per
    section, each parameter with its help line as a comment).

    Parameters are as :func:`preset_document`'s. The text is checked to read back (with
    ``tomllib``) to exactly that document.
    """
    import tomli_w

    doc = preset_document(params, name=name, description=description, evidence=evidence,
                          open=open)
    lines = [
        "# arenabench preset file (docs/formats.md, \"Preset files\"): generate from it with",
        "# `arenabench generate --preset THIS_FILE`; `arenabench presets --params` explains",
        "# every parameter. A range is \"lo:hi\" or [lo, hi].",
        f"schema = {_literal(PRESET_SCHEMA)}",
        "",
        "[preset]",
    ]
    meta = doc["preset"]
    lines += [f"{_key(k)} = {_literal(meta[k])}" for k in ("name", "description")]
    evidence_doc = meta.get("evidence")
    if isinstance(evidence_doc, str):
        lines.append(f"evidence = {_literal(evidence_doc)}")
    elif evidence_doc:
        lines += ["", tomli_w.dumps({"preset": {"evidence": evidence_doc}}).rstrip("\n")]
    for section, values in doc.items():
        if section in RESERVED_KEYS:
            continue
        lines += ["", f"[{_key(section)}]"]
        for key, value in values.items():
            help_ = PARAMETERS[f"{section}.{key}"].help
            lines.append(f"{_key(key)} = {_literal(value)}  # {help_}")
    for key, entry in doc.get("open", {}).items():
        lines += ["", f"[open.{_key(key)}]"]
        lines += [f"{_key(k)} = {_literal(v)}" for k, v in entry.items()]
    text = "\n".join(lines) + "\n"
    if tomllib.loads(text) != doc:  # pragma: no cover - a bug of this writer
        raise RuntimeError("preset_to_toml: the text does not read back to the preset")
    return text


def preset_to_json(params: Mapping[str, Value], *, name: str, description: str = "",
                   evidence: str | Mapping[str, Any] = "",
                   open: Mapping[str, OpenParam | Mapping[str, Any]] | None = None,
                   ) -> str:
    """A preset file in JSON: :func:`preset_document` as canonical JSON (sorted keys)."""
    return dumps_json(preset_document(params, name=name, description=description,
                                      evidence=evidence, open=open))


def write_preset_file(path: str | os.PathLike[str], params: Mapping[str, Value], *,
                      name: str, description: str = "",
                      evidence: str | Mapping[str, Any] = "",
                      open: Mapping[str, OpenParam | Mapping[str, Any]] | None = None,
                      ) -> Path:
    """Write a preset file (TOML, or JSON when ``path`` ends in ``.json``) atomically.

    Parameters are as :func:`preset_document`'s; :func:`load_preset_file` reads the file
    back to a :class:`ResolvedPreset` with the same parameters, so a set generated from the
    file is byte-identical to one generated from ``params`` under ``name``. A texture image
    (``arena.texture_file``: a path, or a reference the texture cache holds) is copied beside
    the file, to ``textures/<sha256>.png``, the path the file names it by.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        Naming the bad name, parameter, value or ``open`` entry (nothing is written).
    """
    p = Path(path)
    as_json = p.suffix.lower() == ".json"
    write = preset_to_json if as_json else preset_to_toml
    text = write(params, name=name, description=description, evidence=evidence, open=open)
    for ref in texture_refs(resolve_params(dict(params))):
        texture_store.export_texture(ref, p.parent)
    atomic_write_text(p, text)
    return p


def texture_refs(params: Mapping[str, Value]) -> list[str]:
    """The texture images (references, ``textures/<sha256>.png``) of resolved ``params``."""
    return sorted({v for k, v in params.items() if PARAMETERS[k].kind == "file" and v})


def show_lines(preset: ResolvedPreset) -> list[str]:
    """``KEY=VALUE`` lines of every parameter (``arenabench presets --show NAME``), in the
    ``--set`` spelling, in the order of :data:`~arenabench.generator.parameters.params.PARAMS`."""
    return [f"{spec.name}={format_value(preset.params[spec.name])}" for spec in PARAMS]
