"""The pipeline on the competition's published example image (tests/data/task1c_image.jpg)."""

import json

import cv2
import numpy as np
import pytest
from paths import TESTS

from arenabench.frame import FrameSpec
from arenabench.pipeline import DetectConfig, Detection, detect
from arenabench.pipeline.geometry import apply_homography

EXAMPLE = TESTS / "data" / "task1c_image.jpg"
PUBLISHED_AREA = 72141.5
# Corners measured on the example (x, y px), cv2.aruco order.
KNOWN_CORNERS = {
    80: [[177, 228], [129, 229], [130, 183], [177, 182]],
    85: [[874, 227], [826, 228], [823, 182], [871, 181]],
    90: [[901, 953], [850, 954], [847, 901], [898, 899]],
    95: [[153, 954], [102, 953], [105, 900], [156, 901]],
}


@pytest.fixture(scope="module")
def image():
    img = cv2.imread(str(EXAMPLE))
    assert img is not None
    return img


@pytest.mark.parametrize("profile", ["reference", "seed"])
def test_example_reproduces_published_result(image, profile):
    det = detect(image, DetectConfig(profile=profile))
    assert det.status == "ok"
    assert det.marker_ids == [80, 85, 90, 95]
    assert det.dictionary == "DICT_4X4_100"
    assert det.count == 2
    assert det.total_area == pytest.approx(PUBLISHED_AREA, rel=0.01)
    assert len(det.obstacles) == 2
    assert sum(o.area for o in det.obstacles) == pytest.approx(PUBLISHED_AREA, rel=0.01)


def test_example_corners_and_homography(image):
    det = detect(image)
    for mid, corners in KNOWN_CORNERS.items():
        np.testing.assert_allclose(det.marker_corners[mid], corners, atol=2.5)
    # Reference corners are the inner ones: corner 0/1/2/3 of 80/85/90/95 (upside-down markers).
    expected = [KNOWN_CORNERS[80][0], KNOWN_CORNERS[85][1], KNOWN_CORNERS[90][2],
                KNOWN_CORNERS[95][3]]
    np.testing.assert_allclose(det.reference_corners, expected, atol=2.5)
    assert det.reference_ids == [80, 85, 90, 95]
    mapped = apply_homography(np.array(det.homography), np.array(det.reference_corners))
    np.testing.assert_allclose(mapped, [[0, 0], [1000, 0], [1000, 1000], [0, 1000]], atol=1e-6)


def test_seed_and_reference_pick_the_same_corners_on_the_example(image):
    seed = detect(image, DetectConfig(profile="seed"))
    ref = detect(image, DetectConfig(profile="reference"))
    np.testing.assert_allclose(seed.reference_corners, ref.reference_corners, atol=1e-9)


def test_detection_serialises_to_json_and_back(image):
    det = detect(image)
    data = json.loads(det.to_json())
    for key in ("status", "dictionary", "marker_ids", "count", "total_area", "homography",
                "obstacles", "timings_ms", "marker_corners"):
        assert key in data
    assert data["marker_corners"]["80"][0] == pytest.approx(det.marker_corners[80][0])
    again = Detection.from_dict(data)
    assert again.to_dict() == det.to_dict()
    assert set(det.timings_ms) >= {"resize", "grayscale", "threshold", "markers", "homography",
                                   "warp", "segment", "contours"}


def test_resized_input_keeps_homography_in_input_pixels(image):
    big = cv2.resize(image, (1600, 1200), interpolation=cv2.INTER_LINEAR)
    det = detect(big)
    assert det.image_size == [1600, 1200]
    assert det.count == 2
    assert det.total_area == pytest.approx(PUBLISHED_AREA, rel=0.01)
    scaled = np.array(KNOWN_CORNERS[80], float) * [1.6, 1.2]
    np.testing.assert_allclose(det.marker_corners[80], scaled, atol=4.0)
    mapped = apply_homography(np.array(det.homography), np.array(det.reference_corners))
    np.testing.assert_allclose(mapped, [[0, 0], [1000, 0], [1000, 1000], [0, 1000]], atol=1e-6)


def test_no_resize_and_other_frame_size(image):
    det = detect(image, DetectConfig(resize=None, frame=FrameSpec(size=500)))
    assert det.count == 2
    # a 500 px frame has a quarter of the area
    assert det.total_area == pytest.approx(PUBLISHED_AREA / 4, rel=0.015)


def test_grayscale_and_bgra_inputs(image):
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    bgra = cv2.cvtColor(image, cv2.COLOR_BGR2BGRA)
    for img in (gray, gray[:, :, None], bgra):
        for profile in ("reference", "seed"):
            det = detect(img, DetectConfig(profile=profile))
            assert det.count == 2
            assert det.total_area == pytest.approx(PUBLISHED_AREA, rel=0.01)


@pytest.mark.parametrize(
    "bad, fragment",
    [
        (np.zeros((100, 100, 3), np.uint16), "uint8"),
        (np.zeros((100, 100, 2), np.uint8), "shape"),
        (np.zeros((8, 8, 3), np.uint8), "16 x 16"),
        ([[1, 2], [3, 4]], "numpy array"),
    ],
)
def test_detect_rejects_unsupported_arrays(bad, fragment):
    with pytest.raises(ValueError, match=fragment):
        detect(bad)
