"""What an open light allows: the lights that give every face the image shows, and among them
those that make each face direction it does not show darkest and lightest.

The twin's light (:func:`arenabench.generator.fitting.scene_fit.fit_lighting`) is an ambient term
and one
directional light, normalised so that the floor and the box tops have factor 1 (the floor's and
the tops' greys are their albedos). With fewer than two side-face directions seen, many lights
give the faces seen: every (elevation, azimuth) with the intensity solved for them (the ambient
follows from the floor's factor), within :data:`FACE_TOLERANCE` of the best fit. They differ only
in the shades of the faces the image does not show, which are what the phase check must try.
So the light's variants are, for each unseen direction, the light of the span that makes that
face darkest and the one that makes it lightest: each a whole light (ambient, intensity,
elevation and azimuth together), keeping every pixel the image shows. Varied one parameter at a
time instead, the ambient or the intensity alone would change the floor's grey, an image the
example rules out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from arenabench.generator.fitting.scene_fit import BoxObservation

#: Compass directions of unseen faces and their normals (azimuth CCW from east, deg).
NORMAL_AZIMUTH_DEG = {"east": 0.0, "north": 90.0, "west": 180.0, "south": 270.0}
#: The grid of lights tried (deg): elevations, azimuths (as ``fit_lighting``'s).
ELEVATIONS_DEG = np.arange(5.0, 90.0, 1.0)
AZIMUTHS_DEG = np.arange(0.0, 360.0, 2.0)
#: The largest intensity (the parameter's bound) and the smallest ambient.
MAX_INTENSITY = 2.0
#: A light gives the faces seen when their shades are within this many grey levels (RMS) of
#: the best light's: about JPEG's and an 8-bit mode's rounding (the blind round trips' grey
#: tolerance is 2).
FACE_TOLERANCE = 1.0


@dataclass(frozen=True)
class Light:
    """One light of the span, as the preset's parameters hold it."""

    ambient: float
    intensity: float
    elevation_deg: float
    azimuth_deg: float

    def params(self) -> dict[str, float]:
        """``lighting.*`` parameter -> value."""
        return {"lighting.ambient": self.ambient, "lighting.intensity": self.intensity,
                "lighting.elevation_deg": self.elevation_deg,
                "lighting.azimuth_deg": self.azimuth_deg}


@dataclass(frozen=True)
class Extreme:
    """The light of the span that makes the faces of ``direction`` darkest or lightest."""

    direction: str
    end: str  # "darkest" or "lightest"
    ratio: float  # that face's factor relative to a top face's
    light: Light


def light_extremes(boxes: Sequence[BoxObservation], unseen: Sequence[str], *,
                   floor: float = 1.0) -> list[Extreme]:
    """For each direction of ``unseen``, the lights of the span (module docstring) that make
    its faces darkest and lightest.

    Parameters
    ----------
    boxes : sequence of BoxObservation
        The boxes with their top grey and the side faces seen (normal, grey).
    unseen : sequence of str
        Compass directions (:data:`NORMAL_AZIMUTH_DEG`) no box shows.
    floor : float, keyword-only
        The floor's factor of the twin's light (:func:`~arenabench.generator.model.shading.
        floor_factor`; 1 unless the light was dimmed to the marker sheets' white): every
        light of the span is scaled to it, ambient and intensity alike.

    Returns
    -------
    list of Extreme
        Two per direction (darkest, then lightest), in the order of ``unseen``.
    """
    obs = [(np.asarray(n, float), g, b.top_gray) for b in boxes for n, g in b.side_faces]
    el = np.radians(ELEVATIONS_DEG)[:, None]
    az = np.radians(AZIMUTHS_DEG)[None, :]
    to_light = np.stack(np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                            np.sin(el) + 0.0 * az), axis=-1)  # (E, A, 3)
    sin_el = np.broadcast_to(np.sin(el), to_light.shape[:2])
    cap = np.minimum(MAX_INTENSITY / floor, 1.0 / sin_el)  # the ambient >= 0
    if obs:
        normals = np.array([n for n, _, _ in obs])
        tops = np.array([max(t, 1.0) for _, _, t in obs])
        ratios = np.array([g for _, g, _ in obs]) / tops
        x = np.clip(to_light @ normals.T, 0.0, None) - sin_el[..., None]  # (E, A, F)
        inten = np.clip((x @ (ratios - 1.0)) / np.maximum((x * x).sum(-1), 1e-12), 0.0, cap)
        error = (1.0 + inten[..., None] * x - ratios) * tops  # grey levels
        rms = np.sqrt((error ** 2).mean(-1))
        ok = rms <= rms.min() + FACE_TOLERANCE
        intensities = [inten]
    else:  # nothing seen: any light, from none to the strongest
        ok = np.ones(sin_el.shape, bool)
        intensities = [np.zeros(sin_el.shape), cap]
    out = []
    for direction in unseen:
        a = math.radians(NORMAL_AZIMUTH_DEG[direction])
        normal = np.array([math.cos(a), math.sin(a), 0.0])
        lam = np.clip(to_light @ normal, 0.0, None) - sin_el
        for end, pick in (("darkest", np.argmin), ("lightest", np.argmax)):
            best = None
            for inten in intensities:
                ratio = np.where(ok, 1.0 + inten * lam, np.nan)
                k = np.unravel_index(int(pick(np.where(np.isnan(ratio), np.inf if
                                                       end == "darkest" else -np.inf,
                                                       ratio))), ratio.shape)
                cand = (float(ratio[k]), k, float(inten[k]))
                if best is None or (cand[0] < best[0] if end == "darkest" else
                                    cand[0] > best[0]):
                    best = cand
            assert best is not None
            ratio, (i, j), inten = best
            e = float(ELEVATIONS_DEG[i])
            light = Light(ambient=round(floor * (1.0 - inten * math.sin(math.radians(e))), 6),
                          intensity=round(floor * inten, 6), elevation_deg=e,
                          azimuth_deg=float(AZIMUTHS_DEG[j]) - 360.0 * (AZIMUTHS_DEG[j] > 180))
            out.append(Extreme(direction, end, round(ratio, 4), light))
    return out
