"""Residuals of pinned values: how much the render moves away from the real image when a value
moves a little (one grey level, one per cent of light), in the region that shows it."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from arenabench.generator.fitting.markers import MarkerFinding
from arenabench.generator.fitting.regions import region_masks
from arenabench.generator.fitting.shades import floor_square_mask
from arenabench.generator.model.layout import floor_extent
from arenabench.generator.model.scene import Scene


def _gray(renderer, scene: Scene) -> np.ndarray:
    return cv2.cvtColor(renderer.render(scene).rgb, cv2.COLOR_RGB2GRAY).astype(np.float64)


def pinned_residuals(scene: Scene, gray: np.ndarray, renderer, finding: MarkerFinding
                     ) -> dict[str, float]:
    """``{"arena.floor_rgb", "background.gray", "lighting"}`` -> growth of the mean absolute
    grey difference in the floor, background and faces regions when the floor grey, the
    background grey (one level lighter) or the light (ambient one per cent brighter) moves."""
    real = gray.astype(np.float64)
    masks = region_masks(scene, finding, gray.shape)
    background = ~floor_square_mask(scene.camera, gray.shape, floor_extent(scene.arena) + 0.02)
    base = _gray(renderer, scene)

    def growth(moved: Scene, mask: np.ndarray) -> float | None:
        if not mask.any():
            return None
        after = _gray(renderer, moved)
        return round(float(np.abs(after[mask] - real[mask]).mean()
                           - np.abs(base[mask] - real[mask]).mean()), 4)

    out: dict[str, float] = {}
    floor = tuple(min(c + 1, 255) for c in scene.arena.floor_rgb)
    value = growth(replace(scene, arena=replace(scene.arena, floor_rgb=floor)), masks["floor"])
    if value is not None:
        out["arena.floor_rgb"] = value
    bg = tuple(min(c + 1, 255) for c in scene.background_rgb)
    value = growth(replace(scene, background_rgb=bg), background)
    if value is not None:
        out["background.gray"] = value
    light = replace(scene.lighting, ambient=scene.lighting.ambient * 1.01)
    value = growth(replace(scene, lighting=light), masks["faces"])
    if value is not None:
        out["lighting"] = value
    return out
