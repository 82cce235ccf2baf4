"""The pipeline on arenas drawn with OpenCV (tests/drawing.py), against analytic truth.

Area conventions: ``total_area`` (default ``area_method="contour"``) is ``cv2.contourArea``,
whose contour runs through the boundary pixels' centres, so it is compared with
``truth.contour_area_px`` (the drawn polygons inset by half a frame pixel);
``area_method="pixels"`` is compared with the exact drawn area ``truth.area_px``.
"""

import cv2
import numpy as np
import pytest
from drawing import STANDARD_BOXES, Box, draw_arena

from arenabench.frame import FrameSpec
from arenabench.pipeline import DetectConfig, detect

REF = DetectConfig()
SEED = DetectConfig(profile="seed")


def centroid(points):
    m = cv2.moments(np.asarray(points, np.float32))
    return [m["m10"] / m["m00"], m["m01"] / m["m00"]]


def assert_matches(det, truth, *, rel=0.01):
    assert det.status == "ok", det.message
    assert det.marker_ids == truth.marker_ids
    assert det.count == truth.count
    assert det.total_area == pytest.approx(truth.contour_area_px, rel=rel)


@pytest.mark.parametrize("rotate", [0, 90, 180, 270])
def test_reference_exact_count_and_area_under_rotation(rotate):
    img, truth = draw_arena(obstacles=STANDARD_BOXES, rotate=rotate)
    det = detect(img, REF)
    assert_matches(det, truth)
    # The frame keeps the arena's orientation: marker 80 is at the frame's NW corner.
    assert det.reference_ids == [80, 85, 90, 95]
    pix = detect(img, REF.with_(area_method="pixels"))
    assert pix.total_area == pytest.approx(truth.area_px, rel=0.01)
    # obstacle contours sit where the boxes were drawn (frame px)
    centres = sorted(centroid(o.contour) for o in det.obstacles)
    drawn = sorted(centroid(p) for p in truth.polygons_frame)
    np.testing.assert_allclose(centres, drawn, atol=2.0)


def test_reference_handles_upright_markers():
    img, truth = draw_arena(obstacles=STANDARD_BOXES, upright=True)
    assert_matches(detect(img, REF), truth)


@pytest.mark.parametrize("upright", [False, True])
def test_reference_outer_corners_mask_markers_and_border_line(upright):
    frame = FrameSpec(corners="outer")
    img, truth = draw_arena(obstacles=STANDARD_BOXES, upright=upright, frame=frame)
    det = detect(img, DetectConfig(frame=frame))
    assert_matches(det, truth)


def test_reference_other_id_layout_and_dictionary():
    img, truth = draw_arena(obstacles=STANDARD_BOXES[:2], ids=(3, 7, 12, 20),
                            dictionary="DICT_5X5_50", marker_side=70)
    det = detect(img, REF)
    assert det.dictionary == "DICT_5X5_50"
    assert_matches(det, truth)


def test_reference_empty_arena_finds_nothing():
    img, _truth = draw_arena(obstacles=())
    det = detect(img, REF)
    assert det.status == "ok"
    assert (det.count, det.total_area) == (0, 0.0)


def test_min_area_threshold_filters_small_blobs():
    boxes = (Box(300, 300, 200, 150), Box(700, 700, 18, 18))  # 324 px^2 < 500
    img, _ = draw_arena(obstacles=boxes)
    assert detect(img, REF).count == 1
    assert detect(img, REF.with_(min_area=100.0)).count == 2


def test_coloured_and_dark_lit_obstacles():
    boxes = (Box(300, 300, 220, 160, color=(40, 200, 230)),  # yellow-ish, light in gray
             Box(700, 650, 180, 220, color=(60, 60, 60)))    # dark "side face" grey
    img, truth = draw_arena(obstacles=boxes)
    assert_matches(detect(img, REF), truth)


def test_rotated_rectangles():
    boxes = (Box(300, 350, 240, 140, angle_deg=17), Box(680, 640, 200, 200, angle_deg=45))
    img, truth = draw_arena(obstacles=boxes, rotate=90)
    assert_matches(detect(img, REF), truth)


# --- what the published method (seed) does on the same images --------------------------------


@pytest.mark.parametrize("rotate", [0, 90, 180, 270])
def test_seed_is_right_on_competition_layout_and_survives_rotation(rotate):
    # Marker-local corner indices rotate with the image, so image rotation alone does not
    # break the published method on the competition layout.
    img, truth = draw_arena(obstacles=STANDARD_BOXES, rotate=rotate)
    assert_matches(detect(img, SEED), truth)


def test_seed_counts_markers_and_border_when_markers_are_upright():
    # Upright markers: the published corner indices are the OUTER corners, the warp includes
    # the markers and the border line, and their dark pixels count as obstacles.
    img, truth = draw_arena(obstacles=STANDARD_BOXES, upright=True)
    det = detect(img, SEED)
    assert det.status == "ok"
    assert det.count > truth.count
    ref = detect(img, REF)
    assert ref.count == truth.count


def test_seed_twists_the_frame_when_ids_are_laid_out_differently():
    img, truth = draw_arena(obstacles=STANDARD_BOXES, ids=(95, 80, 85, 90))
    seed = detect(img, SEED)
    assert abs(seed.total_area / truth.contour_area_px - 1) > 0.05
    assert_matches(detect(img, REF), truth)


# --- markers missing --------------------------------------------------------------------------


@pytest.mark.integration
def test_three_markers_is_markers_not_found_with_found_ids():
    img, _ = draw_arena(obstacles=STANDARD_BOXES)
    img[860:930, 860:930] = 248  # erase the SE marker (90)
    for cfg in (REF, SEED):
        det = detect(img, cfg)
        assert det.status == "markers_not_found"
        assert det.marker_ids == [80, 85, 95]
        assert (det.count, det.total_area, det.homography) == (0, 0.0, None)
        assert "3 marker" in det.message


def test_blank_image_is_markers_not_found():
    det = detect(np.full((300, 400, 3), 200, np.uint8))
    assert det.status == "markers_not_found"
    assert det.marker_ids == []
    assert det.dictionary is None


def test_reference_falls_back_to_grayscale_when_threshold_hides_markers():
    img, truth = draw_arena(obstacles=STANDARD_BOXES[:1])
    # Low-contrast print: marker black at 90 is above the global threshold 70.
    dark = img < 50
    img[dark] = 90
    det = detect(img, REF)
    assert det.details["marker_source"] == "gray"
    assert_matches(det, truth)
    assert detect(img, SEED).status == "markers_not_found"


def test_homography_maps_truth_reference_corners():
    img, truth = draw_arena(obstacles=STANDARD_BOXES, rotate=180)
    det = detect(img, REF)
    h = np.array(det.homography)
    pts = np.hstack([truth.reference_corners_image, np.ones((4, 1))]) @ h.T
    pts = pts[:, :2] / pts[:, 2:]
    np.testing.assert_allclose(pts, FrameSpec().corners_px(), atol=2.0)


def test_non_square_input_is_resized_and_homography_composed():
    img, truth = draw_arena(obstacles=STANDARD_BOXES)
    wide = cv2.resize(img, (1300, 900), interpolation=cv2.INTER_AREA)
    det = detect(wide, REF)
    assert det.count == truth.count
    assert det.total_area == pytest.approx(truth.contour_area_px, rel=0.015)
    scale = np.array([1300 / 1000, 900 / 1000])
    ref_wide = (truth.reference_corners_image + 0.5) * scale - 0.5
    h = np.array(det.homography)
    pts = np.hstack([ref_wide, np.ones((4, 1))]) @ h.T
    np.testing.assert_allclose(pts[:, :2] / pts[:, 2:], FrameSpec().corners_px(), atol=3.0)
