"""Typed results of :func:`arenabench.pipeline.detect`, serialisable to JSON."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Literal

from arenabench.fileio import json_safe

Status = Literal["ok", "markers_not_found"]

#: Version tag written into :meth:`Detection.to_dict`.
DETECTION_SCHEMA = "arenabench.detection/1"


def _points(a: Any) -> list[list[float]]:
    return [[float(x), float(y)] for x, y in a]


@dataclass(frozen=True)
class Obstacle:
    """One counted obstacle.

    Parameters
    ----------
    contour : list of [x, y]
        External contour in frame px.
    area : float
        ``cv2.contourArea`` of the contour (frame px^2; the competition's convention).
    pixel_area : int
        Number of frame pixels inside the contour.
    """

    contour: list[list[float]]
    area: float
    pixel_area: int

    def to_dict(self, *, contour: bool = True) -> dict[str, Any]:
        """JSON-safe form (without the ``contour`` points when ``contour`` is False)."""
        out: dict[str, Any] = {"area": float(self.area), "pixel_area": int(self.pixel_area)}
        if contour:
            out["contour"] = _points(self.contour)
        return out


@dataclass(frozen=True)
class Detection:
    """Everything :func:`~arenabench.pipeline.detect` found in one image.

    Parameters
    ----------
    status : {"ok", "markers_not_found"}
        ``markers_not_found`` when four usable markers were not found (``message`` says why);
        then ``count`` is 0, ``total_area`` 0.0 and ``marker_ids`` lists what was found.
    profile : str
        ``reference`` or ``seed``.
    dictionary : str or None
        Dictionary of the markers (e.g. ``"DICT_4X4_100"``).
    marker_ids : list of int
        Sorted ids.
    marker_corners : dict of int to list of [x, y]
        Per id, the four corners in the *input* image's px, in cv2.aruco order.
    reference_corners : list of [x, y]
        The corners mapped to the frame's NW, NE, SE, SW corners (input px); empty when none.
    reference_ids : list of int
        The marker id at NW, NE, SE, SW.
    homography : list of 3 lists of 3 floats, or None
        Input image px -> frame px (the resize is composed in).
    frame : dict
        ``{"size": [S, S], "corners": "inner" | "outer"}``.
    count : int
        Obstacles (contours larger than ``min_area``).
    total_area : float
        Total obstacle area in frame px^2 (see :class:`~arenabench.pipeline.DetectConfig`).
    obstacles : list of Obstacle
        The counted obstacles.
    image_size : [width, height]
        Input image size.
    timings_ms : dict of str to float
        Wall time per stage.
    details : dict
        Method-specific values (marker search source and passes, floor colour, threshold).
    message : str
        Human-readable note (why markers were not found).
    """

    status: Status
    profile: str
    dictionary: str | None
    marker_ids: list[int]
    marker_corners: dict[int, list[list[float]]]
    reference_corners: list[list[float]]
    reference_ids: list[int]
    homography: list[list[float]] | None
    frame: dict[str, Any]
    count: int
    total_area: float
    obstacles: list[Obstacle]
    image_size: list[int]
    timings_ms: dict[str, float] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)
    message: str = ""

    @property
    def ok(self) -> bool:
        """True when the status is ``ok``."""
        return self.status == "ok"

    @property
    def area(self) -> float:
        """Alias of ``total_area`` (the harness reads either)."""
        return self.total_area

    def to_dict(self, *, contours: bool = True) -> dict[str, Any]:
        """JSON-safe dict (marker ids as string keys in ``marker_corners``).

        Parameters
        ----------
        contours : bool, keyword-only
            Include each obstacle's contour points (the bulk of the output).
        """
        return {
            "schema": DETECTION_SCHEMA,
            "status": self.status,
            "profile": self.profile,
            "dictionary": self.dictionary,
            "marker_ids": [int(i) for i in self.marker_ids],
            "marker_corners": {str(int(k)): _points(v) for k, v in self.marker_corners.items()},
            "reference_corners": _points(self.reference_corners),
            "reference_ids": [int(i) for i in self.reference_ids],
            "homography": None if self.homography is None
            else [[float(v) for v in row] for row in self.homography],
            "frame": dict(self.frame),
            "count": int(self.count),
            "total_area": float(self.total_area),
            "obstacles": [o.to_dict(contour=contours) for o in self.obstacles],
            "image_size": [int(v) for v in self.image_size],
            "timings_ms": {k: float(v) for k, v in self.timings_ms.items()},
            "details": dict(self.details),
            "message": self.message,
        }

    def to_json(self, *, indent: int | None = 2, contours: bool = True) -> str:
        """JSON text of :meth:`to_dict` (sorted keys; an undefined number is ``null``; one
        line when ``indent`` is None)."""
        separators = (",", ":") if indent is None else None
        return json.dumps(json_safe(self.to_dict(contours=contours)), indent=indent,
                          sort_keys=True, allow_nan=False, separators=separators)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Detection:
        """Rebuild a Detection from :meth:`to_dict` output."""
        return cls(
            status=data["status"],
            profile=data["profile"],
            dictionary=data["dictionary"],
            marker_ids=[int(i) for i in data["marker_ids"]],
            marker_corners={int(k): _points(v) for k, v in data["marker_corners"].items()},
            reference_corners=_points(data["reference_corners"]),
            reference_ids=[int(i) for i in data["reference_ids"]],
            homography=data["homography"],
            frame=dict(data["frame"]),
            count=int(data["count"]),
            total_area=float(data["total_area"]),
            obstacles=[
                Obstacle(contour=_points(o.get("contour", [])), area=float(o["area"]),
                         pixel_area=int(o["pixel_area"]))
                for o in data["obstacles"]
            ],
            image_size=[int(v) for v in data["image_size"]],
            timings_ms={k: float(v) for k, v in data.get("timings_ms", {}).items()},
            details=dict(data.get("details", {})),
            message=data.get("message", ""),
        )
