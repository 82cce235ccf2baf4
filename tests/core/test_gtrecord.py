"""The typed GT record: the writer's, the reader's and the COCO export's one declaration."""

from dataclasses import fields
from pathlib import Path

import pytest

from arenabench.eval.datasets.reader import DatasetItem
from arenabench.gtrecord import AreaRecord, GroundTruth, MarkerRecord, ObstacleRecord
from arenabench.schemas import GT_SCHEMA, gt_problem, gt_schema


@pytest.fixture(scope="module")
def written():
    from arenabench.generator.dataset.make import gt_record
    from arenabench.generator.model.sampler import sample_scene

    return [gt_record(sample_scene(preset, seed=5, index=i).scene, sid=f"{i:06d}",
                      preset=preset, seed=5, index=i)
            for preset in ("eyrc", "eyrc-oblique", "warehouse") for i in range(2)]


def test_round_trip_is_exact_for_what_the_generator_writes(written):
    for gt in written:
        assert gt_problem(gt) is None
        record = GroundTruth.from_dict(gt)
        assert record.to_dict() == gt
        assert GroundTruth.from_dict(record.to_dict()) == record


def test_records_name_every_field_of_the_schema():
    props = gt_schema()["properties"]
    def names(cls):
        return {f.name for f in fields(cls)} - {"extra"}

    assert names(GroundTruth) == set(props)
    assert set(props["markers"]["items"]["properties"]) == names(MarkerRecord)
    assert set(props["obstacles"]["items"]["properties"]) == names(ObstacleRecord)
    assert set(props["area"]["properties"]) <= names(AreaRecord)


def test_typed_access_and_unknown_fields_are_kept(written):
    gt = dict(written[0], later_field={"x": [1, 2]})
    record = GroundTruth.from_dict(gt)
    assert record.schema == GT_SCHEMA
    assert record.count == gt["count"]
    assert record.area.visible_px == gt["area"]["visible_px"]
    assert [m.id for m in record.markers] == [m["id"] for m in gt["markers"]]
    assert record.extra == {"later_field": {"x": (1, 2)}}
    assert record.to_dict() == gt


def test_older_minimal_gt_reads_with_absent_fields_none():
    record = GroundTruth.from_dict(
        {"schema": GT_SCHEMA, "count": 0, "area": {"visible_px": 0.0, "footprint_px": 0.0}})
    assert record.area.contour_px is None and record.markers is None
    assert record.to_dict() == {"schema": GT_SCHEMA, "count": 0,
                                "area": {"visible_px": 0.0, "footprint_px": 0.0}}


def test_missing_required_field_is_named():
    with pytest.raises(ValueError, match="area"):
        GroundTruth.from_dict({"count": 1})


def test_dataset_item_takes_the_record_or_its_json_form(written):
    item = DatasetItem(id="a", image_path=Path("a.png"), gt_path=Path("a.json"), gt=written[0])
    assert isinstance(item.gt, GroundTruth)
    assert item.truth().count == written[0]["count"]
