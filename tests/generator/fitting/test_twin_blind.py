"""Blind round trips: a "real" image rendered by the generator with hidden, randomly drawn
parameters (tests/twin_blind.py), ``arenabench twin`` given the image file alone, and every
parameter the twin pins set against what was hidden, within the tolerances of
``twin_blind.TOLERANCES`` (each one justified there); the fitted scene's render within 1.5 grey
levels of the image over the marker squares; and the reference pipeline passing >= 95 % of
scenes of the twin's preset. tools/twin_round_trips.py runs the 20 cases and prints the
figures."""

from __future__ import annotations

import pytest
from twin_blind import TOLERANCES, hidden_case, reference_pass_rate, round_trip

#: Cases run on every test run, as small square images (seed, px): quicker, the same kinds of
#: draws (an ARUCO_ORIGINAL arena turned 180 deg on a plain floor, 4-sample sRGB edges, PNG; a
#: 5x5 one on concrete, 2-sample sRGB edges). At 480 px most cases' markers are too small to
#: decode; 640 px keeps them.
FAST_CASES = ((2, 480), (4, 640))
#: The slow subset of tools/twin_round_trips.py's 20 cases, at their drawn sizes (7: markers
#: printed on a picture floor of 3,836 texels, whose grid the twin has to find).
SLOW_SEEDS = (1, 3, 7)
#: Scenes of each twin the reference pipeline is scored on (tools/twin_round_trips.py: 100).
SCENES = {"fast": 10, "slow": 30}


def _round_trip(case, folder, renderer, scenes: int) -> None:
    result = round_trip(case, folder, renderer)
    failed = {k: v for k, v in result["checks"].items() if not v[2]}
    assert not failed, f"case {case.seed}: (hidden, twin, ok) {failed}"
    assert {"markers.ids", "camera (image px)", "marker squares (grey levels)"} <= set(
        result["checks"])
    rate = reference_pass_rate(folder / "twin", scenes)
    assert rate >= TOLERANCES["pass_rate"][0], (case.seed, rate)


@pytest.mark.acceptance  # a minute or more each on 2 cores
@pytest.mark.parametrize(("seed", "px"), FAST_CASES)
def test_blind_round_trip(seed, px, tmp_path, renderer):
    _round_trip(hidden_case(seed, image_px=px), tmp_path, renderer, SCENES["fast"])


@pytest.mark.acceptance
@pytest.mark.parametrize("seed", SLOW_SEEDS)
def test_blind_round_trip_full_size(seed, tmp_path, renderer):
    _round_trip(hidden_case(seed), tmp_path, renderer, SCENES["slow"])


def test_the_twin_is_given_the_image_alone(tmp_path, renderer):
    """The case's hidden texture lies where the twin is not pointed at, and its folder holds
    nothing else the twin could read."""
    from twin_blind import write_case

    case = next(c for c in map(hidden_case, range(1, 40)) if c.texture is not None)
    image = write_case(case, tmp_path, renderer)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".hidden", image.name]


def test_printed_markers_lie_where_the_generator_places_markers():
    """The cases whose markers are printed on their image texture (tests/twin_blind.py's own
    printer, not the twin's painter): on the texture itself, the detector's sub-pixel corners
    of each marker lie where the generator's layout puts that marker's corners (corner 0
    first, so turned as the case says), within a quarter texel."""
    import cv2
    import numpy as np

    from arenabench.frame import CORNER_ORDER
    from arenabench.generator.model.layout import floor_extent, marker_corners_world

    cases = [c for c in map(hidden_case, range(1, 41)) if c.scene.markers.printed]
    assert len(cases) >= 3 and {c.scene.markers.rotation_deg % 180 for c in cases} == {0, 90}
    for case in cases:
        arena, markers = case.scene.arena, case.scene.markers
        gray = cv2.cvtColor(case.texture, cv2.COLOR_RGB2GRAY)
        e = floor_extent(arena)
        texel = 2.0 * e / gray.shape[1]
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        corners, ids, _ = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(
            getattr(cv2.aruco, markers.dictionary)), params).detectMarkers(gray)
        found = {int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), corners, strict=True)}
        assert sorted(found) == sorted(markers.ids), case.seed
        for corner, marker_id in zip(CORNER_ORDER, markers.ids, strict=True):
            w = marker_corners_world(arena, markers, corner)
            want = np.column_stack([(w[:, 0] + e) / texel, (e - w[:, 1]) / texel]) - 0.5
            assert np.abs(found[marker_id] - want).max() <= 0.25, (case.seed, corner)


#: One case of each preset (tests/twin_blind_presets.py; tools/twin_round_trips.py --presets
#: runs all 42), chosen to cover the variants no preset draws: an AprilTag 36h11 arena, a 5x5
#: one turned 90 deg, a barrel lens, an AprilTag 25h9 one through a pincushion lens.
PRESET_CASES = (("eyrc", 1), ("eyrc-jitter", 2), ("eyrc-upright", 5), ("eyrc-oblique", 4),
                ("eyrc-hard", 1), ("warehouse", 6))


@pytest.mark.acceptance
@pytest.mark.parametrize(("preset", "number"), PRESET_CASES)
def test_blind_case_of_every_preset_gets_a_verdict_it_can_be_held_to(preset, number,
                                                                      tmp_path, renderer):
    """A good twin holds every check against what was hidden and its scenes pass the
    reference pipeline where the image itself does; an image holding what the twin does not
    render, or one it does not reproduce, is called poor."""
    from twin_blind_presets import preset_case, preset_round_trip, reference_passes_image

    result = preset_round_trip(preset_case(preset, number), tmp_path, renderer)
    assert result["verdict"] in {"good", "poor"}, result["causes"]
    assert result["ok"], {k: v for k, v in result.items() if k != "hidden"}
    if result["verdict"] == "poor":
        assert result["causes"], "a poor verdict names what it could not reproduce"
    elif reference_passes_image(result["hidden"]):
        rate = reference_pass_rate(tmp_path / "twin", SCENES["fast"])
        assert rate >= TOLERANCES["pass_rate"][0], rate
