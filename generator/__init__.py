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
    "Scene": "model.scene",
    "ArenaSpec": "model.scene",
    "MarkerSpec": "model.scene",
    "Obstacle": "model.scene",
    "CameraSpec": "model.scene",
    "LightingSpec": "model.scene",
    "DirectionalLight": "model.scene",
    "sample_scene": "model.sampler",
    "SamplingError": "model.sampler",
    "parse_overrides": "parameters.param_values",
    "PRESETS": "parameters.presets",
    "Renderer": "rendering.render",
    "NaiveRenderer": "rendering.render",
    "SceneRenderer": "rendering.renderer_api",
    "RenderOutput": "rendering.renderer_api",
    "compute_ground_truth": "truth.groundtruth",
    "make_sample": "dataset.make",
    "Sample": "dataset.make",
    "generate_dataset": "dataset.dataset_writer",
    "FloorPatch": "model.scene",
    "Degradations": "rendering.degrade",
    "apply_degradations": "rendering.degrade",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
