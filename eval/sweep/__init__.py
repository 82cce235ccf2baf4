"""Robustness sweeps: vary preset parameters over a grid (or at random), render and score every
point in memory with one or more pipelines, find each parameter's breakdown point.

::

    from arenabench.eval.sweep import PipelineSpec, SweepSpec, parse_vary, run_sweep, write_sweep

    spec = SweepSpec(preset="eyrc", axes=(parse_vary("camera.tilt_deg=0:40:20"),),
                     pipelines=(PipelineSpec("pipeline", "reference"),), per_point=20)
    result = run_sweep(spec, workers=2)          # or scheduler="tcp://host:8786"
    write_sweep(result, "out/sweep")             # sweep.json/.csv, results.jsonl, plots, html
"""

from __future__ import annotations

from arenabench.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "Axis": "grid",
    "parse_vary": "grid",
    "parse_varies": "grid",
    "grid_points": "grid",
    "random_points": "grid",
    "PipelineSpec": "records",
    "SweepSpec": "records",
    "SweepTask": "records",
    "SweepResult": "records",
    "PointSummary": "records",
    "SWEEP_SCHEMA": "records",
    "run_sweep": "execution",
    "execute": "execution",
    "sweep_points": "execution",
    "sweep_tasks": "execution",
    "run_task": "task",
    "axis_curve": "breakdown",
    "breakdown_value": "breakdown",
    "write_sweep": "outputs",
    "load_sweep": "outputs",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
