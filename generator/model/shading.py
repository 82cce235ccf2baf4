"""Lambertian shading computed analytically and baked into colours (renders use flat mode)."""

from __future__ import annotations

import numpy as np

from arenabench.generator.model.scene import LightingSpec


def shade_factors(normals: np.ndarray, lighting: LightingSpec) -> np.ndarray:
    """Brightness factor of surfaces with world ``normals`` (N, 3): ambient + sum I max(0, n.l).

    ``l`` is the unit vector towards each light (minus its direction of travel). Factors are
    not clipped; colours are clipped to 0..255 when applied.
    """
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.full(n.shape[0], float(lighting.ambient))
    for light in lighting.directional:
        d = np.asarray(light.direction, dtype=np.float64)
        to_light = -d / np.linalg.norm(d)
        out += light.intensity * np.clip(n @ to_light, 0.0, None)
    return out


def floor_factor(lighting: LightingSpec) -> float:
    """Brightness factor of the floor (normal +z)."""
    return float(shade_factors(np.array([[0.0, 0.0, 1.0]]), lighting)[0])
