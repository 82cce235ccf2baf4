"""Scoring: what an answer scores, and what a set of scores says.

- ``results``: the typed records (a pipeline's :class:`Prediction`, an image's result, the
  summary, the report) and their JSON form;
- ``metrics``: the pass rule, the area error and the summary statistics;
- ``metric_registry``: every summary metric declared once (name, direction, format, range);
- ``thresholds`` and ``compare``: the ``--fail-under`` gates, and two reports side by side;
- ``breakdown`` and ``gt_facts``: pass rates by scene parameter, the ranked causes of failures,
  systematic errors.

Nothing here runs a pipeline or starts a process: that is :mod:`arenabench.eval.runs` (or in
process, :mod:`arenabench.eval.pipelines`); re-running a failure across sub-pixel phases and
open parameters is :mod:`arenabench.eval.phase_check`, a room above.
"""
