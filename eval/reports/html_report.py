"""``report.html``: one self-contained page (no external resources, no scripts): summary,
plots of area error and count confusion, pass rate by scene parameter, and the failures as
thumbnails: the image with the ground-truth outlines and what the pipeline found drawn in two
colours, the rectified frame beside it, and the pipeline's numbers."""

from __future__ import annotations

import base64
import heapq
import html
import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from arenabench.eval.datasets.reader import Dataset, DatasetError, load_dataset
from arenabench.eval.scoring.breakdown import shown_breakdown, strongest_cause_text, systematic_text
from arenabench.eval.scoring.results import ImageResult, Prediction, Report
from arenabench.fileio import atomic_write_text
from arenabench.gtrecord import AREA_REFERENCE_FIELDS, DEFAULT_AREA_REFERENCE
from arenabench.limits import MAX_IMAGE_SIDE_PX

from .incomplete import banner_html, partial
from .markdown_report import TOP_CAUSES, phase_cell
from .summary_rows import (
    BREAKDOWN_COLUMNS,
    breakdown_cells,
    fmt,
    interpreter_text,
    summary_rows,
)

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;
text-align:left;font-size:.9em}th{background:#f3f3f3}.pass{color:#176d2c}.fail{color:#b00020}
.plots img{max-width:48%;margin:4px;border:1px solid #ddd}.plots img.wide{max-width:98%}
.cases{display:flex;flex-wrap:wrap;gap:12px}.case{border:1px solid #ccc;padding:6px;
width:380px;font-size:.85em}.case img{width:100%}pre{white-space:pre-wrap;max-height:10em;
overflow:auto;background:#f7f7f7;padding:4px;font-size:.8em}.bar{background:#b00020;height:8px}
.case.wide{width:780px}.strip{display:flex;flex-wrap:wrap;gap:4px}
.strip figure{margin:0;flex:0 0 calc(50% - 2px)}.strip.three figure{flex-basis:calc(33.3% - 3px)}
figcaption{font-size:.8em;color:#555;overflow-wrap:anywhere}
.swatch{display:inline-block;width:1.6em;height:.5em;margin:0 .3em;vertical-align:middle}
"""

#: Outline colours of the thumbnails (BGR for OpenCV, hex for the legend).
GT_BGR, GT_HEX = (0, 200, 0), "#00c800"
PRED_BGR, PRED_HEX = (255, 0, 255), "#ff00ff"
MARKER_BGR, MARKER_HEX = (255, 120, 0), "#0078ff"


def _png_data_uri(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def histogram_range(errors: Sequence[float], tolerance: float) -> tuple[float, int]:
    """Half-width of the area-error histogram's axis, chosen from the data, and how many
    errors lie beyond it (drawn in the end bins).

    The axis spans the largest |error| (at least twice the tolerance so the tolerance lines
    show; at most 1, beyond which errors are clipped).
    """
    floor = max(2.0 * tolerance, 1e-3)
    if not errors:
        return floor, 0
    biggest = float(np.max(np.abs(errors)))
    lim = min(1.0, max(floor, biggest * 1.05))
    return lim, int(np.sum(np.abs(errors) > lim))


#: Most count values the count confusion shows one by one: larger counts share its last bin,
#: "N or more" (``N+``), so no answer or ground truth can make the figure grow without bound.
CONFUSION_COUNTS = 20


def count_confusion(gts: Sequence[int], preds: Sequence[int | None], *,
                    most: int = CONFUSION_COUNTS) -> tuple[np.ndarray, list[str]]:
    """The count confusion: ground-truth counts (rows) against predicted ones (columns, and
    a last column for images with no count).

    The bins follow the data: counts ``0 .. top``, ``top`` the largest count found, and at
    most ``most + 1`` of them: from ``most`` on, a count falls in the last bin, ``"most+"``.

    Returns
    -------
    matrix : numpy.ndarray
        Image numbers, ``(len(labels), len(labels) + 1)``.
    labels : list of str
        The bins' labels.
    """
    top = min(max([*gts, *(p for p in preds if p is not None), 0]), most)
    labels = [str(i) for i in range(top + 1)]
    if top == most:
        labels[-1] = f"{most}+"
    mat = np.zeros((top + 1, top + 2), dtype=np.int64)
    for g, p in zip(gts, preds, strict=True):
        mat[min(int(g), top), top + 1 if p is None else min(int(p), top)] += 1
    return mat, labels


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
    lim, n_out = histogram_range(rels, report.tolerance)
    if rels:
        values = np.clip(rels, -lim, lim)
        edges = np.histogram_bin_edges(values, bins="auto", range=(-lim, lim))
        bins = int(np.clip(len(edges) - 1, 10, 60))
        ax.hist(values, bins=bins, range=(-lim, lim), color="#4c72b0", edgecolor="white",
                linewidth=0.5)
    ax.set_xlim(-lim, lim)
    for x in (-report.tolerance, report.tolerance):
        ax.axvline(x, color="#b00020", linestyle="--", linewidth=1)
    label = "signed area relative error"
    if n_out:
        label += f" ({n_out} image(s) beyond +-{lim:g} counted in the end bins)"
    ax.set_xlabel(label)
    ax.set_ylabel("images")
    ax.set_title("Area error (dashed: tolerance)")
    out.append(("Area error histogram", _png_data_uri(fig)))

    mat, labels = count_confusion([r.truth.count for r in report.images],
                                  [r.prediction.count for r in report.images])
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
    ax.set_xticks(range(len(labels) + 1), [*labels, "none"])
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("predicted count")
    ax.set_ylabel("ground-truth count")
    ax.set_title("Count confusion")
    out.append(("Count confusion", _png_data_uri(fig)))

    keys = shown_breakdown(report)
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


def _latency(pred: Prediction) -> str:
    """The latency cell: ``-`` for an image without one (timed out, never ran)."""
    ms = pred.measured_latency_ms
    return "-" if ms is None else f"{ms:.1f}"


def worst_cases(images: Sequence[ImageResult], *, limit: int = 12) -> list[ImageResult]:
    """The failing images, largest area error first (failures without a relative area error,
    e.g. crashes, first of all); empty when every image passed."""

    def err(r: ImageResult) -> float:
        e = r.score.area_rel_err
        return abs(e) if e is not None and r.score.area_err_kind == "relative" else float("inf")

    # = sorted(...)[:limit] (stable), holding only ``limit`` results of a big run
    return heapq.nsmallest(limit, (r for r in images if not r.passed), key=lambda r: -err(r))


def _read_colour(image_path: str) -> np.ndarray | None:
    """The image as ``cv2.imread(..., IMREAD_COLOR)`` reads it, only from a regular file;
    ``None`` when it cannot be read."""
    import cv2

    from arenabench.imageio import ImageLoadError, read_image_bytes

    try:
        data = read_image_bytes(image_path)
    except ImageLoadError:
        return None
    return cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)


def _frame_to_image(h: np.ndarray | None) -> np.ndarray | None:
    if h is None:
        return None
    try:
        return np.linalg.inv(h)
    except np.linalg.LinAlgError:
        return None


def _homography(pred: Prediction | None, gt: dict[str, Any] | None) -> np.ndarray | None:
    """Input image px -> frame px: the pipeline's own, else the ground truth's."""
    for h in (None if pred is None else pred.homography, (gt or {}).get("homography")):
        if h is not None:
            m = np.asarray(h, dtype=np.float64)
            if m.shape == (3, 3) and np.isfinite(m).all():
                return m
    return None


def _map(points: Any, h: np.ndarray) -> np.ndarray:
    import cv2

    pts = np.asarray(points, dtype=np.float64).reshape(-1, 1, 2)
    return cv2.perspectiveTransform(pts, h).reshape(-1, 2)


def gt_frame_polygons(gt: dict[str, Any] | None, h: np.ndarray, *,
                      area_key: str = "visible_frame_px") -> list[Any]:
    """The GT's frame polygons (``area_key``) in the frame that ``h`` (input image px ->
    frame px) warps to.

    GT polygons are in the GT's frame (its reference corners, usually the inner ones); a
    pipeline that warps to other corners (the outer ones, markers printed upright) has
    another frame, so they are taken back to the image by the GT's homography and on by
    ``h``. The GT's own homography leaves them as they are.
    """
    polys = [o.get(area_key, []) for o in (gt or {}).get("obstacles", [])]
    gt_h = _homography(None, gt)
    if gt_h is None or np.allclose(gt_h, h, rtol=1e-9, atol=1e-12):
        return polys
    back = _frame_to_image(gt_h)
    if back is None:
        return []
    out = []
    for poly in polys:
        pts = np.asarray(poly, dtype=np.float64)
        if pts.ndim == 2 and pts.shape[0] >= 3 and pts.shape[1] == 2:
            out.append(_map(pts, h @ back))
    return out


def _predicted_polygons(pred: Prediction | None, h: np.ndarray | None, *,
                        space: str) -> list[np.ndarray]:
    """The pipeline's polygons in ``space`` ("image" or "frame") px."""
    if pred is None or not pred.obstacles:
        return []
    polys = [np.asarray(p, dtype=np.float64) for p in pred.obstacles]
    if pred.obstacles_space == space:
        return polys
    m = h if space == "frame" else _frame_to_image(h)
    return [] if m is None else [_map(p, m) for p in polys]


def _small(image: np.ndarray, width: int) -> tuple[np.ndarray, float]:
    import cv2

    scale = width / image.shape[1]
    small = cv2.resize(
        image, (width, max(1, round(image.shape[0] * scale))), interpolation=cv2.INTER_AREA
    )
    return small, scale


def _encode(small: np.ndarray) -> str | None:
    import cv2

    params = [cv2.IMWRITE_JPEG_QUALITY, 90]
    if hasattr(cv2, "IMWRITE_JPEG_SAMPLING_FACTOR"):  # full-resolution colour: crisp outlines
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444]
    ok, buf = cv2.imencode(".jpg", small, params)
    if not ok:  # pragma: no cover
        return None
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def _outline(image: np.ndarray, polys: Sequence[Any], colour: tuple[int, int, int],
             thick: int, scale: float) -> None:
    """Draw closed polygons given in full-size px on the scaled-down ``image``."""
    import cv2

    for poly in polys:
        pts = np.asarray(poly, dtype=np.float64)
        if pts.ndim == 2 and pts.shape[0] >= 3 and pts.shape[1] == 2 and np.isfinite(pts).all():
            fixed = np.round(pts * scale * 16).astype(np.int32)  # 4 fractional bits
            cv2.polylines(image, [fixed], True, colour, thick, cv2.LINE_AA, shift=4)


def thumbnail(image_path: str, gt: dict[str, Any] | None, *, width: int = 380,
              pred: Prediction | None = None) -> str | None:
    """JPEG data URI of the image with the GT obstacle outlines (wide, green), the markers
    (blue) and the pipeline's obstacles (narrow, magenta, on top; when it reported polygons),
    or ``None`` when the image cannot be read."""

    image = _read_colour(image_path)
    if image is None:
        return None
    small, scale = _small(image, width)
    markers = [m.get("corners_px", []) for m in (gt or {}).get("markers", [])]
    _outline(small, markers, MARKER_BGR, 2, scale)
    # GT wide, the pipeline's outline narrow on top: both stay visible where they agree
    _outline(small, [o.get("image_polygon_px", []) for o in (gt or {}).get("obstacles", [])],
             GT_BGR, 5, scale)
    h = _homography(pred, gt)
    _outline(small, _predicted_polygons(pred, h, space="image"), PRED_BGR, 2, scale)
    return _encode(small)


def frame_thumbnail(image_path: str, gt: dict[str, Any] | None, *, width: int = 380,
                    pred: Prediction | None = None, area_key: str = "visible_frame_px"
                    ) -> str | None:
    """JPEG data URI of the image rectified to the frame (the pipeline's homography, else the
    ground truth's) with the GT frame polygons (green) and the pipeline's (magenta); ``None``
    when there is no homography or the image cannot be read."""
    import cv2

    h = _homography(pred, gt)
    image = _read_colour(image_path)
    if h is None or image is None:
        return None
    size = (gt or {}).get("frame", {}).get("size") or [1000, 1000]
    fw, fh = int(size[0]), int(size[1])
    if not (16 <= fw <= MAX_IMAGE_SIDE_PX and 16 <= fh <= MAX_IMAGE_SIDE_PX):
        return None
    small, scale = _small(cv2.warpPerspective(image, h, (fw, fh)), width)
    _outline(small, gt_frame_polygons(gt, h, area_key=area_key), GT_BGR, 5, scale)
    _outline(small, _predicted_polygons(pred, h, space="frame"), PRED_BGR, 2, scale)
    return _encode(small)


def _card_images(r: ImageResult, uri: str | None, frame_uri: str | None) -> list[str]:
    """A failure card's images: the input with the outlines, its rectified frame (the
    pipeline's warp when it reports a homography, else the ground truth's) and, beside them,
    the images the run left in its working directory (its own warp...), each captioned."""
    e = html.escape
    own_warp = r.prediction.homography is not None
    figures = [(uri, f"image {r.id}", "image"),
               (frame_uri, f"frame {r.id}",
                "the pipeline's warp" if own_warp else "the ground truth's warp")]
    figures += [(i.data_uri(), f"run image {i.name} {r.id}",
                 f"the run's {i.name} ({i.width} x {i.height})")
                for i in r.prediction.run_images]
    shown = [f for f in figures if f[0]]
    if not shown:
        return []
    if len(shown) == 1 and not r.prediction.run_images:
        return [f'<img alt="{e(shown[0][1])}" src="{shown[0][0]}">']
    return [f'<div class="strip{" three" if len(shown) >= 3 else ""}">',
            *(f'<figure><img alt="{e(alt)}" src="{src}"><figcaption>{e(cap)}</figcaption>'
              "</figure>" for src, alt, cap in shown),
            "</div>"]


def _causes_html(report: Report) -> list[str]:
    """The "Likely causes" section (right after the summary: what the failures have in
    common): systematic errors, then the ranked scene facts."""
    e = html.escape
    if not report.causes and not report.systematic:
        return []
    parts = ["<h2>Likely causes</h2>"]
    if (text := systematic_text(report.systematic)) is not None:
        parts.append(f'<p class="fail"><b>{e(text)}</b>.</p>')
    if report.causes:
        parts.append(
            "<p>Scene parameters and derived facts that best separate "
            "failing from passing images (strength = |2 AUC - 1|: 0 none, 1 every failure "
            f"beyond every pass). {e(strongest_cause_text(report.causes))}.</p>"
            "<table><tr><th>parameter</th><th>strength</th><th>failures have</th>"
            "<th>median in failures</th><th>median in passes</th><th>p</th></tr>")
        for c in report.causes[:TOP_CAUSES]:
            parts.append(
                f"<tr><td>{e(c['param'])}</td><td>{c['strength']:.2f}</td>"
                f"<td>{e(c['direction'])} values</td><td>{e(fmt(c['fail_median']))}</td>"
                f"<td>{e(fmt(c['pass_median']))}</td><td>{c['p_value']:.2g}</td></tr>")
        parts.append("</table>")
    return parts


def html_page(report: Report, *, dataset: Dataset | None = None, max_cases: int = 12) -> str:
    """The whole page as text."""
    e = html.escape
    if dataset is None:
        try:
            dataset = load_dataset(report.dataset)
        except (DatasetError, ValueError, OSError):
            dataset = None
    cases = worst_cases(report.images, limit=max_cases)
    gts = ({i: s.gt.to_dict() for i, s in dataset.items_by_id(r.id for r in cases).items()}
           if dataset is not None else {})
    s = report.summary
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<link rel="icon" href="data:,">',
        f"<title>arenabench: {e(report.pipeline)}</title><style>{CSS}</style></head><body>",
        f"<h1>arenabench evaluation: {e(report.pipeline)}</h1>",
        "" if report.complete else banner_html(report.images_done, report.n_total),
        f"<p>dataset <code>{e(report.dataset)}</code>; area reference "
        f"<code>{e(report.area_reference)}</code>; tolerance {report.tolerance:g}; "
        f'<span class="{"pass" if s.pass_rate == 1 else "fail"}">'
        f"{partial('pass rate', report.complete)} {fmt(s.pass_rate, pct=True)}</span></p>",
        "" if report.interpreter is None
        else f"<p>interpreter: {e(interpreter_text(report.interpreter))}</p>",
        f"<h2>{partial('Summary', report.complete)}</h2>"
        "<table><tr><th>metric</th><th>value</th></tr>",
    ]
    parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in summary_rows(s)]
    parts.append("</table>")
    parts += _causes_html(report)
    parts.append('<h2>Plots</h2><div class="plots">')
    parts += [
        f'<img{" class=wide" if "parameter" in t else ""} alt="{e(t)}" title="{e(t)}" src="{uri}">'
        for t, uri in _figures(report)
    ]
    parts.append("</div>")
    n_failed = s.n - s.n_passed
    parts.append("<h2>Failures</h2>")
    if not cases:
        parts.append("<p>No failures: every image passed.</p>")
    else:
        shown = f"the {len(cases)} worst of {n_failed}" if n_failed > len(cases) else "all"
        parts.append(
            f"<p>{n_failed} image(s) failed; {shown} below, largest area error first. "
            f'Outlines: <span class="swatch" style="background:{GT_HEX}"></span>ground truth, '
            f'<span class="swatch" style="background:{PRED_HEX}"></span>what the pipeline '
            f'found (when it reports polygons), <span class="swatch" '
            f'style="background:{MARKER_HEX}"></span>markers. Beside: the image rectified to '
            "the frame (the pipeline's homography, else the ground truth's), then the images "
            "a command's run left in its working directory (its own warp, when it saves "
            "one).</p>"
            '<div class="cases">'
        )
        ref = AREA_REFERENCE_FIELDS.get(report.area_reference)
        area_key = (ref or AREA_REFERENCE_FIELDS[DEFAULT_AREA_REFERENCE]).polygons
        for r in cases:
            p = r.prediction
            gt = gts.get(r.id)
            uri = thumbnail(r.image, gt, pred=p)
            frame_uri = frame_thumbnail(r.image, gt, pred=p, area_key=area_key)
            verdict = f"FAIL: {r.category}"
            if r.phase is not None:
                verdict += f" (passes {phase_cell(r.phase)})"
            parts.append(f'<div class="case{" wide" if frame_uri or p.run_images else ""}">')
            parts.append(f'<b class="fail">{e(r.id)} - {e(verdict)}</b>')
            parts += _card_images(r, uri, frame_uri)
            parts.append(
                "<table><tr><th></th><th>GT</th><th>pipeline</th></tr>"
                f"<tr><td>count</td><td>{r.truth.count}</td><td>{e(fmt(p.count))}</td></tr>"
                f"<tr><td>area px</td><td>{r.truth.area:.1f}</td><td>{e(fmt(p.area, digits=8))}"
                "</td></tr>"
                f"<tr><td>marker ids</td><td>{e(str(list(r.truth.marker_ids)))}</td><td>"
                f"{e(str(None if p.marker_ids is None else list(p.marker_ids)))}</td></tr>"
                f"<tr><td>area rel err</td><td colspan=2>{e(fmt(r.score.area_rel_err))}</td></tr>"
                f"<tr><td>latency ms</td><td colspan=2>{_latency(p)}</td></tr></table>"
            )
            if p.message:
                parts.append(f"<div>{e(p.message)}</div>")
            for label, text in (("stdout", p.stdout), ("stderr", p.stderr)):
                if text:
                    parts.append(f"<div>{label} (tail):</div><pre>{e(text[-1500:])}</pre>")
            parts.append("</div>")
        parts.append("</div>")
    keys = shown_breakdown(report)
    if keys:
        parts.append("<h2>Breakdown by scene parameter</h2><p>The parameters that best "
                     "separate failures from passes (all of them: <code>breakdown</code> in "
                     "report.json).</p>")
        for key in keys:
            parts.append(f"<h3>{e(key)}</h3><table><tr>"
                         + "".join(f"<th>{e(c)}</th>" for c in BREAKDOWN_COLUMNS) + "</tr>")
            for row in report.breakdown[key]:
                parts.append("<tr>" + "".join(f"<td>{e(c)}</td>" for c in breakdown_cells(row))
                             + "</tr>")
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
            f"{'pass' if r.passed else e(str(r.category))}"
            f"{'' if r.phase is None else ' ' + e(phase_cell(r.phase))}</td>"
            f"<td>{r.truth.count}</td>"
            f"<td>{e(fmt(p.count))}</td><td>{r.truth.area:.1f}</td>"
            f"<td>{e(fmt(p.area, digits=8))}</td><td>{e(fmt(r.score.area_rel_err))}</td>"
            f"<td>{_latency(p)}</td></tr>"
        )
    parts.append("</table></body></html>")
    return "\n".join(parts) + "\n"


def write_html(
    report: Report, path: str | os.PathLike[str], *, dataset: Dataset | None = None
) -> Path:
    """Write ``report.html`` (self-contained)."""
    return atomic_write_text(path, html_page(report, dataset=dataset))
