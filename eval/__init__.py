"""arenabench.eval: the harness. It runs pipelines on datasets, scores them, reports, sweeps
and grades. One room per job:

- ``evaluation``: the evaluation loop (:func:`evaluate`, :func:`score`);
- ``phase_check``: a failing image re-run across sub-pixel phases and the open parameters of
  its preset, and labelled (robust, phase-dependent, depends on open, unchecked);
- ``pipelines``: the pipeline interface and the in-process kinds (built-in, a callable);
- ``scoring/``: what an answer scores, and what a set of scores says (records, metrics, the
  metric registry, gates, comparisons, breakdowns and causes);
- ``runs/``: running a pipeline anywhere but in this process (external commands cold and warm,
  the sandbox, limits, run slots, interpreters, isolated callables, what an answer becomes);
- ``datasets/``: reading and checking a dataset (and results kept on disk for big sets);
- ``reports/``: the report files; ``sweep/``: robustness sweeps; ``grade/``: grading teams;
- ``commands/``: the command-line front ends (``arenabench eval``, ``check``, ``grade``...);
- ``bench/``: ``arenabench bench``'s measurements.

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
    "load_dataset": "datasets.reader",
    "Dataset": "datasets.reader",
    "DatasetError": "datasets.reader",
    "DatasetItem": "datasets.reader",
    "score_image": "scoring.metrics",
    "summarize": "scoring.metrics",
    "wilson_interval": "scoring.metrics",
    "Truth": "scoring.results",
    "Prediction": "scoring.results",
    "ImageScore": "scoring.results",
    "ImageResult": "scoring.results",
    "Summary": "scoring.results",
    "Report": "scoring.results",
    "BuiltinPipeline": "pipelines",
    "CallablePipeline": "pipelines",
    "CommandPipeline": "runs.command",
    "make_pipeline": "pipelines",
    "write_reports": "reports",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
