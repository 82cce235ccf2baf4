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
    "score": "evaluation",
    "evaluate": "evaluation",
    "build_report": "evaluation",
    "load_dataset": "dataset_reader",
    "Dataset": "dataset_reader",
    "DatasetError": "dataset_reader",
    "DatasetItem": "dataset_reader",
    "score_image": "metrics",
    "summarize": "metrics",
    "wilson_interval": "metrics",
    "Truth": "results",
    "Prediction": "results",
    "ImageScore": "results",
    "ImageResult": "results",
    "Summary": "results",
    "Report": "results",
    "BuiltinPipeline": "pipelines",
    "CallablePipeline": "pipelines",
    "CommandPipeline": "external",
    "make_pipeline": "pipelines",
    "write_reports": "reports",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
