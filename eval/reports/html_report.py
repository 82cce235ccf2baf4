"""``report.html``: one self-contained page (no external resources, no scripts): summary,
plots of area error and count confusion, pass rate by scene parameter, and the worst cases as
thumbnails with the ground-truth polygons drawn and the pipeline's numbers beside them."""

from __future__ import annotations

import base64
import html
import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from arenabench.fileio import atomic_write_text

from ..breakdown import importance
from ..dataset import Dataset, DatasetError, load_dataset
from ..records import ImageResult, Report
from .summary_rows import fmt, summary_rows

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;
text-align:left;font-size:.9em}th{background:#f3f3f3}.pass{color:#176d2c}.fail{color:#b00020}
.plots img{max-width:48%;margin:4px;border:1px solid #ddd}.plots img.wide{max-width:98%}
.cases{display:flex;flex-wrap:wrap;gap:12px}.case{border:1px solid #ccc;padding:6px;
width:380px;font-size:.85em}.case img{width:100%}pre{white-space:pre-wrap;max-height:10em;
overflow:auto;background:#f7f7f7;padding:4px;font-size:.8em}.bar{background:#b00020;height:8px}
"""


def _png_data_uri(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _figures(report: Report) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    out: list[tuple[str, str]] = []
    rels = [
        r.score.area_rel_err
        for r in report.images
        if r.score.area_rel_err is not None and r.score.area_err_kind == "relative"
    ]
    fig = Figure(figsize=(6, 3.6))
    ax = fig.add_subplot()
    if rels:
        ax.hist(np.clip(rels, -1.0, 1.0), bins=min(40, max(5, len(rels))), color="#4c72b0")
    for x in (-report.tolerance, report.tolerance):
        ax.axvline(x, color="#b00020", linestyle="--", linewidth=1)
    ax.set_xlabel("signed area relative error (clipped to [-1, 1])")
    ax.set_ylabel("images")
    ax.set_title("Area error (dashed: tolerance)")
    out.append(("Area error histogram", _png_data_uri(fig)))

    gts = [r.truth.count for r in report.images]
    preds = [r.prediction.count for r in report.images]
    hi = max([*gts, *[p for p in preds if p is not None], 0])
    size = hi + 2  # counts 0..hi plus a "none" column
    mat = np.zeros((hi + 1, size), dtype=np.int64)
    for g, p in zip(gts, preds, strict=True):
        mat[g, size - 1 if p is None else p] += 1
    fig = Figure(figsize=(6, 4.2))
    ax = fig.add_subplot()
    ax.imshow(mat, cmap="Blues", aspect="auto")
    for (i, j), v in np.ndenumerate(mat):
        if v:
            ax.text(
                j,
                i,
                str(v),
                ha="center",
                va="center",
                color="white" if v > mat.max() / 2 else "black",
                fontsize=8,
            )
    ax.set_xticks(range(size), [*map(str, range(hi + 1)), "none"])
    ax.set_yticks(range(hi + 1), [str(i) for i in range(hi + 1)])
    ax.set_xlabel("predicted count")
    ax.set_ylabel("ground-truth count")
    ax.set_title("Count confusion")
    out.append(("Count confusion", _png_data_uri(fig)))

    keys = sorted(report.breakdown, key=lambda k: importance(report.breakdown[k]), reverse=True)[:4]
    if keys:
        fig = Figure(figsize=(12, 2.8 * ((len(keys) + 1) // 2)))
        for i, key in enumerate(keys):
            ax = fig.add_subplot((len(keys) + 1) // 2, 2, i + 1)
            rows = report.breakdown[key]
            rates = np.array([r["pass_rate"] or 0.0 for r in rows])
            x = np.arange(len(rows))
            ax.bar(x, rates, color="#55a868", label="pass")
            ax.bar(x, 1.0 - rates, bottom=rates, color="#c44e52", label="fail")
            for xi, row in zip(x, rows, strict=True):
                ax.text(xi, 0.5, f"n={row['n']}", ha="center", va="center", fontsize=7)
            ax.set_xticks(x, [r["bin"] for r in rows], fontsize=7)
            ax.set_ylim(0, 1.0)
            ax.set_title(f"pass (green) / fail (red) rate by {key}", fontsize=9)
        fig.tight_layout()
        out.append(("Pass rate by scene parameter", _png_data_uri(fig)))
    return out


def worst_cases(images: Sequence[ImageResult], *, limit: int = 12) -> list[ImageResult]:
    """Failing images first (largest area error first within), then the passing images with
    the largest ``|area_rel_err|``."""

    def err(r: ImageResult) -> float:
        e = r.score.area_rel_err
        return abs(e) if e is not None and r.score.area_err_kind == "relative" else float("inf")

    ranked = sorted(
        images,
        key=lambda r: (r.passed, -err(r) if not r.passed else -abs(r.score.area_rel_err or 0.0)),
    )
    return ranked[:limit]


def thumbnail(image_path: str, gt: dict[str, Any] | None, *, width: int = 380) -> str | None:
    """JPEG data URI of the image with GT obstacle polygons (green) and marker outlines (blue),
    or ``None`` when the image cannot be read."""
    import cv2

    image = cv2.imread(image_path, cv2.IMREAD_COLOR)
    if image is None:
        return None
    scale = width / image.shape[1]
    thick = max(1, round(2 / scale))
    for marker in (gt or {}).get("markers", []):
        pts = np.asarray(marker.get("corners_px", []), dtype=np.float64)
        if pts.shape == (4, 2):
            cv2.polylines(image, [np.round(pts).astype(np.int32)], True, (255, 120, 0), thick)
    for obs in (gt or {}).get("obstacles", []):
        pts = np.asarray(obs.get("image_polygon_px", []), dtype=np.float64)
        if pts.ndim == 2 and pts.shape[0] >= 3 and pts.shape[1] == 2:
            cv2.polylines(image, [np.round(pts).astype(np.int32)], True, (0, 200, 0), thick)
    small = cv2.resize(
        image, (width, max(1, round(image.shape[0] * scale))), interpolation=cv2.INTER_AREA
    )
    ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 80])
    if not ok:  # pragma: no cover
        return None
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def html_page(report: Report, *, dataset: Dataset | None = None, max_cases: int = 12) -> str:
    """The whole page as text."""
    e = html.escape
    if dataset is None:
        try:
            dataset = load_dataset(report.dataset)
        except (DatasetError, ValueError, OSError):
            dataset = None
    gts = {s.id: s.gt for s in dataset.samples} if dataset is not None else {}
    s = report.summary
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<link rel="icon" href="data:,">',
        f"<title>arenabench: {e(report.pipeline)}</title><style>{CSS}</style></head><body>",
        f"<h1>arenabench evaluation: {e(report.pipeline)}</h1>",
        f"<p>dataset <code>{e(report.dataset)}</code>; area reference "
        f"<code>{e(report.area_reference)}</code>; tolerance {report.tolerance:g}; "
        f'<span class="{"pass" if s.pass_rate == 1 else "fail"}">'
        f"pass rate {fmt(s.pass_rate, pct=True)}</span></p>",
        "<h2>Summary</h2><table><tr><th>metric</th><th>value</th></tr>",
    ]
    parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in summary_rows(s)]
    parts.append('</table><h2>Plots</h2><div class="plots">')
    parts += [
        f'<img{" class=wide" if "parameter" in t else ""} alt="{e(t)}" title="{e(t)}" src="{uri}">'
        for t, uri in _figures(report)
    ]
    parts.append("</div>")
    cases = worst_cases(report.images, limit=max_cases)
    if cases:
        parts.append(
            "<h2>Worst cases</h2><p>Green: ground-truth obstacle outlines; blue: "
            'markers.</p><div class="cases">'
        )
        for r in cases:
            p = r.prediction
            uri = thumbnail(r.image, gts.get(r.id))
            verdict = "PASS" if r.passed else f"FAIL: {r.category}"
            parts.append('<div class="case">')
            parts.append(
                f'<b class="{"pass" if r.passed else "fail"}">{e(r.id)} - {e(verdict)}</b>'
            )
            if uri:
                parts.append(f'<img alt="image {e(r.id)}" src="{uri}">')
            parts.append(
                "<table><tr><th></th><th>GT</th><th>pipeline</th></tr>"
                f"<tr><td>count</td><td>{r.truth.count}</td><td>{e(fmt(p.count))}</td></tr>"
                f"<tr><td>area px</td><td>{r.truth.area:.1f}</td><td>{e(fmt(p.area, digits=8))}"
                "</td></tr>"
                f"<tr><td>marker ids</td><td>{e(str(list(r.truth.marker_ids)))}</td><td>"
                f"{e(str(None if p.marker_ids is None else list(p.marker_ids)))}</td></tr>"
                f"<tr><td>area rel err</td><td colspan=2>{e(fmt(r.score.area_rel_err))}</td></tr>"
                f"<tr><td>latency ms</td><td colspan=2>{p.latency_ms:.1f}</td></tr></table>"
            )
            if p.message:
                parts.append(f"<div>{e(p.message)}</div>")
            for label, text in (("stdout", p.stdout), ("stderr", p.stderr)):
                if text and not r.passed:
                    parts.append(f"<div>{label} (tail):</div><pre>{e(text[-1500:])}</pre>")
            parts.append("</div>")
        parts.append("</div>")
    if report.breakdown:
        parts.append("<h2>Breakdown by scene parameter</h2>")
        for key in sorted(
            report.breakdown, key=lambda k: importance(report.breakdown[k]), reverse=True
        ):
            parts.append(
                f"<h3>{e(key)}</h3><table><tr><th>bin</th><th>n</th><th>pass rate</th>"
                "<th>count exact</th><th>median |area err|</th><th>failures</th></tr>"
            )
            for row in report.breakdown[key]:
                fails = ", ".join(f"{c} {v}" for c, v in row["failures"].items()) or "-"
                parts.append(
                    f"<tr><td>{e(row['bin'])}</td><td>{row['n']}</td>"
                    f"<td>{fmt(row['pass_rate'], pct=True)}</td>"
                    f"<td>{fmt(row['count_exact_rate'], pct=True)}</td>"
                    f"<td>{fmt(row['area_rel_err_median'])}</td><td>{e(fails)}</td></tr>"
                )
            parts.append("</table>")
    parts.append(
        "<h2>All images</h2><table><tr><th>id</th><th>result</th><th>gt count</th>"
        "<th>pred count</th><th>gt area</th><th>pred area</th><th>area rel err</th>"
        "<th>latency ms</th></tr>"
    )
    for r in report.images:
        p = r.prediction
        cls = "pass" if r.passed else "fail"
        parts.append(
            f'<tr><td>{e(r.id)}</td><td class="{cls}">'
            f"{'pass' if r.passed else e(str(r.category))}</td><td>{r.truth.count}</td>"
            f"<td>{e(fmt(p.count))}</td><td>{r.truth.area:.1f}</td>"
            f"<td>{e(fmt(p.area, digits=8))}</td><td>{e(fmt(r.score.area_rel_err))}</td>"
            f"<td>{p.latency_ms:.1f}</td></tr>"
        )
    parts.append("</table></body></html>")
    return "\n".join(parts) + "\n"


def write_html(
    report: Report, path: str | os.PathLike[str], *, dataset: Dataset | None = None
) -> Path:
    """Write ``report.html`` (self-contained)."""
    return atomic_write_text(path, html_page(report, dataset=dataset))
