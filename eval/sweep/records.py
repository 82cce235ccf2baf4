"""Typed records of a sweep: its settings, the work units sent to workers, and the result
(``sweep.json``, schema ``arenabench.sweep/1``)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

from arenabench.eval.datasets.reader import AREA_REFERENCES
from arenabench.eval.runs import OUTPUT_MODES, CommandPipeline, RunSettings
from arenabench.eval.scoring.metrics import DEFAULT_TOLERANCE
from arenabench.eval.scoring.results import Summary
from arenabench.generator.parameters.param_values import format_value
from arenabench.generator.parameters.params import Value
from arenabench.generator.parameters.presets import preset_name
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE
from arenabench.limits import MAX_SWEEP_SCENES, check_at_most
from arenabench.records import from_plain, to_plain
from arenabench.seeds import check_seed

from ..pipelines import Pipeline, make_pipeline, pipeline_name_problem
from .grid import Axis

SWEEP_SCHEMA = "arenabench.sweep/1"
#: Pipeline kinds: in-process (built-in name or ``pkg.module:function``) or external command.
PIPELINE_KINDS: tuple[str, ...] = ("pipeline", "cmd")
#: What happens to rendered images: nothing, all written, only those some pipeline failed.
KEEP_MODES: tuple[str, ...] = ("none", "all", "failures")
#: How breakdown points pool the other axes (see :mod:`arenabench.eval.sweep.breakdown`).
BREAKDOWN_MODES: tuple[str, ...] = ("marginal", "axis")
DEFAULT_THRESHOLD = 0.9


@dataclass(frozen=True)
class PipelineSpec:
    """A pipeline as a picklable description (each worker builds its own adapter from it).

    Parameters
    ----------
    kind : {"pipeline", "cmd"}
        ``pipeline``: ``reference``, ``seed`` or ``pkg.module:function``; ``cmd``: a command
        template for :class:`~arenabench.eval.pipelines.CommandPipeline`.
    value : str
        The name, spec or template.
    settings : RunSettings
        How a command runs: limits (``settings.limits.timeout_s`` per image), sandbox,
        image name, environment.
    output : {"obstacles", "json"}
        How a command answers.
    base_dir : str
        Folder relative paths in a command template refer to.
    """

    kind: str
    value: str
    settings: RunSettings = field(default_factory=RunSettings)
    output: str = "obstacles"
    base_dir: str = field(default_factory=os.getcwd)

    def __post_init__(self) -> None:
        if self.kind not in PIPELINE_KINDS:
            raise ValueError(f"kind must be one of {PIPELINE_KINDS}, got {self.kind!r}")
        if self.output not in OUTPUT_MODES:
            raise ValueError(f"output must be one of {OUTPUT_MODES}, got {self.output!r}")
        if not self.value:
            raise ValueError("pipeline value must not be empty")
        if self.kind == "pipeline" and (problem := pipeline_name_problem(self.value)):
            raise ValueError(problem)

    @property
    def name(self) -> str:
        """Name in reports: the built-in name, the callable spec or the command template."""
        return self.value

    @property
    def in_memory(self) -> bool:
        """Whether the pipeline takes the image from memory (no file is written for it)."""
        return self.kind == "pipeline"

    def build(self) -> Pipeline:
        """The adapter (:func:`~arenabench.eval.pipelines.make_pipeline` or a command)."""
        if self.kind == "cmd":
            return CommandPipeline(
                self.value, settings=self.settings, output=self.output, base_dir=self.base_dir
            )
        return make_pipeline(self.value)


@dataclass(frozen=True)
class SweepSpec:
    """Everything that defines a sweep's results.

    Parameters
    ----------
    preset : str or ResolvedPreset
        Scene preset: a built-in name or a preset file's
        :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`.
    axes : tuple of Axis
        Varied parameters (``--vary``).
    pipelines : tuple of PipelineSpec
        Pipelines run on every image (they share the images).
    per_point : int
        Scenes per point.
    seed : int
        Sweep seed: scene ``i`` of every point is scene ``i`` of ``seed`` (common random
        numbers), unless ``independent_scenes``.
    random : int or None
        Draw this many random points instead of the grid.
    overrides : dict
        Fixed ``--set`` values applied at every point (the varied keys win).
    tolerance : float
        Largest passing ``|area_rel_err|``.
    area_reference : {"visible", "footprint", "contour"}
        GT area scored against (:data:`arenabench.eval.datasets.reader.AREA_REFERENCES`).
    threshold : float
        Breakdown threshold on the pass rate's lower 95 % bound.
    breakdown_mode : {"marginal", "axis"}
        How the other axes are pooled for a parameter's breakdown point.
    keep : {"none", "all", "failures"}
        Which rendered images are written to disk.
    independent_scenes : bool
        Give every point its own scenes (indices ``p * per_point + i``) instead of the same.
    phases : int
        Phase check of every failing image (:mod:`arenabench.eval.phase_check`), in the
        worker that rendered it; 0 = off.
    """

    preset: Any
    axes: tuple[Axis, ...]
    pipelines: tuple[PipelineSpec, ...]
    per_point: int = 50
    seed: int = 0
    random: int | None = None
    overrides: dict[str, Value] = field(default_factory=dict)
    tolerance: float = DEFAULT_TOLERANCE
    area_reference: str = DEFAULT_AREA_REFERENCE
    threshold: float = DEFAULT_THRESHOLD
    breakdown_mode: str = "marginal"
    keep: str = "none"
    independent_scenes: bool = False
    phases: int = 0

    def __post_init__(self) -> None:
        if int(self.per_point) != self.per_point or self.per_point < 1:
            raise ValueError(f"per_point must be an integer >= 1, got {self.per_point!r}")
        check_seed(self.seed)
        if self.random is not None and (int(self.random) != self.random or self.random < 1):
            raise ValueError(f"random must be an integer >= 1, got {self.random!r}")
        check_at_most(int(self.per_point), MAX_SWEEP_SCENES, "per_point")
        if self.random is not None:
            check_at_most(int(self.random), MAX_SWEEP_SCENES, "random (points)")
        # counted, not listed: a grid of several long axes can have 10**12 points
        n_points = self.random if self.random is not None else math.prod(
            len(a.values) for a in self.axes
        )
        check_at_most(int(n_points) * int(self.per_point), MAX_SWEEP_SCENES,
                      f"scenes ({n_points} points x {self.per_point} per point)")
        if not self.pipelines:
            raise ValueError("pipelines must not be empty")
        names = [p.name for p in self.pipelines]
        if len(set(names)) != len(names):
            raise ValueError(f"pipelines must have distinct names, got {names!r}")
        if not self.tolerance >= 0:
            raise ValueError(f"tolerance must be >= 0, got {self.tolerance!r}")
        if self.area_reference not in AREA_REFERENCES:
            raise ValueError(f"area_reference must be one of {tuple(AREA_REFERENCES)}, "
                             f"got {self.area_reference!r}")
        if not 0 <= self.threshold <= 1:
            raise ValueError(f"threshold must be in [0, 1], got {self.threshold!r}")
        if self.breakdown_mode not in BREAKDOWN_MODES:
            raise ValueError(
                f"breakdown_mode must be one of {BREAKDOWN_MODES}, got {self.breakdown_mode!r}"
            )
        if self.breakdown_mode == "axis" and self.random is not None:
            raise ValueError("breakdown_mode 'axis' needs a grid sweep (random points never "
                             "hold the other axes at their first value)")
        if self.keep not in KEEP_MODES:
            raise ValueError(f"keep must be one of {KEEP_MODES}, got {self.keep!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON form of the settings (``sweep.json`` top level)."""
        return {
            "preset": preset_name(self.preset),
            **({} if isinstance(self.preset, str)  # a preset file: what it held
               else {"preset_definition": self.preset.document()}),
            "seed": int(self.seed),
            "per_point": int(self.per_point),
            "mode": "grid" if self.random is None else "random",
            "random": self.random,
            "vary": [a.to_dict() for a in self.axes],
            "set": {k: format_value(v) for k, v in sorted(self.overrides.items())},
            "pipelines": [
                {"name": p.name, "kind": p.kind,
                 **({"output": p.output, "run": p.settings.to_dict()}
                    if p.kind == "cmd" else {})}
                for p in self.pipelines
            ],
            "tolerance": self.tolerance,
            "area_reference": self.area_reference,
            "threshold": self.threshold,
            "breakdown_mode": self.breakdown_mode,
            "scenes": "independent" if self.independent_scenes else "common",
            "keep": self.keep,
            "phase_check": self.phases,
        }


@dataclass(frozen=True)
class SweepTask:
    """One work unit: scene ``index`` rendered at point ``point``, every pipeline run on it.

    Small and picklable (sent to local processes or Dask workers).
    """

    point: int
    scene: int
    index: int
    preset: Any
    seed: int
    overrides: dict[str, Value]
    pipelines: tuple[PipelineSpec, ...]
    tolerance: float
    area_reference: str
    keep: str
    phases: int = 0

    @property
    def key(self) -> tuple[int, int]:
        """Sort key: (point, scene)."""
        return self.point, self.scene


@dataclass(frozen=True)
class PointSummary:
    """One point of one pipeline (a ``sweep.json["points"]`` entry).

    Attributes
    ----------
    index : int
        Point number.
    params : dict
        The varied parameters' values.
    pipeline : str
        Pipeline name.
    summary : Summary
        The harness summary over the point's images.
    skipped : int
        Scenes that could not be generated at this point (e.g. markers never all in view).
    """

    index: int
    params: dict[str, Any]
    pipeline: str
    summary: Summary
    skipped: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON form: the fields, in order."""
        return to_plain(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PointSummary:
        """Inverse of :meth:`to_dict`."""
        return from_plain(cls, d, summary=Summary.from_dict(d["summary"]))


@dataclass(frozen=True)
class SweepResult:
    """A finished sweep.

    Attributes
    ----------
    spec : SweepSpec
    points : tuple of dict
        The points' parameter values, by point index.
    summaries : tuple of PointSummary
        One per point and pipeline (point-major, pipelines in the order given).
    images : tuple of dict
        Per-image rows (``results.jsonl``), sorted by (point, scene, pipeline order).
    breakdown : dict
        ``{pipeline: {parameter: value or None}}``.
    run : dict
        How it ran (executor, workers, seconds; ``complete``, ``samples_done``,
        ``points_done`` and, when stopped by a signal, ``interrupted``); not part of the
        results proper.
    """

    spec: SweepSpec
    points: tuple[dict[str, Any], ...]
    summaries: tuple[PointSummary, ...]
    images: tuple[dict[str, Any], ...]
    breakdown: dict[str, dict[str, Any]]
    run: dict[str, Any] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        """False when a stop signal ended the sweep early (``run`` says how far it got)."""
        return bool(self.run.get("complete", True))

    def to_dict(self) -> dict[str, Any]:
        """``sweep.json`` content (schema ``arenabench.sweep/1``)."""
        return {
            "schema": SWEEP_SCHEMA,
            **self.spec.to_dict(),
            "n_points": len(self.points),
            "complete": self.complete,
            "points": [s.to_dict() for s in self.summaries],
            "breakdown": self.breakdown,
            "run": dict(self.run),
        }
