"""The ground-truth record of one image (schema ``arenabench.gt/1``), typed.

One declaration of the GT file's layout, used by the generator's writer, the harness's reader
and the COCO export; the JSON Schema shipped in :mod:`arenabench.schemas`
(``gt.schema.json``) describes the same fields for readers in other languages, and
docs/formats.md documents them.

Every record is a frozen dataclass with ``to_dict()`` (the JSON form, as written to
``gt/NNNNNN.json``) and ``from_dict()`` (its inverse). Optional fields are ``None`` when
absent (older generator versions wrote fewer) and are left out by ``to_dict``; fields this
version does not know are kept in ``extra`` and written back, so
``X.from_dict(d).to_dict() == d`` for every valid record ``d``. Lists are stored as tuples.
``from_dict`` does not validate: readers check a parsed file with
:func:`arenabench.schemas.gt_problem` first (messages naming the field).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, ClassVar

from arenabench.fileio import dumps_json
from arenabench.schemas import GT_SCHEMA

__all__ = [
    "AreaRecord", "CameraRecord", "FrameRecord", "GroundTruth", "MarkerRecord",
    "ObstacleRecord",
]  # fmt: skip


def _frozen(value: Any) -> Any:
    """``value`` with lists as tuples (nested); mappings are copied."""
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    if isinstance(value, Mapping):
        return {k: _frozen(v) for k, v in value.items()}
    return value


def _plain(value: Any) -> Any:
    """The JSON form of a stored value: records as dicts, tuples as lists."""
    if isinstance(value, _Record):
        return value.to_dict()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


class _Record:
    """``to_dict`` / ``from_dict`` for the record dataclasses below."""

    #: field -> record type of its value
    _NESTED: ClassVar[dict[str, type]] = {}
    #: field -> record type of its list items
    _ITEMS: ClassVar[dict[str, type]] = {}

    extra: Mapping[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (absent optional fields left out, ``extra`` merged back)."""
        out = {k: _plain(v) for k, v in self.extra.items()}
        for f in fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if f.name != "extra" and value is not None:
                out[f.name] = _plain(value)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Any:
        """The record of a parsed JSON object (already checked against the schema).

        Raises
        ------
        ValueError
            When ``data`` is not a mapping or lacks a required field (named).
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"{cls.__name__} needs a JSON object, got {type(data).__name__}")
        names = {f.name for f in fields(cls) if f.name != "extra"}  # type: ignore[arg-type]
        kwargs: dict[str, Any] = {}
        for name in names & data.keys():
            value = data[name]
            if value is None:
                continue
            if name in cls._NESTED:
                value = cls._NESTED[name].from_dict(value)
            elif name in cls._ITEMS:
                value = tuple(cls._ITEMS[name].from_dict(v) for v in value)
            else:
                value = _frozen(value)
            kwargs[name] = value
        extra = {k: _frozen(v) for k, v in data.items() if k not in names}
        try:
            return cls(**kwargs, extra=extra)
        except TypeError:
            missing = sorted(f.name for f in fields(cls)  # type: ignore[arg-type]
                             if f.name not in kwargs and f.default is MISSING
                             and f.default_factory is MISSING)
            raise ValueError(f"{cls.__name__}: field(s) {', '.join(missing)} missing") from None


@dataclass(frozen=True)
class AreaRecord(_Record):
    """GT ``area``: unions of the obstacles in the rectified frame, in frame px².

    Attributes
    ----------
    visible_px : float
        Union of the visible silhouettes (what a top-down camera sees hidden by boxes).
    footprint_px : float
        Union of the footprints on the floor.
    contour_px : float, optional
        What ``cv2.contourArea`` of the pixelated visible silhouettes gives (generator
        version 4 on).
    extra : mapping
        Other areas (the schema allows more).
    """

    visible_px: float
    footprint_px: float
    contour_px: float | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class AreaReference:
    """The GT fields behind one ``--area-reference``.

    Parameters
    ----------
    area : str
        The GT ``area`` field (:class:`AreaRecord`) an answer is compared with.
    polygons : str
        The per-obstacle frame polygons (:class:`ObstacleRecord`) whose union that area
        measures, drawn as the ground truth in the HTML report.
    """

    area: str
    polygons: str


#: ``--area-reference`` name -> its GT fields, the one mapping scoring and the reports use.
#: ``contour_px`` (absent from GT files written before generator version 4) is
#: ``cv2.contourArea`` of the pixelated union of the *visible* polygons, so it draws those.
AREA_REFERENCE_FIELDS: dict[str, AreaReference] = {
    "visible": AreaReference(area="visible_px", polygons="visible_frame_px"),
    "footprint": AreaReference(area="footprint_px", polygons="footprint_frame_px"),
    "contour": AreaReference(area="contour_px", polygons="visible_frame_px"),
}

#: ``--area-reference`` name -> the GT ``area`` field an answer is compared with.
AREA_REFERENCES: dict[str, str] = {k: v.area for k, v in AREA_REFERENCE_FIELDS.items()}

#: The area reference of every command unless ``--area-reference`` says otherwise.
DEFAULT_AREA_REFERENCE = "visible"


@dataclass(frozen=True)
class FrameRecord(_Record):
    """GT ``frame``: the rectified frame the homography maps to (``size`` [w, h] px and
    ``corners``, ``"inner"`` or ``"outer"``)."""

    size: tuple[int, ...] | None = None
    corners: str | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CameraRecord(_Record):
    """GT ``camera``: intrinsics ``K`` (3x3), distortion ``dist`` (OpenCV order) and the 4x4
    pose ``world_from_camera``."""

    K: tuple[tuple[float, ...], ...] | None = None
    dist: tuple[float, ...] | None = None
    world_from_camera: tuple[tuple[float, ...], ...] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class MarkerRecord(_Record):
    """One entry of GT ``markers``.

    Attributes
    ----------
    id : int
        ArUco id.
    dictionary : str, optional
        ArUco dictionary name.
    corner : {"nw", "ne", "se", "sw"}, optional
        The arena corner it marks.
    corners_px : tuple of (x, y), optional
        Its four corners in the image, px (pixel centres at integers).
    in_view, visible : bool, optional
        Inside the image; inside and not occluded (what a pipeline should report).
    in_view_fraction, occluded_fraction : float, optional
        Fraction of its area inside the image / hidden from the camera (by floor patches
        and boxes).
    """

    id: int
    dictionary: str | None = None
    corner: str | None = None
    corners_px: tuple[tuple[float, float], ...] | None = None
    in_view: bool | None = None
    visible: bool | None = None
    in_view_fraction: float | None = None
    occluded_fraction: float | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    @property
    def expected(self) -> bool:
        """Whether a pipeline is expected to report it: ``visible`` when the GT has it, else
        ``in_view``, else True."""
        if self.visible is not None:
            return bool(self.visible)
        return True if self.in_view is None else bool(self.in_view)


@dataclass(frozen=True)
class ObstacleRecord(_Record):
    """One entry of GT ``obstacles`` (a box).

    Attributes
    ----------
    shape : str, optional
        ``"box"``.
    center_m, size_m : tuple of float, optional
        Centre (x, y) on the floor and (length, width, height), metres.
    yaw_deg : float, optional
        Rotation about the vertical axis.
    color_rgb : tuple of int, optional
        Side colour.
    footprint_frame_px, visible_frame_px, image_polygon_px : tuple of (x, y), optional
        Footprint and visible silhouette in the frame, outline in the image.
    footprint_area_px, visible_area_px : float, optional
        Their areas in the frame, px².
    in_view : bool, optional
        All its projected vertices lie inside the image.
    """

    shape: str | None = None
    center_m: tuple[float, ...] | None = None
    yaw_deg: float | None = None
    size_m: tuple[float, ...] | None = None
    color_rgb: tuple[int, ...] | None = None
    footprint_frame_px: tuple[tuple[float, float], ...] | None = None
    visible_frame_px: tuple[tuple[float, float], ...] | None = None
    image_polygon_px: tuple[tuple[float, float], ...] | None = None
    footprint_area_px: float | None = None
    visible_area_px: float | None = None
    in_view: bool | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class GroundTruth(_Record):
    """The ground truth of one image: the content of ``gt/NNNNNN.json`` (docs/formats.md).

    Attributes
    ----------
    count : int
        Obstacles whose footprint overlaps the frame.
    area : AreaRecord
        Obstacle areas in the frame.
    schema : str
        ``arenabench.gt/1``.
    id, image : str, optional
        Image id (``"000042"``) and path relative to the dataset (``images/000042.png``).
    preset, generator_version : str, optional
        Preset (or scene file) name and the generator version that wrote it.
    seed, index : int, optional
        Run seed and scene index.
    params : mapping, optional
        Sampled scalar parameters (dotted names).
    overrides : mapping, optional
        The run's ``--set`` values.
    image_size : (int, int), optional
        Width and height, px.
    scene : mapping, optional
        The scene description (:meth:`arenabench.generator.model.scene.Scene.to_dict`).
    components : int, optional
        Connected pieces of the union of visible silhouettes.
    frame : FrameRecord, optional
    homography : 3x3 tuple, optional
        Undistorted image px -> frame px.
    homography_domain : str, optional
        ``"undistorted"``.
    camera : CameraRecord, optional
    markers : tuple of MarkerRecord, optional
    obstacles : tuple of ObstacleRecord, optional
    extra : mapping
        Fields this version does not know, kept as read.
    """

    _NESTED: ClassVar[dict[str, type]] = {
        "area": AreaRecord, "frame": FrameRecord, "camera": CameraRecord,
    }
    _ITEMS: ClassVar[dict[str, type]] = {"markers": MarkerRecord, "obstacles": ObstacleRecord}

    count: int
    area: AreaRecord
    schema: str = GT_SCHEMA
    id: str | None = None
    image: str | None = None
    preset: str | None = None
    seed: int | None = None
    index: int | None = None
    generator_version: str | None = None
    params: Mapping[str, Any] | None = None
    overrides: Mapping[str, Any] | None = None
    image_size: tuple[int, ...] | None = None
    scene: Mapping[str, Any] | None = None
    components: int | None = None
    frame: FrameRecord | None = None
    homography: tuple[tuple[float, ...], ...] | None = None
    homography_domain: str | None = None
    camera: CameraRecord | None = None
    markers: tuple[MarkerRecord, ...] | None = None
    obstacles: tuple[ObstacleRecord, ...] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    def to_json(self) -> str:
        """The GT file's text: canonical JSON (:func:`arenabench.fileio.dumps_json`)."""
        return dumps_json(self.to_dict())
