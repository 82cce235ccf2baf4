"""arenabench.eval: pipeline adapters, metrics, reports and robustness sweeps.

Public API (imported lazily, so ``import arenabench.eval`` - and the pytest plugin - stay
cheap)::

    from arenabench.eval import score, evaluate, load_dataset
    summary = score("reference", "datasets/eyrc")      # -> Summary
    report = evaluate(my_function, "datasets/eyrc", workers=4)  # -> Report
"""

from __future__ import annotations

from arenabench.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "score": "runner",
    "evaluate": "runner",
    "build_report": "runner",
    "load_dataset": "dataset",
    "Dataset": "dataset",
    "DatasetError": "dataset",
    "DatasetItem": "dataset",
    "score_image": "metrics",
    "summarize": "metrics",
    "wilson_interval": "metrics",
    "Truth": "records",
    "Prediction": "records",
    "ImageScore": "records",
    "ImageResult": "records",
    "Summary": "records",
    "Report": "records",
    "BuiltinPipeline": "pipelines",
    "CallablePipeline": "pipelines",
    "CommandPipeline": "pipelines",
    "make_pipeline": "pipelines",
    "write_reports": "reports",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
