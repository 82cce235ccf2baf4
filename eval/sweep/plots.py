"""Sweep plots (matplotlib, Agg, no pyplot state): per parameter the pass rate with 95 % Wilson
bands and the area error (median and p95 of ``|area_rel_err|``), one line per pipeline; a
pass-rate heat map per pipeline for the first two parameters."""

from __future__ import annotations

import io
import re
from typing import Any

import numpy as np

from arenabench.eval.scoring.results import ImageResult

from .breakdown import CurvePoint, axis_curve, heat_grid
from .grid import Axis
from .records import SweepResult

COLORS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3")


def _figure(size: tuple[float, float]) -> Any:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure(figsize=size)


def png_bytes(fig: Any) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return buf.getvalue()


def slug(text: str) -> str:
    """File-name-safe form of a parameter or pipeline name."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_")[:60] or "x"


def _by_pipeline(result: SweepResult) -> dict[str, dict[int, list[ImageResult]]]:
    out: dict[str, dict[int, list[ImageResult]]] = {p.name: {} for p in result.spec.pipelines}
    for row in result.images:
        out[row["pipeline"]].setdefault(row["point"], []).append(ImageResult.from_dict(row))
    return out


def curves(result: SweepResult) -> dict[str, dict[str, list[CurvePoint]]]:
    """``{parameter: {pipeline: curve}}`` with the sweep's pooling mode."""
    spec = result.spec
    by_pipe = _by_pipeline(result)
    return {
        axis.key: {
            name: axis_curve(axis, axes=spec.axes, points=result.points, results=res,
                             random=spec.random is not None, mode=spec.breakdown_mode)
            for name, res in by_pipe.items()
        }
        for axis in spec.axes
    }


def _x(axis: Axis, curve: list[CurvePoint]) -> tuple[np.ndarray, list[str] | None]:
    if axis.numeric:
        return np.array([float(c.value) for c in curve]), None
    return np.arange(len(curve), dtype=float), [c.label for c in curve]


def pass_rate_figure(axis: Axis, by_pipeline: dict[str, list[CurvePoint]], *,
                     threshold: float, breakdown: dict[str, Any]) -> Any:
    """Pass rate against one parameter, 95 % Wilson band per pipeline, threshold line and
    breakdown points marked."""
    fig = _figure((6.4, 3.8))
    ax = fig.add_subplot()
    ticks = None
    for k, (name, curve) in enumerate(by_pipeline.items()):
        x, ticks = _x(axis, curve)
        have = np.array([c.summary.n > 0 for c in curve])
        rate = np.array([c.summary.pass_rate for c in curve])
        lo = np.array([c.summary.pass_rate_ci95[0] for c in curve])
        hi = np.array([c.summary.pass_rate_ci95[1] for c in curve])
        color = COLORS[k % len(COLORS)]
        ax.plot(x[have], rate[have], "o-", color=color, label=name[:40])
        ax.fill_between(x[have], lo[have], hi[have], color=color, alpha=0.2, linewidth=0)
        bp = breakdown.get(name, {}).get(axis.key)
        if bp is not None:
            xb = float(bp) if axis.numeric else float([c.value for c in curve].index(bp))
            ax.axvline(xb, color=color, linestyle=":", linewidth=1.2)
    ax.axhline(threshold, color="#b00020", linestyle="--", linewidth=1,
               label=f"threshold {threshold:g}")
    if ticks is not None:
        ax.set_xticks(np.arange(len(ticks)), ticks)
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel(axis.key)
    ax.set_ylabel("pass rate (band: 95 % Wilson)")
    ax.set_title(f"Pass rate vs {axis.key} (dotted: breakdown point)", fontsize=10)
    ax.legend(fontsize=8, loc="lower left")
    return fig


def area_error_figure(axis: Axis, by_pipeline: dict[str, list[CurvePoint]], *,
                      tolerance: float) -> Any:
    """Median (solid) and p95 (dashed) of ``|area_rel_err|`` against one parameter."""
    fig = _figure((6.4, 3.8))
    ax = fig.add_subplot()
    ticks = None
    for k, (name, curve) in enumerate(by_pipeline.items()):
        x, ticks = _x(axis, curve)
        color = COLORS[k % len(COLORS)]
        for stat, style in (("median", "o-"), ("p95", "s--")):
            vals = [c.summary.area_rel_err.get(stat) for c in curve]
            have = np.array([v is not None for v in vals])
            y = np.array([max(v, 1e-4) if v is not None else np.nan for v in vals])
            if have.any():
                ax.plot(x[have], y[have], style, color=color, label=f"{name[:30]} {stat}")
    ax.axhline(tolerance, color="#b00020", linestyle="--", linewidth=1,
               label=f"tolerance {tolerance:g}")
    if ticks is not None:
        ax.set_xticks(np.arange(len(ticks)), ticks)
    ax.set_yscale("log")
    ax.set_xlabel(axis.key)
    ax.set_ylabel("|area relative error| (log; floor 1e-4)")
    ax.set_title(f"Area error vs {axis.key}", fontsize=10)
    ax.legend(fontsize=7)
    return fig


def heat_figure(result: SweepResult, pipeline: str,
                results: dict[int, list[ImageResult]]) -> Any:
    """Pass-rate heat map of one pipeline over the first two parameters."""
    spec = result.spec
    ax0, ax1 = spec.axes[0], spec.axes[1]
    from .breakdown import axis_groups

    random = spec.random is not None
    grid = heat_grid(ax0, ax1, points=result.points, results=results, random=random)
    fig = _figure((6.4, 4.8))
    ax = fig.add_subplot()
    im = ax.imshow(grid, cmap="RdYlGn", vmin=0.0, vmax=1.0, aspect="auto", origin="lower")
    for (i, j), v in np.ndenumerate(grid):
        if np.isfinite(v):
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7)
    ax.set_yticks(range(grid.shape[0]), [lab for _, lab in axis_groups(ax0, random=random)],
                  fontsize=7)
    ax.set_xticks(range(grid.shape[1]), [lab for _, lab in axis_groups(ax1, random=random)],
                  fontsize=7)
    ax.set_ylabel(ax0.key)
    ax.set_xlabel(ax1.key)
    ax.set_title(f"Pass rate, {pipeline[:40]}", fontsize=10)
    fig.colorbar(im, ax=ax, label="pass rate")
    return fig


def sweep_figures(result: SweepResult) -> list[tuple[str, str, bytes]]:
    """Every plot of a sweep: ``[(file name, title, png bytes), ...]``."""
    spec = result.spec
    out: list[tuple[str, str, bytes]] = []
    all_curves = curves(result)
    for axis in spec.axes:
        by_pipeline = all_curves[axis.key]
        fig = pass_rate_figure(axis, by_pipeline, threshold=spec.threshold,
                               breakdown=result.breakdown)
        out.append((f"pass_rate_{slug(axis.key)}.png", f"Pass rate vs {axis.key}",
                    png_bytes(fig)))
        fig = area_error_figure(axis, by_pipeline, tolerance=spec.tolerance)
        out.append((f"area_error_{slug(axis.key)}.png", f"Area error vs {axis.key}",
                    png_bytes(fig)))
    if len(spec.axes) >= 2:
        by_pipe = _by_pipeline(result)
        for k, (name, res) in enumerate(by_pipe.items()):
            fig = heat_figure(result, name, res)
            keys = f"{slug(spec.axes[0].key)}_{slug(spec.axes[1].key)}"
            out.append((
                f"heatmap_{keys}_{k}_{slug(name)}.png",
                f"Pass rate over {spec.axes[0].key} x {spec.axes[1].key}: {name}",
                png_bytes(fig),
            ))
    return out
