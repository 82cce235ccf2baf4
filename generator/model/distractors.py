"""Flat things on the floor that are not obstacles: tape lines, papers, marker occluders.

Tapes and papers lie inside the inner square (between the markers), so they never touch a
marker; they are drawn just above the floor and below the markers. An occluder is a flat patch
laid over part of one marker (drawn above it); the ground truth records, per marker, the
fraction of its square that patches hide.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import shapely
from shapely.geometry import Polygon, box

from arenabench.frame import CORNER_ORDER
from arenabench.generator.model.layout import box_footprint, marker_square
from arenabench.generator.model.scene import ArenaSpec, FloorPatch, MarkerSpec

#: Heights (m) of the patches: tapes/papers under the markers (MARKER_Z = 0.0005), occluders
#: over them.
PATCH_Z = {"tape": 0.0002, "paper": 0.0002, "occluder": 0.0009}

#: Tape sizes (m) and grey levels; paper sizes (m) from A4 to A2.
TAPE_LENGTH_M = (0.6, 2.5)
TAPE_WIDTH_M = (0.04, 0.06)
TAPE_GRAY = (25, 90)
PAPER_SIDES_M = ((0.21, 0.297), (0.297, 0.42), (0.42, 0.594))
PAPER_COLORS = ((250, 250, 250), (245, 240, 220), (255, 245, 150), (190, 220, 250))
#: Colour of the occluder patch (a dark sheet) and how far it sticks out past the marker.
OCCLUDER_RGB = (70, 70, 70)
OCCLUDER_OVERHANG_M = 0.05


def patch_corners(patch: FloorPatch) -> np.ndarray:
    """World (x, y) of a patch's corners, counter-clockwise from above, shape (4, 2)."""
    return box_footprint(patch)


def sample_patches(rng: np.random.Generator, *, tapes: int, papers: int, arena: ArenaSpec,
                   markers: MarkerSpec) -> tuple[FloorPatch, ...]:
    """Draw ``tapes`` tape lines and ``papers`` papers lying wholly inside the inner square.

    Each patch uses a fixed number of draws from ``rng`` (deterministic per scene).
    """
    inner = arena.side_m / 2.0 - markers.side_m
    region = box(-inner, -inner, inner, inner)
    out: list[FloorPatch] = []
    for kind, n in (("tape", tapes), ("paper", papers)):
        for _ in range(int(n)):
            u = rng.random(6)
            if kind == "tape":
                length = TAPE_LENGTH_M[0] + u[0] * (TAPE_LENGTH_M[1] - TAPE_LENGTH_M[0])
                width = TAPE_WIDTH_M[0] + u[1] * (TAPE_WIDTH_M[1] - TAPE_WIDTH_M[0])
                g = round(TAPE_GRAY[0] + u[2] * (TAPE_GRAY[1] - TAPE_GRAY[0]))
                color = (g, g, g)
            else:
                length, width = PAPER_SIDES_M[min(int(u[0] * len(PAPER_SIDES_M)), 2)]
                color = PAPER_COLORS[min(int(u[2] * len(PAPER_COLORS)),
                                         len(PAPER_COLORS) - 1)]
            yaw = -90.0 + 180.0 * u[3]
            reach = math.hypot(length, width) / 2.0
            span = max(inner - reach, 0.0)
            centre = (-span + 2 * span * u[4], -span + 2 * span * u[5])
            patch = FloorPatch(kind=kind, center_m=centre, yaw_deg=yaw, length_m=length,
                               width_m=width, color_rgb=color)
            if region.contains(Polygon(patch_corners(patch))):
                out.append(patch)
    return tuple(out)


def occluder_patch(arena: ArenaSpec, markers: MarkerSpec, *, marker: int,
                   fraction: float) -> FloorPatch | None:
    """A flat patch hiding ``fraction`` of marker ``marker`` (0 NW, 1 NE, 2 SE, 3 SW).

    The patch covers the marker from its outer (east or west) edge inwards and overhangs the
    marker's other three sides by :data:`OCCLUDER_OVERHANG_M`, so exactly ``fraction`` of the
    marker square is hidden. None when ``fraction`` is 0.
    """
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"markers.occlusion must be in [0, 1], got {fraction!r}")
    if marker not in range(4):
        raise ValueError(f"markers.occluded must be 0..3, got {marker!r}")
    if fraction <= 0:
        return None
    x0, x1, y0, y1 = marker_square(arena, markers, CORNER_ORDER[marker])
    cover = fraction * (x1 - x0)
    o = OCCLUDER_OVERHANG_M
    west = CORNER_ORDER[marker] in ("nw", "sw")
    xa, xb = (x0 - o, x0 + cover) if west else (x1 - cover, x1 + o)
    return FloorPatch(kind="occluder", center_m=((xa + xb) / 2.0, (y0 + y1) / 2.0), yaw_deg=0.0,
                      length_m=xb - xa, width_m=(y1 - y0) + 2 * o, color_rgb=OCCLUDER_RGB)


def occluded_fractions(arena: ArenaSpec, markers: MarkerSpec,
                       patches: tuple[FloorPatch, ...], *,
                       hidden: Sequence[Polygon] = ()) -> list[float]:
    """Fraction of each marker's square (NW, NE, SE, SW) hidden from the camera: by occluder
    patches and by ``hidden``, the floor regions each box hides (its vertices projected onto
    the floor from the camera:
    :func:`arenabench.generator.truth.groundtruth.visible_silhouette_world`).
    """
    occluders = [Polygon(patch_corners(p)) for p in patches if p.kind == "occluder"]
    occluders += [h for h in hidden if not h.is_empty]
    cover = shapely.union_all(occluders) if occluders else Polygon()
    out = []
    for corner in CORNER_ORDER:
        x0, x1, y0, y1 = marker_square(arena, markers, corner)
        sq = box(x0, y0, x1, y1)
        out.append(float(sq.intersection(cover).area / sq.area) if not cover.is_empty else 0.0)
    return out


def patch_mesh_arrays(patches: tuple[FloorPatch, ...], factor: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Positions (4N, 3), RGBA (4N, 4) and triangles (2N, 3) of flat patches lit by ``factor``.

    None when there are no patches.
    """
    if not patches:
        return None
    pos, rgba = [], []
    f = min(float(factor), 1.0)
    for p in patches:
        pos.append(np.column_stack([patch_corners(p), np.full(4, PATCH_Z[p.kind])]))
        c = np.clip(np.round(np.asarray(p.color_rgb, dtype=np.float64) * f), 0, 255) / 255.0
        rgba.append(np.tile([*c, 1.0], (4, 1)))
    tris = np.concatenate([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * k for k in range(len(patches))])
    return (np.concatenate(pos).astype(np.float32), np.concatenate(rgba).astype(np.float32),
            tris)
