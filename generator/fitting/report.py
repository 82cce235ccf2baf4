"""``report.html`` of a twin: the real image, the twin's render of the same scene and their
difference, region by region (markers, box edges, faces, floor), then every parameter pinned or
open and what varies. One self-contained file (pictures inlined)."""

from __future__ import annotations

import base64
import html

import cv2
import numpy as np

from arenabench.generator.fitting.build import Twin
from arenabench.generator.fitting.regions import REGIONS, difference_image
from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices
from arenabench.generator.parameters.param_values import format_value

#: Zoom of the marker crops and of the box crops.
MARKER_ZOOM = 3
BOX_ZOOM = 2
#: Width (px) of the whole-image pictures.
WHOLE_PX = 480

_STYLE = """
body{font-family:system-ui,sans-serif;margin:24px;max-width:1500px;color:#222}
h1{font-size:22px}h2{font-size:18px;margin-top:28px}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 6px;
vertical-align:top;text-align:left}th{background:#f2f2f2}.pinned{color:#175}.open{color:#a50}
figure{display:inline-block;margin:4px 8px 4px 0;text-align:center;font-size:12px}
img{image-rendering:pixelated;border:1px solid #bbb}.note{color:#555;font-size:13px}
.warn{color:#a50}
.verdict{padding:8px 12px;border-radius:4px;font-size:15px}.verdict.good{background:#e6f4ea}
.verdict.poor{background:#fce8e6}
"""


def _png(bgr: np.ndarray) -> str:
    ok, buf = cv2.imencode(".png", bgr)
    if not ok:  # pragma: no cover - OpenCV failure
        raise RuntimeError("PNG encoding failed")
    return "data:image/png;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def _detector_note(offsets: dict[str, float | None]) -> str:
    """The default detector's corners on the render against the image, and what it means
    for scripts that warp from them."""
    from arenabench.generator.fitting.markers import detector_offset_text

    said = html.escape(detector_offset_text({int(k): v for k, v in offsets.items()}))
    if any(v is None for v in offsets.values()):
        return (f"<p class=warn>On the twin's render, {said} (<code>cv2.aruco</code>, no "
                "corner refinement, as competition scripts call it), which finds it on the "
                "image: scripts that use that detector can fail the twin's scenes where they pass "
                "the real ones.</p>")
    if all(v == 0 for v in offsets.values()):
        return ("<p>The default <code>cv2.aruco</code> detector (no corner refinement, as "
                "competition scripts call it) reports the markers' corners on the twin's "
                "render at the same pixels as on the image.</p>")
    return ("<p class=warn>The default <code>cv2.aruco</code> detector (no corner "
            "refinement, as competition scripts call it) reports the markers' corners on the "
            f"twin's render {said} from where it reports them on the image. Its "
            "corners are whole pixels read off a thresholded outline: they follow the markers' "
            "finest blends, which the twin matches only as well as the marker squares' "
            "difference says. A script that warps the arena from them sees a frame that much "
            "off on the twin's scenes, so its results can differ from the real tests' even "
            "where the method is sound; a script that refines the corners does not.</p>")


def _img(bgr: np.ndarray, caption: str, *, width: int | None = None) -> str:
    w = f' width="{width}"' if width else ""
    return (f'<figure><img src="{_png(bgr)}"{w} alt="{html.escape(caption)}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _zoom(img: np.ndarray, factor: int) -> np.ndarray:
    return cv2.resize(img, None, fx=factor, fy=factor, interpolation=cv2.INTER_NEAREST)


def _triple(real: np.ndarray, render: np.ndarray, diff: np.ndarray, box: tuple[int, ...],
            zoom: int, label: str) -> str:
    x0, y0, x1, y1 = box
    return "".join(_img(_zoom(im[y0:y1, x0:x1], zoom), f"{label}: {what}")
                   for im, what in ((real, "real"), (render, "twin"), (diff, "difference")))


def _boxes_of(twin: Twin, shape: tuple[int, int], pad: int = 6) -> list[tuple[int, ...]]:
    K = cam.intrinsics(twin.scene.camera)
    pose = cam.world_from_camera(twin.scene.camera)
    out = []
    for ob in twin.scene.obstacles:
        px = cam.project(box_vertices(ob), K, pose)
        x0, y0 = np.floor(px.min(axis=0)).astype(int) - pad
        x1, y1 = np.ceil(px.max(axis=0)).astype(int) + pad
        out.append((max(x0, 0), max(y0, 0), min(x1, shape[1]), min(y1, shape[0])))
    return out


def report_html(twin: Twin, *, name: str) -> str:
    """The report's HTML."""
    f = twin.facts
    real, render = twin.real, twin.render
    rg, tg = (cv2.cvtColor(i, cv2.COLOR_BGR2GRAY) for i in (real, render))
    diff = difference_image(tg, rg)
    scale = WHOLE_PX / real.shape[1]
    small = (WHOLE_PX, round(real.shape[0] * scale))
    parts = [f"<!doctype html><meta charset='utf-8'><title>twin {html.escape(name)}</title>",
             f"<style>{_STYLE}</style>",
             f"<h1>Twin <code>{html.escape(name)}</code> of "
             f"<code>{html.escape(f['image']['file'])}</code></h1>"]
    verdict = twin.verdict
    parts.append(f"<p class='verdict {verdict.verdict}'><b>Fit: {verdict.verdict}</b>. "
                 + html.escape(verdict.line().removeprefix(f"fit: {verdict.verdict}")
                               .lstrip(":; ")) + "</p>")
    fig = f["figures"]
    parts.append(
        "<p>The fitted scene rendered by the generator and written as the image was "
        f"({html.escape(f['image']['format'])}"
        + (f", quality {f['image']['jpeg_quality']}, {f['image']['jpeg_subsampling']}"
           if f["image"]["format"] == "jpeg" else "")
        + f"), against the image: marker squares <b>{fig['mad']['markers']:.2f}</b> grey levels "
        f"mean absolute difference, whole image {fig['whole']:.2f}, SSIM {fig['ssim']:.4f}. "
        f"{sum(r.status == 'pinned' for r in twin.records)} parameters pinned, "
        f"{sum(r.status == 'open' for r in twin.records)} open. Built in "
        f"{sum(twin.timings.values()):.0f} s.</p>")
    parts.append("<h2>The image, the twin, the difference</h2>")
    parts.append("<p class=note>Difference: grey where equal, red where the twin is lighter, "
                 "blue where darker, 8 times the grey difference.</p>")
    for im, what in ((real, "real image"), (render, "twin's render of the same scene"),
                     (diff, "difference")):
        parts.append(_img(cv2.resize(im, small, interpolation=cv2.INTER_AREA), what,
                          width=WHOLE_PX))
    parts.append("<h2>Region by region</h2><table><tr><th>region</th><th>pixels</th>"
                 "<th>mean absolute difference (grey levels)</th></tr>")
    for region in REGIONS:
        v = fig["mad"].get(region)
        parts.append(f"<tr><td>{region}</td><td>{fig['pixels'].get(region, 0)}</td>"
                     f"<td>{'-' if v is None else f'{v:.3f}'}</td></tr>")
    parts.append("</table>")
    parts.append("<h3>Markers</h3><p class=note>Each marker's square, 8 px around it "
                 f"(zoom {MARKER_ZOOM}x); per marker: "
                 + ", ".join(f"{k}: {v:.2f}" for k, v in fig["per_marker"].items()) + "</p>")
    parts.append(_detector_note(fig["detector_corners_px"]))
    from arenabench.generator.fitting.markers import find_markers
    from arenabench.generator.fitting.regions import marker_squares, region_masks

    finding = find_markers(rg)
    for marker_id, square in marker_squares(finding, rg.shape).items():
        ys, xs = np.nonzero(square)
        parts.append("<div>" + _triple(real, render, diff, (xs.min(), ys.min(), xs.max() + 1,
                                                             ys.max() + 1), MARKER_ZOOM,
                                       f"marker {marker_id}") + "</div>")
    boxes = _boxes_of(twin, rg.shape)
    parts.append(f"<h3>Box edges and faces</h3><p class=note>Each box (zoom {BOX_ZOOM}x): "
                 "its edges (2 px around the outline) and faces. Faces seen: top and "
                 + (", ".join(sorted({x['direction'] for x in f['shades']['faces']})) or "none")
                 + f"; edges: {f['edges']['samples'] or 'open'} samples, "
                 f"{f['edges']['resolve'] or 'open'} resolve.</p>")
    for i, b in enumerate(boxes):
        parts.append("<div>" + _triple(real, render, diff, b, BOX_ZOOM, f"box {i + 1}")
                     + "</div>")
    if not boxes:
        parts.append("<p>No box in the image.</p>")
    parts.append("<h3>Floor</h3><p class=note>The difference over the floor (markers and boxes "
                 "masked grey), contrast 8x.</p>")
    floor = region_masks(twin.scene, finding, rg.shape)["floor"]
    floor_diff = diff.copy()
    floor_diff[~floor] = 128
    parts.append(_img(cv2.resize(floor_diff, small, interpolation=cv2.INTER_AREA),
                      "floor difference", width=WHOLE_PX))
    parts.append("<h2>Parameters: pinned or open</h2><p class=note>Pinned: the image fixes the "
                 "value; its residual says how much the render moves away from the image when "
                 "the value moves. Open: the image leaves it free; the range kept, and why. "
                 "Open boxes' values vary in the preset's scenes (the target varies them "
                 "too); other open values stay at one consistent value, and the phase check "
                 "tries the others, with what moves with them.</p>")
    parts.append("<table><tr><th>parameter</th><th>value</th><th>status</th><th>evidence</th>"
                 "<th>residual / range kept, why</th></tr>")
    for r in twin.records:
        if r.status == "pinned":
            detail = ("" if r.residual is None
                      else f"{r.residual:g} {html.escape(r.residual_unit)}")
        else:
            kept = (f"{r.range.lo:g} .. {r.range.hi:g}" if r.range is not None
                    else ", ".join(format_value(v) for v in r.values or ()))
            detail = f"{html.escape(kept)}: {html.escape(r.reason)}"
            if r.moves_with:  # varied together: what each variant sets with it
                detail += "; moves with it: " + html.escape("; ".join(
                    f"{name} {', '.join(f'{v:g}' for v in at)}" for name, at in r.moves_with))
            if r.gauge:
                detail += " (not varied: every length scaled alike gives the same images)"
        parts.append(f"<tr><td><code>{r.name}</code></td><td>"
                     f"{html.escape(format_value(r.value))}</td><td class={r.status}>{r.status}"
                     f"</td><td>{html.escape(r.evidence)}</td><td>{detail}</td></tr>")
    parts.append("</table><h2>What varies</h2><table><tr><th>parameter</th><th>in the preset"
                 "</th><th>the image shows</th><th>rule</th></tr>")
    for v in twin.varied:
        parts.append(f"<tr><td><code>{v.name}</code></td><td>"
                     f"{html.escape(format_value(v.value))}</td><td>{html.escape(v.seen)}</td>"
                     f"<td>{html.escape(v.rule)}</td></tr>")
    parts.append("</table><h2>Camera</h2><table><tr><th>fitted freely</th><th>snapped</th></tr>"
                 f"<tr><td>{html.escape(str(f['camera']['free']))}</td><td>"
                 + html.escape(", ".join(f"{k} = {v['value']:g} {v['unit']}"
                                         for k, v in f["camera"]["snapped"].items()) or "none")
                 + "</td></tr></table>")
    parts.append("<h2>Timings</h2><p>" + ", ".join(f"{k} {v:.1f} s"
                                                   for k, v in twin.timings.items()) + "</p>")
    return "\n".join(parts) + "\n"
