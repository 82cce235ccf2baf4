"""arenabench.generator: scene model, sampling, off-screen rendering and analytic ground truth.

In-memory API (names are imported lazily)::

    from arenabench.generator import Renderer, make_sample, sample_scene, compute_ground_truth

    with Renderer() as r:
        s = make_sample("eyrc", seed=7, index=0, renderer=r, masks=True)
        s.rgb, s.gt, s.render.instance_mask

Files: :func:`generate_dataset` (``arenabench generate``).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Scene": "arenabench.generator.scene",
    "ArenaSpec": "arenabench.generator.scene",
    "MarkerSpec": "arenabench.generator.scene",
    "Obstacle": "arenabench.generator.scene",
    "CameraSpec": "arenabench.generator.scene",
    "LightingSpec": "arenabench.generator.scene",
    "DirectionalLight": "arenabench.generator.scene",
    "sample_scene": "arenabench.generator.sampler",
    "SamplingError": "arenabench.generator.sampler",
    "parse_overrides": "arenabench.generator.presets",
    "PRESETS": "arenabench.generator.presets",
    "Renderer": "arenabench.generator.render",
    "RenderOutput": "arenabench.generator.render",
    "compute_ground_truth": "arenabench.generator.groundtruth",
    "make_sample": "arenabench.generator.sample",
    "Sample": "arenabench.generator.sample",
    "generate_dataset": "arenabench.generator.dataset",
    "FloorPatch": "arenabench.generator.scene",
    "Degradations": "arenabench.generator.degrade",
    "apply_degradations": "arenabench.generator.degrade",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'arenabench.generator' has no attribute {name!r}")
