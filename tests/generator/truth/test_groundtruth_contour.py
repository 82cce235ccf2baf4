"""``area.contour_px`` against what it stands for: ``cv2.contourArea`` of the external contours of
the ground-truth visible silhouettes, rasterised into the 1000 x 1000 frame (pixel (i, j) set
when its centre lies inside), on many generated scenes of several presets (no rendering needed).

A raster's area depends on where the edges fall between pixel centres (up to ~0.5 % for the
boxes here), so the check is made twice: against the raster directly (per scene within that
phase noise, centred on 0 over many scenes), and with that phase noise taken out by using the
raster's own pixel count instead of the analytic area, which tests the perimeter term sharply
(a Euclidean half perimeter is ~10 px off per scene, the max-norm one ~0.6 px).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from arenabench.generator.model.sampler import SamplingError, sample_scene
from arenabench.generator.truth.groundtruth import compute_ground_truth, contour_area

SCENES_PER_PRESET = 40
PRESETS = ("eyrc", "eyrc-oblique", "eyrc-hard")
_J, _I = np.mgrid[0:1000, 0:1000].astype(np.float64)


def _raster(geom) -> tuple[float, int]:
    """(sum of cv2.contourArea over external contours, pixel count) of ``geom`` rasterised."""
    shapely.prepare(geom)
    mask = shapely.contains_xy(geom, _I, _J).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return float(sum(cv2.contourArea(c) for c in contours)), int(mask.sum())


@pytest.fixture(scope="module")  # 120 scenes rasterised at 1000 x 1000 (about 10 s): slow tests
def rows() -> list[tuple[float, float, float, int]]:
    out = []
    for preset in PRESETS:
        for index in range(SCENES_PER_PRESET):
            try:
                scene = sample_scene(preset, seed=11, index=index).scene
            except SamplingError:
                continue
            gt = compute_ground_truth(scene)
            polys = [Polygon(o["visible_frame_px"]) for o in gt["obstacles"]
                     if len(o["visible_frame_px"]) >= 3]
            union = shapely.union_all(polys)
            measured, pixels = _raster(union)
            out.append((gt["area"]["contour_px"], gt["area"]["visible_px"], measured, pixels))
    assert len(out) >= 0.9 * SCENES_PER_PRESET * len(PRESETS)
    return out


@pytest.mark.integration
def test_contour_px_matches_rasterised_contour_area(rows):
    contour, _, measured, _ = np.array(rows).T
    rel = (measured - contour) / measured
    # phase noise only: where an edge falls between pixel centres moves whole rows or columns
    # of pixels in or out; axis-aligned boxes (the eyrc twin) show it at its largest
    assert np.abs(rel).max() < 0.01
    # centred on 0: the mean offset is a few px on silhouettes of ~50,000 px
    assert abs(np.mean(measured - contour)) < 5e-4 * np.mean(measured)
    assert np.median(contour / measured) == pytest.approx(1.0, abs=5e-4)


@pytest.mark.integration
def test_contour_px_perimeter_term_with_phase_noise_removed(rows):
    contour, visible, measured, pixels = np.array(rows).T
    predicted = contour - visible + pixels  # the same formula, from the raster's pixel count
    d = measured - predicted
    assert np.abs(d).max() < 6
    assert abs(d.mean()) < 1.5


@pytest.mark.integration
def test_contour_px_is_below_visible_by_about_half_a_perimeter(rows):
    contour, visible, _, _ = np.array(rows).T
    low = 1 - contour / visible
    assert np.all(low > 0) and 0.002 < np.median(low) < 0.03


def test_contour_area_of_a_rectangle_is_what_opencv_gives():
    # 100 x 50 px with edges half-way between pixel centres: 100 x 50 centres inside, the
    # contour through the outer ones encloses (100 - 1) * (50 - 1) = 4851
    rect = shapely.box(10.5, 20.5, 110.5, 70.5)
    assert _raster(rect) == (4851.0, 5000)
    assert contour_area(rect) == 4851.0
    # a 45-degree square: its edges cost half as much per unit of length in the max norm
    diamond = Polygon([(500.5, 300), (700.5, 500), (500.5, 700), (300.5, 500)])
    measured, _ = _raster(diamond)
    assert contour_area(diamond) == pytest.approx(diamond.area - 4 * 200 / 2 + 1)
    assert contour_area(diamond) == pytest.approx(measured, abs=2)


def test_contour_area_fills_holes_and_counts_each_piece():
    ring = shapely.box(0, 0, 100, 100).difference(shapely.box(40, 40, 60, 60))
    assert contour_area(ring) == pytest.approx(100 * 100 - 200 + 1)
    two = shapely.union_all([shapely.box(0, 0, 10, 10), shapely.box(50, 0, 60, 10)])
    assert contour_area(two) == pytest.approx(2 * (100 - 20 + 1))
    assert contour_area(Polygon()) == 0.0
