"""What varies between the target's scenes: the boxes, drawn around what the image shows.

One image shows one draw of the boxes, so their ranges are open by nature: the twin keeps a
range around each observed value and says how it was made. The rules are those the hand-built
``eyrc`` twin followed for the competition's example (docs/twin.md, "What varies"), written as
factors of what the image shows, so that on that example they give eyrc's ranges:

- **count**: 1 to twice the boxes seen (at least 1), and no more than the free floor holds
  (:data:`FLOOR_SHARE` of the markers' inner square, boxes with their gaps);
- **width, length, height**: the observed extremes times :data:`SIZE_FACTORS`, rounded
  to :data:`ROUND_M` (widths alike in the image stay alike; lengths and heights get
  room either way);
- **yaw**: when every box stands within :data:`AXIS_TOLERANCE_DEG` of the arena's axes, yaw
  0 or 90 (``obstacles.yaw_step_deg`` 90); otherwise any yaw;
- **grey**: the box tops' albedos seen (one value, or their range);
- **spacing**: boxes keep :data:`GAP_SHARE` of the mean width between them, and at most the
  smallest distance a seen box keeps to the markers' inner square (rounded down to
  :data:`ROUND_M`) from it, so that every box stays as far inside as the image's do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon, box

from arenabench.generator.model.layout import box_footprint
from arenabench.generator.model.scene import ArenaSpec, MarkerSpec, Obstacle
from arenabench.generator.parameters.params import Range, Value

#: (low, high) factors of the observed extremes, by size.
SIZE_FACTORS = {"width_m": (0.89, 1.07), "length_m": (0.71, 1.26), "height_m": (0.85, 1.47)}
#: Ranges are rounded to this (m), spacings rounded down.
ROUND_M = 0.01
#: Boxes within this angle of the arena's axes are axis-aligned.
AXIS_TOLERANCE_DEG = 1.0
#: Gap between boxes: this share of the mean box width (rounded down to 5 cm).
GAP_SHARE = 0.5
#: Share of the markers' inner square that boxes (with their gaps) may fill.
FLOOR_SHARE = 0.25


@dataclass(frozen=True)
class Varied:
    """A varied parameter: its value in the preset and how it was drawn from the image.

    Attributes
    ----------
    name : str
        Preset parameter.
    value : Range or value
        What the preset holds.
    seen : str
        What the image shows of it.
    rule : str
        How the range was made from that.
    """

    name: str
    value: Value
    seen: str
    rule: str


def _down(v: float, step: float = ROUND_M) -> float:
    return round(math.floor(v / step + 1e-9) * step, 6)


def _nearest(v: float, step: float = ROUND_M) -> float:
    return round(round(v / step) * step, 6)


def _axis_offset(yaw: float) -> float:
    return abs((yaw + 45.0) % 90.0 - 45.0)


def vary_boxes(obstacles: tuple[Obstacle, ...], arena: ArenaSpec, markers: MarkerSpec
               ) -> list[Varied]:
    """The ``obstacles.*`` parameters of the twin's preset (see the module docstring)."""
    out: list[Varied] = []
    n = len(obstacles)
    inner_half = arena.side_m / 2.0 - markers.side_m
    if n == 0:  # nothing to draw around: sizes as shares of the arena, everything open
        side = arena.side_m
        rule = "no box is seen: sizes as shares of the arena's side"
        out += [Varied("obstacles.count", Range(0, 2), "no box", "no box is seen: 0 to 2"),
                Varied("obstacles.length_m", Range(_nearest(0.1 * side), _nearest(0.25 * side)),
                       "no box", rule),
                Varied("obstacles.width_m", Range(_nearest(0.05 * side), _nearest(0.1 * side)),
                       "no box", rule),
                Varied("obstacles.height_m", Range(_nearest(0.04 * side), _nearest(0.1 * side)),
                       "no box", rule),
                Varied("obstacles.yaw_deg", Range(-45.0, 135.0), "no box", "yaw 0 or 90 deg"),
                Varied("obstacles.yaw_step_deg", 90.0, "no box", "axis-aligned"),
                Varied("obstacles.gray", Range(80, 160), "no box", "any mid grey"),
                Varied("obstacles.min_gap_m", _nearest(0.05 * side), "no box", rule),
                Varied("obstacles.edge_margin_m", _nearest(0.05 * side), "no box", rule)]
        return out
    sizes = {k: [getattr(o, k) for o in obstacles] for k in SIZE_FACTORS}
    ranges = {}
    for k, (lo_f, hi_f) in SIZE_FACTORS.items():
        lo, hi = _nearest(min(sizes[k]) * lo_f), _nearest(max(sizes[k]) * hi_f)
        ranges[k] = Range(max(lo, ROUND_M), max(hi, lo + ROUND_M))
        seen = ", ".join(f"{v:.3f}" for v in sizes[k])
        out.append(Varied(f"obstacles.{k}", ranges[k], f"{seen} m",
                          f"the extremes seen times {lo_f:g} and {hi_f:g}, rounded to "
                          f"{ROUND_M:g} m"))
    width = float(np.mean(sizes["width_m"]))
    gap = max(_down(GAP_SHARE * width, 0.05), 0.05)
    inner = box(-inner_half, -inner_half, inner_half, inner_half)
    margins = [inner.exterior.distance(Polygon(box_footprint(o))) if inner.contains(
        Polygon(box_footprint(o))) else 0.0 for o in obstacles]
    edge = _down(min(margins))
    mean_area = float(np.mean([(o.length_m + gap) * (o.width_m + gap) for o in obstacles]))
    free = (2.0 * (inner_half - edge)) ** 2
    capacity = max(int(FLOOR_SHARE * free / mean_area), 1)
    hi = max(min(2 * n, capacity), 1)
    out.insert(0, Varied("obstacles.count", Range(1, hi) if hi > 1 else 1, f"{n} boxes",
                         f"1 to twice the boxes seen, at most what {FLOOR_SHARE:.0%} of the "
                         f"free floor holds ({capacity})"))
    offsets = [_axis_offset(o.yaw_deg - 0.0) for o in obstacles]
    if max(offsets) <= AXIS_TOLERANCE_DEG:
        out.append(Varied("obstacles.yaw_deg", Range(-45.0, 135.0),
                          "every box along the arena's axes (within "
                          f"{max(offsets):.2f} deg)", "yaw 0 or 90 deg"))
        out.append(Varied("obstacles.yaw_step_deg", 90.0, "axis-aligned boxes",
                          "yaws rounded to multiples of 90 deg"))
    else:
        out.append(Varied("obstacles.yaw_deg", Range(-90.0, 90.0),
                          ", ".join(f"{o.yaw_deg:.1f}" for o in obstacles) + " deg",
                          "boxes turned off the arena's axes: any yaw"))
        out.append(Varied("obstacles.yaw_step_deg", 0.0, "turned boxes", "no rounding"))
    greys = sorted({o.color_rgb[0] for o in obstacles})
    out.append(Varied("obstacles.gray", greys[0] if len(greys) == 1
                      else Range(greys[0], greys[-1]),
                      ", ".join(map(str, greys)), "the box tops' albedos seen"))
    out.append(Varied("obstacles.min_gap_m", gap, f"mean width {width:.3f} m",
                      f"{GAP_SHARE:g} of the mean width, rounded down to 0.05 m"))
    out.append(Varied("obstacles.edge_margin_m", edge,
                      f"the boxes keep {min(margins):.3f} m or more from the markers' inner "
                      "square", f"the smallest, rounded down to {ROUND_M:g} m"))
    return out
