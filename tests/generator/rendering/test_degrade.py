"""Photometric degradations (arenabench.generator.rendering.degrade) and the lens model
(arenabench.generator.model.lens), on real renders.

Each degradation at its neutral value leaves the image byte-identical; a strong value changes
it the intended way. The lens helpers are checked against OpenCV's own model.
"""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from arenabench.generator.dataset.make import degrade_rng, make_sample
from arenabench.generator.model.lens import densify, distort_points, lens_canvas, undistort_points
from arenabench.generator.parameters.param_values import parse_overrides
from arenabench.generator.parameters.params import NEUTRAL, PARAMETERS
from arenabench.generator.parameters.presets import resolve
from arenabench.generator.rendering.degrade import (
    PARAM_NAMES,
    Degradations,
    apply_degradations,
    standard_normal,
)


@pytest.fixture(scope="module")
def clean(renderer):
    """A clean eyrc render (uint8 RGB) and its sample."""
    s = make_sample("eyrc", seed=11, index=0, renderer=renderer)
    return s


def _rng() -> np.random.Generator:
    return degrade_rng(11, 0)


def _laplacian_var(rgb: np.ndarray) -> float:
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    return float(cv2.Laplacian(gray, cv2.CV_64F).var())


def test_every_degradation_parameter_is_declared_with_a_neutral_default():
    for name in NEUTRAL:
        assert name in PARAMETERS, name
        assert PARAMETERS[name].help
    assert Degradations.from_params(resolve("eyrc")).is_neutral
    for preset in ("eyrc", "eyrc-upright", "eyrc-oblique"):
        params = resolve(preset)
        assert all(params[k] == v for k, v in NEUTRAL.items()), preset


@pytest.mark.parametrize("field", [
    "vignetting", "exposure_ev", "motion_blur_px", "motion_angle_deg", "defocus_px",
    "noise_sigma", "poisson_photons", "gamma", "jpeg_quality",
])
def test_neutral_value_of_each_degradation_leaves_the_image_byte_identical(clean, field):
    neutral = Degradations()
    kwargs = {field: getattr(neutral, field)}
    out = apply_degradations(clean.rgb, Degradations(**kwargs), _rng())
    assert out.tobytes() == clean.rgb.tobytes()


def test_neutral_set_values_give_the_same_image_through_make_sample(renderer, clean):
    sets = [f"{k}={v}" for k, v in NEUTRAL.items()]
    s = make_sample("eyrc", seed=11, index=0, renderer=renderer, overrides=parse_overrides(sets))
    assert s.rgb.tobytes() == clean.rgb.tobytes()
    for key, value in NEUTRAL.items():
        assert s.gt["params"][key] == value, key


def test_gaussian_noise_raises_the_residual_std_by_sigma():
    flat = np.full((300, 300, 3), 128, np.uint8)
    for sigma in (3.0, 10.0):
        out = apply_degradations(flat, Degradations(noise_sigma=sigma), _rng())
        std = float((out.astype(np.float64) - flat).std())
        assert abs(std - sigma) < 0.05 * sigma + 0.3, (sigma, std)


def test_poisson_noise_follows_the_photon_count():
    flat = np.full((300, 300, 3), 128, np.uint8)
    photons = 100.0
    out = apply_degradations(flat, Degradations(poisson_photons=photons), _rng())
    lam = 128 * photons / 255.0
    expected = np.sqrt(lam) * 255.0 / photons  # about 18 grey levels
    std = float((out.astype(np.float64) - flat).std())
    assert abs(std - expected) < 0.05 * expected, (std, expected)
    assert abs(float(out.mean()) - 128) < 0.5
    brighter = apply_degradations(flat, Degradations(poisson_photons=1e5), _rng())
    assert float((brighter.astype(np.float64) - flat).std()) < 1.0
    # Few photons: exact Poisson counts (multiples of 255 / photons grey levels).
    dark = apply_degradations(flat, Degradations(poisson_photons=20.0), _rng())
    lam = 128 * 20.0 / 255.0
    std = float((dark.astype(np.float64) - flat).std())
    assert abs(std - np.sqrt(lam) * 255.0 / 20.0) < 0.05 * np.sqrt(lam) * 255.0 / 20.0
    assert abs(float(dark.mean()) - 128) < 1.0
    assert len(np.unique(dark)) < 30  # quantised by the photon count


def test_noise_is_deterministic_per_generator(clean):
    d = Degradations(noise_sigma=8.0, poisson_photons=500.0)
    a = apply_degradations(clean.rgb, d, degrade_rng(3, 4))
    b = apply_degradations(clean.rgb, d, degrade_rng(3, 4))
    c = apply_degradations(clean.rgb, d, degrade_rng(3, 5))
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()


@pytest.mark.parametrize("kwargs", [
    {"motion_blur_px": 9.0, "motion_angle_deg": 30.0},
    {"defocus_px": 3.0},
])
def test_blur_lowers_the_laplacian_variance(clean, kwargs):
    out = apply_degradations(clean.rgb, Degradations(**kwargs), _rng())
    assert _laplacian_var(out) < 0.5 * _laplacian_var(clean.rgb)
    assert abs(float(out.mean()) - float(clean.rgb.mean())) < 1.0  # blur keeps brightness


def test_motion_blur_follows_its_direction():
    img = np.zeros((101, 101, 3), np.uint8)
    img[50, 50] = 255
    horizontal = apply_degradations(img, Degradations(motion_blur_px=21.0), _rng())[:, :, 0]
    vertical = apply_degradations(
        img, Degradations(motion_blur_px=21.0, motion_angle_deg=90.0), _rng())[:, :, 0]
    ys, xs = np.nonzero(horizontal)
    assert np.ptp(xs) >= 18 and np.ptp(ys) <= 2
    ys, xs = np.nonzero(vertical)
    assert np.ptp(ys) >= 18 and np.ptp(xs) <= 2


def test_jpeg_at_low_quality_differs_and_matches_an_opencv_round_trip(clean):
    out = apply_degradations(clean.rgb, Degradations(jpeg_quality=10), _rng())
    assert out.shape == clean.rgb.shape and out.dtype == np.uint8
    assert out.tobytes() != clean.rgb.tobytes()
    ok, buf = cv2.imencode(".jpg", clean.bgr, [cv2.IMWRITE_JPEG_QUALITY, 10])
    assert ok
    ref = cv2.imdecode(buf, cv2.IMREAD_COLOR)[:, :, ::-1]
    assert np.array_equal(out, ref)
    high = apply_degradations(clean.rgb, Degradations(jpeg_quality=95), _rng())
    err_low = np.abs(out.astype(int) - clean.rgb).mean()
    err_high = np.abs(high.astype(int) - clean.rgb).mean()
    assert err_high < err_low


def test_exposure_and_gamma_move_the_mean_the_right_way(clean):
    mean = float(clean.rgb.mean())

    def m(**kw):
        return float(apply_degradations(clean.rgb, Degradations(**kw), _rng()).mean())

    assert m(exposure_ev=-1.0) == pytest.approx(mean / 2, rel=0.02)
    assert m(exposure_ev=0.5) > mean
    assert m(gamma=2.0) > mean
    assert m(gamma=0.5) < mean


def test_vignetting_darkens_the_corners_more_than_the_centre():
    flat = np.full((200, 300, 3), 200, np.uint8)
    out = apply_degradations(flat, Degradations(vignetting=0.6), _rng()).astype(float)
    centre = out[95:105, 145:155].mean()
    corners = [out[:5, :5].mean(), out[:5, -5:].mean(), out[-5:, :5].mean(),
               out[-5:, -5:].mean()]
    assert centre > 198
    assert all(c < 0.5 * 200 for c in corners), corners  # gain 0.4 at the very corner
    edge_mid = out[95:105, :3].mean()
    assert corners[0] < edge_mid < centre


def test_invalid_values_are_refused_with_the_parameter_name():
    with pytest.raises(ValueError, match=r"degrade\.vignetting"):
        Degradations(vignetting=1.5)
    with pytest.raises(ValueError, match=r"degrade\.jpeg_quality"):
        Degradations(jpeg_quality=101)
    with pytest.raises(ValueError, match=r"degrade\.gamma"):
        Degradations(gamma=0.0)
    with pytest.raises(ValueError, match=r"degrade\.noise_sigma"):
        parse_overrides(["degrade.noise_sigma=-1"])
    with pytest.raises(ValueError, match="rgb"):
        apply_degradations(np.zeros((4, 4), np.uint8), Degradations(noise_sigma=1.0), _rng())


@pytest.mark.parametrize("field", sorted(PARAM_NAMES))
def test_degradation_bounds_are_the_declared_parameter_bounds(field):
    """Each field takes exactly its parameter's declared range: both ends pass, a step beyond
    either end is refused with one message naming the parameter and the value."""
    spec = PARAMETERS[PARAM_NAMES[field]]
    lo, hi = spec.bounds.lo, spec.bounds.hi
    step = 1 if spec.kind == "int" else 1e-6 * max(1.0, abs(hi))
    assert getattr(Degradations(**{field: lo}), field) == lo
    assert getattr(Degradations(**{field: hi}), field) == hi
    for bad in (lo - step, hi + step):
        with pytest.raises(ValueError, match=rf"{re.escape(spec.name)}.*{re.escape(repr(bad))}"):
            Degradations(**{field: bad})


@pytest.mark.parametrize(("field", "bad"), [
    ("noise_sigma", 128.5), ("gamma", 0.05), ("gamma", 10.5), ("jpeg_quality", 50.5),
])
def test_degradations_refuse_what_the_parameter_refuses(field, bad):
    key = PARAM_NAMES[field]
    with pytest.raises(ValueError, match=re.escape(key)):
        parse_overrides([f"{key}={bad}"])
    with pytest.raises(ValueError, match=rf"{re.escape(key)}.*{re.escape(repr(bad))}"):
        Degradations(**{field: bad})


def test_set_degradations_through_make_sample(renderer, clean):
    sets = parse_overrides(["degrade.noise_sigma=4:8", "degrade.jpeg_quality=40"])
    a = make_sample("eyrc", seed=11, index=0, renderer=renderer, overrides=sets)
    b = make_sample("eyrc", seed=11, index=0, renderer=renderer, overrides=sets)
    assert a.rgb.tobytes() == b.rgb.tobytes()
    assert a.rgb.tobytes() != clean.rgb.tobytes()
    assert 4 <= a.gt["params"]["degrade.noise_sigma"] < 8
    assert a.gt["params"]["degrade.jpeg_quality"] == 40
    # Photometric degradations never touch the geometry.
    for key in ("count", "area", "markers", "obstacles", "homography"):
        assert a.gt[key] == clean.gt[key], key
    # Drawing the new parameters does not shift the scene's own draws.
    assert {k: v for k, v in a.gt["params"].items() if not k.startswith("degrade.")} == {
        k: v for k, v in clean.gt["params"].items() if not k.startswith("degrade.")}


# ----------------------------------------------------------------------------- lens model

K = np.array([[866.0, 0.0, 499.5], [0.0, 866.0, 499.5], [0.0, 0.0, 1.0]])
DISTS = [(-0.3, 0.1, 0.0, 0.0, 0.0), (0.2, 0.0, 0.01, -0.01, 0.0),
         (-0.1, 0.02, -0.005, 0.008, 0.01)]


@pytest.mark.parametrize("dist", DISTS)
def test_distort_points_is_opencv_projection_and_undistort_inverts_it(dist):
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 1000, size=(200, 2))
    d = distort_points(pts, K, dist)
    rays = np.column_stack([(pts - K[:2, 2]) / K[0, 0], np.ones(len(pts))])
    ref, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, np.array(dist))
    assert np.allclose(d, ref.reshape(-1, 2), atol=1e-9)
    assert np.allclose(undistort_points(d, K, dist), pts, atol=1e-6)
    assert np.array_equal(distort_points(pts, K, (0.0,) * 5), pts)


@pytest.mark.parametrize("dist", DISTS)
def test_lens_canvas_map_sends_each_output_pixel_to_its_pinhole_source(dist):
    canvas = lens_canvas(K, dist, 1000, 1000)
    rng = np.random.default_rng(1)
    px = rng.integers(0, 1000, size=(300, 2))
    src = np.column_stack([canvas.map_x[px[:, 1], px[:, 0]], canvas.map_y[px[:, 1], px[:, 0]]])
    # canvas px -> pinhole px of the original K, then distort: back to the output pixel.
    offset = K[:2, 2] - canvas.K[:2, 2]
    back = distort_points(src + offset, K, dist)
    assert np.abs(back - px).max() < 0.02
    assert canvas.width >= 1000 and canvas.height >= 1000


def test_lens_distortion_that_folds_over_is_refused():
    with pytest.raises(ValueError, match="folds over"):
        lens_canvas(K, (-1.0, 0.0, 0.0, 0.0, 0.0), 1000, 1000)


def test_densify_keeps_vertices_and_bounds_the_step():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    d = densify(square, step_px=3.0)
    for v in square:
        assert np.any(np.all(d == v, axis=1))
    gaps = np.linalg.norm(np.diff(np.vstack([d, d[:1]]), axis=0), axis=1)
    assert gaps.max() <= 3.0 + 1e-9


def test_standard_normal_is_seeded_by_the_generator_only():
    threads = cv2.getNumThreads()
    try:
        cv2.setNumThreads(1)
        a = standard_normal((200, 300, 3), np.random.default_rng(5))
        cv2.setRNGSeed(123)  # someone else touching OpenCV's RNG must not matter
        cv2.setNumThreads(4)
        b = standard_normal((200, 300, 3), np.random.default_rng(5))
    finally:
        cv2.setNumThreads(threads)
    np.testing.assert_array_equal(a, b)
    c = standard_normal((200, 300, 3), np.random.default_rng(6))
    assert not np.array_equal(a, c)
    assert a.dtype == np.float32 and a.shape == (200, 300, 3)
    assert abs(float(a.mean())) < 0.02
    for channel in range(3):
        assert abs(float(a[..., channel].std()) - 1.0) < 0.02


def test_standard_normal_seen_again_is_the_same_field_and_a_copy():
    """The last field is kept per thread: the same seed and shape give the same samples as a
    fresh draw, in an array the caller may change."""
    shape = (40, 30, 3)

    def direct(seed_rng):
        out = np.empty(shape, np.float32)
        cv2.setRNGSeed(int(seed_rng.integers(0, 2**31 - 1)))
        cv2.randn(out.reshape(-1, 3), 0.0, 1.0)
        return out

    first = standard_normal(shape, np.random.default_rng(7))
    want = direct(np.random.default_rng(7))
    np.testing.assert_array_equal(first, want)
    first[:] = 0  # the caller's to change
    again = standard_normal(shape, np.random.default_rng(7))
    np.testing.assert_array_equal(again, want)
    assert again.flags.writeable and not np.shares_memory(again, first)
    other = standard_normal(shape, np.random.default_rng(8))
    np.testing.assert_array_equal(other, direct(np.random.default_rng(8)))
    assert not np.array_equal(other, want)
    flat = standard_normal((40, 90), np.random.default_rng(7))  # same seed, other shape
    assert flat.shape == (40, 90)
