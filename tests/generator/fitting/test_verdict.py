"""The twin's fit verdict (generator/fitting/verdict.py): good within every bound, poor naming
the figures off and what the image shows that the render does not, on real image operations
(OpenCV blur, noise, clipping) of a drawn arena."""

import cv2
import numpy as np
import pytest

from arenabench.generator.fitting.regions import RegionFigures
from arenabench.generator.fitting.verdict import (
    BOUND_OF,
    BOUNDS,
    GOOD,
    POOR,
    causes,
    figure_values,
    judge,
)


def _arena() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A grey floor with four black-and-white marker-like squares and a box; its masks."""
    img = np.full((400, 400), 200, np.uint8)
    markers = np.zeros(img.shape, bool)
    rng = np.random.default_rng(0)
    for x, y in ((20, 20), (330, 20), (330, 330), (20, 330)):
        cells = rng.integers(0, 2, (6, 6)) * 255
        cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 0
        img[y:y + 48, x:x + 48] = np.kron(cells, np.ones((8, 8))).astype(np.uint8)
        markers[y - 8:y + 56, x - 8:x + 56] = True
    img[150:230, 170:260] = 110
    faces = np.zeros(img.shape, bool)
    faces[152:228, 172:258] = True
    floor = ~markers & ~faces
    return img, {"markers": markers, "faces": faces, "floor": floor}


def _figures(real, render, masks, detector=0.0) -> RegionFigures:
    diff = np.abs(real.astype(float) - render.astype(float))
    mad = {k: float(diff[m].mean()) for k, m in masks.items()}
    return RegionFigures(mad=mad, pixels={k: int(m.sum()) for k, m in masks.items()},
                         per_marker={1: mad["markers"]}, whole=float(diff.mean()),
                         detector_px={1: detector})


def test_a_render_like_its_image_is_good_and_names_nothing():
    img, masks = _arena()
    v = judge(_figures(img, img, masks), img, img, masks)
    assert v.verdict == GOOD and v.good and v.off == () and v.causes == ()
    assert v.line().startswith("fit: good")
    assert v.to_dict()["verdict"] == "good" and len(v.to_dict()["bounds"]) == len(BOUNDS)


def test_a_blurred_image_is_poor_and_the_blur_is_named():
    render, masks = _arena()
    real = cv2.GaussianBlur(render, (0, 0), 3)
    v = judge(_figures(real, render, masks), real, render, masks)
    assert v.verdict == POOR
    assert {o.key for o in v.off} >= {"marker squares"}
    assert any(c.kind == "blur" for c in v.causes), v.causes
    assert "bound 1.5" in v.line()


def test_noise_glare_exposure_and_distortion_are_each_named():
    render, masks = _arena()
    rng = np.random.default_rng(1)
    noisy = np.clip(render + rng.normal(0, 8, render.shape), 0, 255).astype(np.uint8)
    assert any(c.kind == "noise" for c in causes(noisy, render, masks))
    glare = render.copy()
    glare[100:140, 60:300] = 255
    assert any(c.kind == "glare" for c in causes(glare, render, masks))
    dark = np.clip(render.astype(int) - 12, 0, 255).astype(np.uint8)
    assert any(c.kind == "exposure" for c in causes(dark, render, masks))
    assert any(c.kind == "lens"
               for c in causes(render, render, masks, corner_rms_px=2.2))
    assert not any(c.kind == "lens" for c in causes(render, render, masks,
                                                         corner_rms_px=1.1))


def test_noise_softened_by_motion_blur_is_named_and_a_clean_image_names_none():
    """Noise of sigma 4 under a motion blur of about a pixel (as ``eyrc-hard`` draws them): a
    pixel's spread about its 3 x 3 median reads it at whole grey levels and missed it; the
    difference from the render's fine part does not."""
    render, masks = _arena()
    rng = np.random.default_rng(2)
    noisy = np.clip(render + rng.normal(0, 4, render.shape), 0, 255).astype(np.float32)
    kernel = np.array([[0.25, 0.5, 0.25]], np.float32)
    soft = np.clip(cv2.filter2D(noisy, -1, kernel), 0, 255).round().astype(np.uint8)
    assert any(c.kind == "noise" for c in causes(soft, render, masks))
    assert not any(c.kind == "noise" for c in causes(render, render, masks))
    shaded = np.clip(render.astype(int) + np.linspace(-6, 6, 400)[None, :].astype(int), 0,
                     255).astype(np.uint8)  # a slow change of light is not noise
    assert not any(c.kind == "noise" for c in causes(shaded, render, masks))


def test_noise_on_the_faces_alone_is_named():
    """A floor rectified from the image carries the image's noise into the render; the
    boxes' faces, rendered flat, still show it."""
    render, masks = _arena()
    rng = np.random.default_rng(3)
    real = render.astype(np.float64)
    real[masks["faces"]] += rng.normal(0, 3, int(masks["faces"].sum()))
    real = np.clip(real, 0, 255).round().astype(np.uint8)
    assert any(c.kind == "noise" for c in causes(real, render, masks))


def test_a_marker_the_detector_misses_on_the_render_is_off_without_bound():
    img, masks = _arena()
    figures = _figures(img, img, masks, detector=None)
    assert figure_values(figures)["detector corners"] == float("inf")
    v = judge(figures, img, img, masks)
    assert v.verdict == POOR and [o.key for o in v.off] == ["detector corners"]
    assert v.causes and v.causes[0].kind == "unmodelled" and "unmodelled" in v.causes[0].text


@pytest.mark.parametrize("bound", BOUNDS, ids=lambda b: b.key)
def test_every_bound_says_where_it_comes_from(bound):
    assert bound.limit > 0 and bound.unit and len(bound.why) > 40
    assert BOUND_OF[bound.key] is bound


def test_every_unrendered_parameter_is_the_generators_and_a_cause_names_its_kind():
    from arenabench.generator.fitting.verdict import CAUSE_KINDS, UNRENDERED, Cause
    from arenabench.generator.parameters.params import PARAMS

    names = {p.name for p in PARAMS}
    assert UNRENDERED and {name for name, _, _ in UNRENDERED} <= names
    assert {kind for _, _, kind in UNRENDERED} < set(CAUSE_KINDS)
    with pytest.raises(ValueError, match=r"Cause\.kind: 'smudge'"):
        Cause("smudge", "a smudge")
