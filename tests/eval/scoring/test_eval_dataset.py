"""Which markers a pipeline is expected to report: those it can see."""

from pathlib import Path

from arenabench.eval.datasets.reader import DatasetItem


def _sample(markers):
    gt = {"count": 1, "area": {"visible_px": 10.0, "footprint_px": 9.0}, "markers": markers}
    return DatasetItem(id="000000", image_path=Path("x.png"), gt_path=Path("x.json"), gt=gt)


def test_occluded_marker_is_not_expected():
    truth = _sample(
        [
            {"id": 80, "in_view": True, "visible": True},
            {"id": 85, "in_view": True, "visible": False},  # in view but occluded
            {"id": 90, "in_view": False, "visible": False},
        ]
    ).truth()
    assert truth.marker_ids == (80,)


def test_older_gt_without_visible_falls_back_to_in_view():
    truth = _sample([{"id": 80, "in_view": True}, {"id": 95, "in_view": False}]).truth()
    assert truth.marker_ids == (80,)
    assert truth.area == 10.0
    assert _sample([]).truth(area_reference="footprint").area == 9.0
