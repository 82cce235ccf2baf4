"""The fitted competition example against the real image: what a detector sees, and edges."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from paths import ROOT

from arenabench.generator.model import camera as cam
from arenabench.generator.model.layout import box_vertices
from arenabench.generator.model.scene import load_scene
from arenabench.generator.rendering.edges import linear_to_srgb, srgb_to_linear
from arenabench.generator.rendering.render import Renderer
from arenabench.generator.truth.groundtruth import compute_ground_truth

IMAGE = ROOT / "tests" / "data" / "task1c_image.jpg"
SCENE = ROOT / "generator" / "scenes" / "task1c_example.json"
#: Floor, top face, north face and dark side faces of the example (grey levels).
FACE_LEVELS = (248, 120, 100, 71)


def _outlines(gray: np.ndarray) -> list[tuple[int, float]]:
    """(id, outline length px) in cv2.aruco's detection order, default parameters."""
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_100),
        cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(gray)
    out = []
    for quad, marker_id in zip(corners, ids.ravel(), strict=True):
        q = quad.reshape(4, 2).astype(np.float64)
        out.append((int(marker_id), float(np.linalg.norm(q - np.roll(q, -1, 0), axis=1).sum())))
    return out


def _band(scene, shape) -> np.ndarray:
    """Pixels within 2 px of the boxes' image outlines."""
    K, pose = cam.intrinsics(scene.camera), cam.world_from_camera(scene.camera)
    outline = np.zeros(shape, np.uint8)
    for ob in scene.obstacles:
        hull = cv2.convexHull(cam.project(box_vertices(ob), K, pose).astype(np.float32))
        cv2.polylines(outline, [np.round(hull * 16).astype(np.int32)], True, 1, 1,
                      cv2.LINE_8, 4)
    return cv2.distanceTransform(1 - outline, cv2.DIST_L2, 5) <= 2


def _blended(gray: np.ndarray, band: np.ndarray) -> float:
    """Fraction of the band between the box and floor greys (130..235): blended pixels."""
    return float(((gray >= 130) & (gray <= 235) & band).sum() / band.sum())


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def real() -> np.ndarray:
    return cv2.imread(str(IMAGE), cv2.IMREAD_GRAYSCALE)


@pytest.fixture(scope="module")
def renders(scene):
    out = {}
    for aa in (False, True):
        with Renderer(antialias=aa) as r:
            out[aa] = cv2.cvtColor(r.render(scene).rgb, cv2.COLOR_RGB2GRAY)
    return out


def test_render_gives_the_real_marker_order_and_outlines(real, renders):
    """Same detection order; outline lengths equal to 0.01 px (the camera that rendered the
    example, generator/fitting/competition_world.py, puts every marker corner on the real pixel)."""
    want, got = _outlines(real), _outlines(renders[True])
    assert [i for i, _ in want] == [i for i, _ in got] == [90, 95, 85, 80]
    for (marker_id, a), (_, b) in zip(want, got, strict=True):
        assert abs(a - b) <= 0.02, (marker_id, a, b)


def _marker_squares(gray: np.ndarray, grow: int = 8) -> np.ndarray:
    """Each detected marker's bounding square grown by ``grow`` px (the union, as a mask)."""
    mask = np.zeros(gray.shape, bool)
    for square in _marker_squares_by_id(gray, grow).values():
        mask |= square
    return mask


def _marker_squares_by_id(gray: np.ndarray, grow: int = 8) -> dict[int, np.ndarray]:
    """Each detected marker's bounding square grown by ``grow`` px, as a mask, by id."""
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_100),
        cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(gray)
    out = {}
    for quad, marker_id in zip(corners, ids.ravel(), strict=True):
        q = quad.reshape(4, 2)
        x0, y0 = np.floor(q.min(axis=0)).astype(int) - grow
        x1, y1 = np.ceil(q.max(axis=0)).astype(int) + grow
        out[int(marker_id)] = np.zeros(gray.shape, bool)
        out[int(marker_id)][max(y0, 0):y1 + 1, max(x0, 0):x1 + 1] = True
    return out


def _warp_corner_greys(gray: np.ndarray) -> tuple[np.ndarray, float]:
    """The four corner pixels (TL, TR, BL, BR) of the inner-corner warp to 1000 px after a
    2 px crop, and that crop's Otsu threshold: what the every-contour styles see."""
    from competition_style import detect_markers, warp_by_id

    bgr = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    corners, ids = detect_markers(bgr)
    warped = cv2.cvtColor(warp_by_id(bgr, corners, ids)[2:-2, 2:-2], cv2.COLOR_BGR2GRAY)
    otsu, _ = cv2.threshold(warped, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    return warped[[0, 0, -1, -1], [0, -1, 0, -1]].astype(int), float(otsu)


def test_marker_pixels_are_close_to_the_real_image(real, renders):
    """Around the markers the render is 0.43 grey levels from the real image on average (the
    issue's target: 2.0; 0.52 at llvmpipe's own level of detail, 4.49 with the 1.047 rad
    camera fitted to the corners, 6.96 with the earlier texture sampling), and no marker's
    square more than 0.5 (measured 0.41-0.49)."""
    squares = _marker_squares(real)
    diff = np.abs(renders[True].astype(float) - real)
    assert diff[squares].mean() <= 0.48, diff[squares].mean()  # measured 0.43
    for marker_id, square in _marker_squares_by_id(real).items():
        assert diff[square].mean() <= 0.55, (marker_id, diff[square].mean())


def test_warp_corner_pixels_stay_above_otsu(real, renders):
    """Every-contour styles count a warp corner pixel darker than Otsu's threshold as an
    obstacle: on the real image all four are lighter (185, 187, 218, 239; threshold 182), and
    so are the render's, within 2 grey levels of the real ones (184, 187, 217, 239); the
    earlier texture sampling gave 148 at the top right, the earlier camera 210 at the top left."""
    want, otsu = _warp_corner_greys(real)
    got, _ = _warp_corner_greys(renders[True])
    assert (want > otsu).all() and (got > otsu).all(), (want, got, otsu)
    assert np.abs(got - want).max() <= 2, (want, got)


def test_jpeg_render_has_the_examples_top_left_warp_corner(real, renders):
    """Through the twin's JPEG (quality 95) the render's warp corners are 185, 186, 219, 241
    (real 185, 187, 218, 239): the top-left one, which Otsu's threshold of a single-box twin
    scene reaches at 184, is the example's 185 (184 at llvmpipe's own level of detail, which
    cost `style_otsu_every_contour` 6 of 200 twin scenes)."""
    from arenabench.imageio import decode_image, encode_jpeg

    bgr = decode_image(encode_jpeg(cv2.cvtColor(renders[True], cv2.COLOR_GRAY2BGR), quality=95))
    want, _ = _warp_corner_greys(real)
    got, _ = _warp_corner_greys(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    assert got[0] == want[0], (want, got)
    assert np.abs(got - want).max() <= 2, (want, got)


def test_antialiased_edges_blend_like_the_real_image(scene, real, renders):
    band = _band(scene, real.shape)
    assert 0.05 <= _blended(real, band) <= 0.11  # measured 0.079
    assert _blended(renders[False], band) <= 0.03  # hard edges: 0.0
    assert 0.06 <= _blended(renders[True], band) <= 0.10  # two edge samples: 0.081
    mad = {aa: float(np.abs(renders[aa].astype(float) - real)[band].mean()) for aa in renders}
    assert mad[True] < mad[False]  # measured 0.64 vs 8.3 grey levels
    assert mad[True] <= 1.0


def _between(gray: np.ndarray, band: np.ndarray) -> np.ndarray:
    """Band pixels more than 5 grey levels from every face and floor level of the example."""
    v = gray[band].astype(int)
    return v[np.abs(v[:, None] - np.array(FACE_LEVELS)[None]).min(axis=1) > 5]


def test_blended_pixels_are_half_blends_in_linear_light(scene, real, renders):
    """The edge model (two samples, averaged in linear light) predicts the blended greys: the
    half blend of a dark side face and the floor, and of the top face and the floor. The real
    image has those and almost no quarter blends (which 4x coverage would give)."""
    floor, top, dark = 248, 120, 71
    halves = [int(linear_to_srgb((srgb_to_linear(a) + srgb_to_linear(floor)) / 2))
              for a in (dark, top)]
    assert halves == [188, 198]
    quarters = [int(linear_to_srgb(srgb_to_linear(a) * (1 - f) + srgb_to_linear(floor) * f))
                for a in (dark, top) for f in (0.25, 0.75)]
    for gray in (real, renders[True]):
        mid = _between(gray, band := _band(scene, real.shape))
        near_half = np.abs(mid[:, None] - np.array(halves)[None]).min(axis=1) <= 6
        near_quarter = np.abs(mid[:, None] - np.array(quarters)[None]).min(axis=1) <= 3
        assert len(mid) > 0.05 * band.sum()
        assert near_half.mean() >= 0.85, near_half.mean()  # real 0.97, render 0.98
        assert near_quarter.mean() <= 0.05, near_quarter.mean()


def test_ground_truth_does_not_depend_on_antialiasing(scene):
    """The GT is a function of the scene alone (no renderer is an input); the instance masks,
    the one pixel product the GT tests compare with, are the same with or without edge
    samples."""
    gt = compute_ground_truth(scene)
    with Renderer(antialias=True) as a, Renderer(antialias=False) as b:
        ma = a.render(scene, masks=True).instance_mask
        mb = b.render(scene, masks=True).instance_mask
    assert np.array_equal(ma, mb)  # the SEG pass never blends
    assert gt["count"] == 2


@pytest.mark.integration
def test_antialiased_render_does_not_depend_on_earlier_scenes():
    """Edge samples on depth ties (a box's bottom edge on the floor) follow the draw order, and
    a renderer may reuse its static layer: neither may depend on what it drew before."""
    from arenabench.generator import make_sample
    from arenabench.generator.parameters.param_values import parse_overrides

    overrides = parse_overrides(["camera.tilt_deg=20"])
    with Renderer() as r:
        alone = make_sample("eyrc-jitter", seed=0, index=4, renderer=r, overrides=overrides)
    with Renderer() as r:
        for index in (7, 6, 5):
            make_sample("eyrc-jitter", seed=0, index=index, renderer=r, overrides=overrides)
        after = make_sample("eyrc-jitter", seed=0, index=4, renderer=r, overrides=overrides)
    assert alone.rgb.tobytes() == after.rgb.tobytes()
