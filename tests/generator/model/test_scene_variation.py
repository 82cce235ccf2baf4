"""Scene-side variations and lens distortion, checked against cv2.aruco on real renders.

Lens distortion, image sizes, dictionaries, camera headings and marker orientation: the GT
corners agree with cv2.aruco's detections (<= 1 px). Shadows, uneven light and floor
distractors change the image but never the GT count or areas; occluded and partly out-of-view
markers are recorded in the GT.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from marks import integration_but
from shapely.geometry import Polygon

from arenabench.generator.dataset.make import make_sample
from arenabench.generator.model.distractors import patch_corners
from arenabench.generator.model.layout import marker_square
from arenabench.generator.model.lens import undistort_points
from arenabench.generator.model.lights import shadow_alpha
from arenabench.generator.model.scene import Scene
from arenabench.generator.parameters.param_values import parse_overrides

SEED = 5


def _sample(renderer, sets, *, index=0, masks=False):
    return make_sample("eyrc-jitter", seed=SEED, index=index, renderer=renderer, masks=masks,
                       overrides=parse_overrides(sets))


def _detect(bgr: np.ndarray, dictionary: str) -> dict[int, np.ndarray]:
    """cv2.aruco detection with corners refined by cv2.cornerSubPix (3 x 3 window)."""
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    corners, ids, _ = cv2.aruco.ArucoDetector(d).detectMarkers(gray)
    if ids is None:
        return {}
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 0.001)
    return {int(i): cv2.cornerSubPix(gray, np.asarray(c, np.float32).reshape(-1, 1, 2), (3, 3),
                                     (-1, -1), crit).reshape(4, 2)
            for i, c in zip(ids.ravel(), corners, strict=True)}


def _assert_gt_matches_aruco(sample, tol_px: float = 1.0) -> None:
    dictionary = sample.gt["markers"][0]["dictionary"]
    found = _detect(sample.bgr, dictionary)
    want = {m["id"] for m in sample.gt["markers"] if m["visible"]}
    assert set(found) == want, (sorted(found), sorted(want))
    for m in sample.gt["markers"]:
        if m["id"] in found:
            err = np.abs(found[m["id"]] - np.asarray(m["corners_px"])).max()
            assert err <= tol_px, (m["id"], err)


def _geometry(gt):
    return {k: gt[k] for k in ("count", "components", "area", "homography")}


# ------------------------------------------------------------------------------- lens


LENSES = [
    ["camera.k1=-0.3", "camera.k2=0.08"],
    ["camera.k1=0.15", "camera.p1=0.01", "camera.p2=-0.008"],
    ["camera.k1=-0.2", "camera.p1=-0.01", "camera.p2=0.01", "camera.k3=0.05",
     "camera.tilt_deg=15", "camera.altitude_m=10"],
]


@pytest.mark.parametrize("lens", integration_but(LENSES, first=1))
def test_distorted_gt_corners_match_aruco_and_h_stays_undistorted(renderer, lens):
    for index in range(2):
        s = _sample(renderer, lens, index=index, masks=True)
        assert s.gt["camera"]["dist"] != [0.0] * 5
        assert s.gt["homography_domain"] == "undistorted"
        _assert_gt_matches_aruco(s)
        # Undistorting the detected reference corners and applying H hits the frame corners.
        found = _detect(s.bgr, "DICT_4X4_100")
        K = np.asarray(s.gt["camera"]["K"])
        dist = s.gt["camera"]["dist"]
        H = np.asarray(s.gt["homography"])
        ref = np.array([found[80][0], found[85][1], found[90][2], found[95][3]])
        p = np.column_stack([undistort_points(ref, K, dist), np.ones(4)]) @ H.T
        frame = p[:, :2] / p[:, 2:]
        assert np.abs(frame - [[0, 0], [1000, 0], [1000, 1000], [0, 1000]]).max() < 2.0
        # Obstacle image polygons are distorted like the image: they match the masks.
        for i, ob in enumerate(s.gt["obstacles"]):
            mask = (s.render.instance_mask == i + 1).astype(np.uint8)
            poly = np.zeros_like(mask)
            cv2.fillPoly(poly, [np.round(np.asarray(ob["image_polygon_px"]) * 16).astype(
                np.int32)], 1, shift=4)
            # fillPoly also paints the pixels the outline crosses: the polygon is about one
            # boundary pixel larger than the mask, and the mask lies inside it.
            iou = (mask & poly).sum() / (mask | poly).sum()
            assert iou > 0.95, (i, iou)
            assert (mask & (1 - poly)).sum() <= 0.002 * mask.sum(), i


def test_lens_scenes_re_render_from_their_gt(renderer):
    s = _sample(renderer, LENSES[1] + ["lighting.shadow_strength=1", "distractors.tapes=3",
                                       "lighting.spot_strength=0.5"])
    again = renderer.render(Scene.from_dict(s.gt["scene"]))
    assert again.rgb.tobytes() == s.rgb.tobytes()


# ------------------------------------------------------------ image size, dictionaries, pose


@pytest.mark.parametrize("size", [(640, 480), (1920, 1080)])
def test_non_square_images_keep_gt_consistent_with_aruco(renderer, size):
    s = _sample(renderer, [f"camera.width={size[0]}", f"camera.height={size[1]}"])
    assert s.rgb.shape == (size[1], size[0], 3)
    assert s.gt["image_size"] == list(size)
    K = np.asarray(s.gt["camera"]["K"])
    assert K[0, 0] == K[1, 1]  # square pixels
    assert K[0, 2] == pytest.approx((size[0] - 1) / 2) and K[1, 2] == pytest.approx(
        (size[1] - 1) / 2)
    _assert_gt_matches_aruco(s)


@pytest.mark.parametrize("dictionary, ids", [
    ("DICT_5X5_100", "1,22,50,99"),
    ("DICT_6X6_250", "0,100,200,249"),
    ("DICT_APRILTAG_36h11", "3,17,300,586"),
    ("DICT_4X4_50", "0,7,21,49"),
])
def test_other_dictionaries_and_ids_are_found_with_the_gt_ids(renderer, dictionary, ids):
    s = _sample(renderer, [f"markers.dictionary={dictionary}", f"markers.ids={ids}"])
    assert [m["id"] for m in s.gt["markers"]] == [int(i) for i in ids.split(",")]
    assert all(m["dictionary"] == dictionary for m in s.gt["markers"])
    _assert_gt_matches_aruco(s)


def test_an_id_outside_the_dictionary_is_refused(renderer):
    with pytest.raises(ValueError, match="not in DICT_4X4_50"):
        _sample(renderer, ["markers.dictionary=DICT_4X4_50", "markers.ids=80,85,90,95"])


@pytest.mark.parametrize("sets", integration_but([
    ["camera.yaw_deg=180"],
    ["camera.yaw_deg=-180"],
    ["camera.yaw_deg=-135", "camera.altitude_m=12.5:13"],
    ["camera.yaw_deg=90", "camera.tilt_deg=20", "camera.altitude_m=11"],
    ["camera.yaw_deg=-180:180", "camera.altitude_m=12.5:13"],
], first=2))
def test_camera_heading_all_the_way_round(renderer, sets):
    for index in range(2):
        s = _sample(renderer, sets, index=index)
        assert all(m["in_view"] for m in s.gt["markers"])
        _assert_gt_matches_aruco(s)


def test_upright_markers_put_corner_0_at_the_top_left(renderer):
    s = _sample(renderer, ["markers.rotation_deg=0", "camera.tilt_deg=0", "camera.yaw_deg=0",
                           "camera.roll_deg=0"])
    _assert_gt_matches_aruco(s)
    for m in s.gt["markers"]:
        c = np.asarray(m["corners_px"])
        assert np.argmin(c.sum(axis=1)) == 0, m  # top-left in the image
    competition = _sample(renderer, ["camera.tilt_deg=0", "camera.yaw_deg=0",
                                     "camera.roll_deg=0"])
    for m in competition.gt["markers"]:
        assert np.argmax(np.asarray(m["corners_px"]).sum(axis=1)) == 0, m  # bottom-right


# ----------------------------------------------------------------- lights and distractors


def test_shadows_darken_the_floor_but_never_change_the_gt(renderer):
    base = ["lighting.elevation_deg=35", "obstacles.height_m=0.6:0.9"]
    clean = _sample(renderer, base)
    shaded = _sample(renderer, [*base, "lighting.shadow_strength=1"])
    assert _geometry(shaded.gt) == _geometry(clean.gt)
    assert shaded.gt["params"]["lighting.shadow_strength"] == 1.0
    a, b = clean.rgb.astype(float), shaded.rgb.astype(float)
    assert np.all(b <= a + 1)
    darker = (a - b).max(axis=2) > 3
    assert darker.mean() > 0.01  # a visible shadow
    alpha = shadow_alpha(Scene.from_dict(shaded.gt["scene"]).lighting)
    ratio = np.median(b[darker][:, 0] / a[darker][:, 0])
    assert ratio == pytest.approx(1 - alpha, abs=0.02)


def test_uneven_light_darkens_away_from_the_spot(renderer):
    clean = _sample(renderer, ["camera.tilt_deg=0", "camera.target_x_m=0",
                               "camera.target_y_m=0"])
    spot = _sample(renderer, ["camera.tilt_deg=0", "camera.target_x_m=0", "camera.target_y_m=0",
                              "lighting.spot_strength=0.8", "lighting.spot_radius_m=2"])
    assert _geometry(spot.gt) == _geometry(clean.gt)
    gain = spot.rgb.astype(float).mean(axis=2) / np.maximum(clean.rgb.mean(axis=2), 1)
    h, w = gain.shape
    centre = np.median(gain[h // 2 - 10:h // 2 + 10, w // 2 - 10:w // 2 + 10])
    corner = np.median(gain[:40, :40])
    assert centre > 0.97 and corner < 0.5
    _assert_gt_matches_aruco(spot)


def test_floor_distractors_are_recorded_and_never_counted(renderer):
    clean = _sample(renderer, [])
    busy = _sample(renderer, ["distractors.tapes=6", "distractors.papers=4"])
    patches = busy.gt["scene"]["patches"]
    assert {p["kind"] for p in patches} == {"tape", "paper"} and 2 <= len(patches) <= 10
    assert _geometry(busy.gt) == _geometry(clean.gt)
    assert busy.gt["obstacles"] == clean.gt["obstacles"]
    assert busy.rgb.tobytes() != clean.rgb.tobytes()
    scene = Scene.from_dict(busy.gt["scene"])
    for corner in ("nw", "ne", "se", "sw"):
        x0, x1, y0, y1 = marker_square(scene.arena, scene.markers, corner)
        sq = Polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
        assert all(not Polygon(patch_corners(p)).intersects(sq) for p in scene.patches)
    _assert_gt_matches_aruco(busy)


@pytest.mark.parametrize("marker, fraction", [(2, 0.5), (0, 0.15), (1, 1.0)])
def test_partly_occluded_marker_is_recorded(renderer, marker, fraction):
    s = _sample(renderer, [f"markers.occlusion={fraction}", f"markers.occluded={marker}"])
    for i, m in enumerate(s.gt["markers"]):
        want = fraction if i == marker else 0.0
        # scene coordinates are stored to 1e-6 m, so the fraction is exact to about 1e-5
        assert m["occluded_fraction"] == pytest.approx(want, abs=1e-4)
        assert m["in_view"] and m["visible"] == (i != marker)
    assert _geometry(s.gt) == _geometry(_sample(renderer, []).gt)
    if fraction >= 0.5:
        _assert_gt_matches_aruco(s)  # the occluded marker is not found, the others are
    else:
        # a marker with a small corner covered may still decode (error correction), depending
        # on how the occluder's edge is drawn: only the others are checked
        found = _detect(s.bgr, s.gt["markers"][0]["dictionary"])
        others = {m["id"] for i, m in enumerate(s.gt["markers"]) if i != marker}
        assert others <= set(found)


def test_marker_cut_by_the_image_border_is_out_of_view(renderer):
    # the whole camera fixed (no draw): the view spans x = 1 -+ 8 tan(31.5 deg) = -3.9..5.9 m,
    # so the west markers (outer edge at x = -4 m) are cut by the image border
    s = _sample(renderer, ["camera.markers_in_view=false", "camera.target_x_m=1.0",
                           "camera.target_y_m=0", "camera.altitude_m=8.0", "camera.fov_deg=63",
                           "camera.tilt_deg=0", "camera.yaw_deg=0", "camera.roll_deg=0"])
    by_corner = {m["corner"]: m for m in s.gt["markers"]}
    assert by_corner["ne"]["in_view"] and by_corner["ne"]["in_view_fraction"] == 1.0
    cut = by_corner["nw"]
    assert not cut["in_view"] and not cut["visible"] and 0.0 < cut["in_view_fraction"] < 1.0
    _assert_gt_matches_aruco(s)
