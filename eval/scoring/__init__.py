"""Scoring: what an answer scores, and what a set of scores says.

- ``results``: the typed records (a pipeline's :class:`Prediction`, an image's result, the
  summary, the report) and their JSON form;
- ``metrics``: the pass rule, the area error and the summary statistics;
- ``metric_registry``: every summary metric declared once (name, direction, format, range);
- ``thresholds`` and ``compare``: the ``--fail-under`` gates, and two reports side by side;
- ``breakdown`` and ``gt_facts``: pass rates by scene parameter, the ranked causes of failures,
  systematic errors;
- ``phase_check``: a failure re-run at sub-pixel phases (robust or phase-dependent).

Nothing here starts a process: a pipeline is run through :mod:`arenabench.eval.runs` (or in
process, :mod:`arenabench.eval.pipelines`), and the phase check takes the run as a callable.
"""
