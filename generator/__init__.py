"""arenabench.generator: scene model, sampling, off-screen rendering and analytic ground truth.

In-memory API (names are imported lazily)::

    from arenabench.generator import Renderer, make_sample, sample_scene, compute_ground_truth

    with Renderer() as r:
        s = make_sample("eyrc", seed=7, index=0, renderer=r, masks=True)
        s.rgb, s.gt, s.render.instance_mask

Files: :func:`generate_dataset` (``arenabench generate``).
"""

from __future__ import annotations

from arenabench.lazy import lazy_exports

_EXPORTS = {
    "Scene": "scene",
    "ArenaSpec": "scene",
    "MarkerSpec": "scene",
    "Obstacle": "scene",
    "CameraSpec": "scene",
    "LightingSpec": "scene",
    "DirectionalLight": "scene",
    "sample_scene": "sampler",
    "SamplingError": "sampler",
    "parse_overrides": "param_values",
    "PRESETS": "presets",
    "Renderer": "render",
    "NaiveRenderer": "render",
    "SceneRenderer": "renderer_api",
    "RenderOutput": "renderer_api",
    "compute_ground_truth": "groundtruth",
    "make_sample": "make",
    "Sample": "make",
    "generate_dataset": "dataset_writer",
    "FloorPatch": "scene",
    "Degradations": "degrade",
    "apply_degradations": "degrade",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
