"""Sweep output files, all written atomically into ``DIR``::

    sweep.json      settings, per point x pipeline harness summaries, breakdown points
                    (schema arenabench.sweep/1)
    sweep.csv       one row per point x pipeline: parameters and summary metrics
    results.jsonl   one line per image x pipeline (the harness's per-image record plus
                    pipeline, point, scene, index)
    plots/*.png     pass rate and area error per parameter; heat maps for two parameters
    sweep.html      the page tying them together (plots inline)
    images/, gt/    kept images and their GT (--keep-images / --keep-failures only)
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from arenabench.eval.scoring.metric_registry import METRICS, Metric, column_metrics
from arenabench.fileio import (
    atomic_write_bytes,
    atomic_write_text,
    dumps_json,
    dumps_json_line,
)
from arenabench.generator.parameters.param_values import format_value

from .html import sweep_page
from .plots import sweep_figures
from .records import SweepResult
from .task import image_name

FILES: dict[str, str] = {
    "json": "sweep.json",
    "csv": "sweep.csv",
    "jsonl": "results.jsonl",
    "html": "sweep.html",
}


def _cell(value: Any) -> Any:
    return "" if value is None else value


def sweep_csv(result: SweepResult, *, metrics: Sequence[Metric] = METRICS) -> str:
    """``sweep.csv`` text: one row per point and pipeline.

    Parameters
    ----------
    result : SweepResult
    metrics : sequence of Metric, keyword-only
        The registry whose :func:`~arenabench.eval.scoring.metric_registry.column_metrics`
        are the metric columns (after ``point``, the varied parameters, ``pipeline``, ``n``,
        ``n_passed`` and ``skipped``).
    """
    keys = [a.key for a in result.spec.axes]
    columns = column_metrics(metrics)
    header = ["point", *keys, "pipeline", "n", "n_passed", "skipped", *(m.key for m in columns)]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for ps in result.summaries:
        s = ps.summary
        d = s.to_dict()
        row = [ps.index, *(format_value(ps.params[k]) for k in keys), ps.pipeline, s.n,
               s.n_passed, ps.skipped, *(_metric_cell(m, d) for m in columns)]
        writer.writerow([_cell(v) for v in row])
    return buf.getvalue()


def _metric_cell(m: Metric, summary: dict[str, Any]) -> Any:
    """``m``'s value in ``summary``; a failure category no image fell into counts 0."""
    value = m.value(summary)
    return 0 if value is None and m.group == "failures" else value


def results_jsonl(result: SweepResult) -> str:
    """``results.jsonl`` text (sorted by point, scene, pipeline order)."""
    return "".join(dumps_json_line(row) for row in result.images)


class KeptImageWriter:
    """Writes the images (PNG) and GT of kept samples as their results arrive.

    Use as ``run_sweep(..., on_output=KeptImageWriter(out_dir))``; does nothing for samples
    whose result carries no image.
    """

    def __init__(self, out_dir: str | os.PathLike[str]) -> None:
        self.out = Path(out_dir)
        self.written = 0

    def __call__(self, output: dict[str, Any]) -> None:
        """Write one task's kept image and GT, if any."""
        if output.get("image") is None:
            return
        name = image_name(output["point"], output["scene"])
        atomic_write_bytes(self.out / "images" / f"{name}.{output['image_ext']}",
                           output["image"])
        atomic_write_text(self.out / "gt" / f"{name}.json", dumps_json(output["gt"]))
        self.written += 1


def write_sweep(
    result: SweepResult, out_dir: str | os.PathLike[str], *, plots: bool = True
) -> dict[str, Path]:
    """Write ``sweep.json``, ``sweep.csv``, ``results.jsonl``, ``plots/*.png`` and
    ``sweep.html`` into ``out_dir`` (created).

    Parameters
    ----------
    result : SweepResult
    out_dir : path-like
    plots : bool, keyword-only
        Also draw the plots and the HTML page.

    Returns
    -------
    dict
        ``{"json", "csv", "jsonl", "html", "plot:<file>"...: path}``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _export_textures(result, out)
    written = {
        "json": atomic_write_text(out / FILES["json"], dumps_json(result.to_dict())),
        "csv": atomic_write_text(out / FILES["csv"], sweep_csv(result)),
        "jsonl": atomic_write_text(out / FILES["jsonl"], results_jsonl(result)),
    }
    if plots:
        figures = sweep_figures(result)
        for name, _, png in figures:
            written[f"plot:{name}"] = atomic_write_bytes(out / "plots" / name, png)
        written["html"] = atomic_write_text(out / FILES["html"], sweep_page(result, figures))
    return written


def _export_textures(result: SweepResult, out: Path) -> None:
    """Copy the preset's texture images (``arena.texture_file``) into ``out/textures``: the
    sweep's ``preset_definition`` names them there, as a set's does."""
    from arenabench.generator.assets import texture_store
    from arenabench.generator.parameters.preset_files import texture_refs
    from arenabench.generator.parameters.presets import resolve

    spec = result.spec
    if isinstance(spec.preset, str):
        return
    for ref in sorted({*texture_refs(spec.preset.params),
                       *texture_refs(resolve(spec.preset, spec.overrides))}):
        texture_store.export_texture(ref, out)


def load_sweep(out_dir: str | os.PathLike[str]) -> SweepResult:
    """Read a sweep back from ``sweep.json`` and ``results.jsonl`` (e.g. to re-plot it).

    Raises
    ------
    ValueError
        When ``sweep.json`` is not of schema ``arenabench.sweep/1``.
    """
    from arenabench.eval.runs import RunSettings
    from arenabench.generator.parameters.param_values import parse_overrides

    from .grid import parse_vary
    from .records import SWEEP_SCHEMA, PipelineSpec, PointSummary, SweepSpec

    out = Path(out_dir)
    doc = json.loads((out / FILES["json"]).read_text(encoding="utf-8"))
    if doc.get("schema") != SWEEP_SCHEMA:
        raise ValueError(f"{out / FILES['json']}: schema must be {SWEEP_SCHEMA!r}, "
                         f"got {doc.get('schema')!r}")
    preset: Any = doc["preset"]
    if isinstance(doc.get("preset_definition"), dict):  # the preset, as it was
        from arenabench.generator.parameters.preset_files import preset_from_document

        preset = preset_from_document(doc["preset_definition"], base=out,
                                      where=f"{out / FILES['json']} preset_definition")
    spec = SweepSpec(
        preset=preset,
        axes=tuple(parse_vary(f"{a['key']}={a['spec']}") for a in doc["vary"]),
        pipelines=tuple(
            PipelineSpec("cmd" if p["kind"] == "cmd" else "pipeline", p["name"],
                         settings=RunSettings.from_dict(
                             p.get("run") or {"timeout_s": p.get("timeout_s", 60.0)}),
                         output=p.get("output", "obstacles"))
            for p in doc["pipelines"]
        ),
        per_point=doc["per_point"], seed=doc["seed"], random=doc.get("random"),
        overrides=parse_overrides([f"{k}={v}" for k, v in doc.get("set", {}).items()]),
        tolerance=doc["tolerance"], area_reference=doc["area_reference"],
        threshold=doc["threshold"], breakdown_mode=doc["breakdown_mode"], keep=doc["keep"],
        independent_scenes=doc.get("scenes") == "independent",
        phases=int(doc.get("phase_check", 0)),
    )
    summaries = tuple(PointSummary.from_dict(p) for p in doc["points"])
    points: dict[int, dict[str, Any]] = {s.index: s.params for s in summaries}
    lines = (out / FILES["jsonl"]).read_text(encoding="utf-8").splitlines()
    return SweepResult(
        spec=spec, points=tuple(points[i] for i in range(doc["n_points"])),
        summaries=summaries, images=tuple(json.loads(line) for line in lines if line.strip()),
        breakdown=doc["breakdown"], run=doc.get("run", {}),
    )
