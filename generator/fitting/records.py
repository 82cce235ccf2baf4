"""Pinned and open: what the image says of each parameter of the twin's preset.

A parameter is **pinned** when the image fixes it: the record holds its value, the evidence and
its residual (how much a change of it moves the render away from the real image, in the unit
the record names). It is **open** when the image leaves it free: the record holds the range (or
values) kept and why. Every parameter of :data:`arenabench.generator.parameters.params.PARAMS` gets
one
record; those that cannot change this twin's images (a procedural texture's seed on an image
texture, say) are open with that reason and their one value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from arenabench.generator.parameters.params import PARAMS, Range, Value
from arenabench.generator.parameters.preset_files import OpenParam

#: The ``schema`` of ``twin.json``.
TWIN_SCHEMA = "arenabench.twin/1"
#: Record statuses.
STATUSES = ("pinned", "open")


@dataclass(frozen=True)
class Record:
    """What the image says of one parameter.

    Attributes
    ----------
    name : str
        The preset parameter.
    status : str
        ``"pinned"`` or ``"open"``.
    value : Range or value
        The preset's value.
    evidence : str
        What in the image gives it (pinned), or what the image shows of it (open).
    residual : float or None
        Pinned: how much the render moves away from the real image when the value moves by
        ``step`` (``residual_unit`` says in what); ``None`` where no render measures it (read
        from the file, say).
    residual_unit : str
        What ``residual`` measures.
    range : Range or None
        Open: the range kept (numbers).
    values : tuple or None
        Open: the values kept, when not a range.
    reason : str
        Open: why the image leaves it open.
    varies : bool
        Whether the preset draws it per scene (the boxes: the target varies them too).
    moves_with : tuple of (str, tuple of float)
        Open: the parameters the image ties to this one, with their values at the range's low
        and high end, or at each of the values (:attr:`OpenParam.moves_with`).
    gauge : bool
        Open only as every length is (the image fixes lengths up to one scale): at any scale,
        every length scaled alike, the images and the answers in the rectified frame are the
        same, and alone it would give another image. It is not an ``[open]`` entry of the
        preset file (there is nothing to vary); ``twin.json`` keeps the record.
    """

    name: str
    status: str
    value: Value
    evidence: str = ""
    residual: float | None = None
    residual_unit: str = ""
    range: Range | None = None
    values: tuple[Value, ...] | None = None
    reason: str = ""
    varies: bool = False
    moves_with: tuple[tuple[str, tuple[float, ...]], ...] = ()
    gauge: bool = False

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"record {self.name}: status must be pinned or open, "
                             f"got {self.status!r}")
        if self.status == "open" and self.range is None and self.values is None:
            raise ValueError(f"record {self.name}: an open record keeps a range or values")

    def to_dict(self) -> dict[str, Any]:
        """The record as ``twin.json`` holds it."""
        out: dict[str, Any] = {"status": self.status, "value": _plain(self.value)}
        if self.evidence:
            out["evidence"] = self.evidence
        if self.status == "pinned":
            out["residual"] = self.residual
            if self.residual_unit:
                out["residual_unit"] = self.residual_unit
        else:
            if self.range is not None:
                out["range"] = [self.range.lo, self.range.hi]
            else:
                out["values"] = [_plain(v) for v in self.values or ()]
            out["reason"] = self.reason
            if self.moves_with:
                out["moves_with"] = {name: list(ends) for name, ends in self.moves_with}
        if self.varies:
            out["varies"] = True
        if self.gauge:
            out["gauge"] = True
        return out

    def open_param(self) -> OpenParam | None:
        """The preset file's ``[open]`` entry of an open record that matters (one whose range
        or values hold more than the preset's value), else None."""
        if self.status != "open" or self.gauge:
            return None
        if self.range is not None:
            return OpenParam(self.name, self.reason, range=self.range,
                             moves_with=self.moves_with)
        if self.values is not None and len(self.values) > 1:
            return OpenParam(self.name, self.reason, values=tuple(self.values),
                             moves_with=self.moves_with)
        return None


def _plain(value: Value) -> Any:
    if isinstance(value, Range):
        return [value.lo, value.hi]
    if isinstance(value, tuple):
        return list(value)
    return value


def pinned(name: str, value: Value, evidence: str, residual: float | None = None,
           unit: str = "") -> Record:
    """A pinned record."""
    return Record(name, "pinned", value, evidence, None if residual is None
                  else round(float(residual), 4), unit)


def open_range(name: str, value: Value, range_: Range, reason: str, *, evidence: str = "",
               varies: bool = False,
               moves_with: tuple[tuple[str, tuple[float, float]], ...] = (),
               gauge: bool = False) -> Record:
    """An open record keeping a range (and what moves with it)."""
    return Record(name, "open", value, evidence, range=range_, reason=reason, varies=varies,
                  moves_with=moves_with, gauge=gauge)


def open_values(name: str, value: Value, values: tuple[Value, ...], reason: str, *,
                evidence: str = "", varies: bool = False,
                moves_with: tuple[tuple[str, tuple[float, ...]], ...] = ()) -> Record:
    """An open record keeping values (and what moves with it, a value for each)."""
    return Record(name, "open", value, evidence, values=tuple(values), reason=reason,
                  varies=varies, moves_with=moves_with)


def complete(records: dict[str, Record], params: dict[str, Value]) -> list[Record]:
    """Every parameter's record in :data:`PARAMS` order: those given, and for the others an
    open record saying the parameter cannot change this twin's images."""
    out = []
    for spec in PARAMS:
        if spec.name in records:
            out.append(records[spec.name])
        else:
            value = params[spec.name]
            out.append(Record(spec.name, "open", value, values=(value,),
                              reason="no effect on this twin's images (the generator's neutral "
                                     "or an unused value)"))
    return out

