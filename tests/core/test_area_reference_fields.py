"""The ``--area-reference`` -> GT fields mapping is declared once (gtrecord.AREA_REFERENCE_FIELDS)
and names real GT fields: the area scored and the polygons the HTML report draws."""

from __future__ import annotations

from dataclasses import fields

from arenabench.gtrecord import (
    AREA_REFERENCE_FIELDS,
    AREA_REFERENCES,
    DEFAULT_AREA_REFERENCE,
    AreaRecord,
    ObstacleRecord,
)


def test_area_references_derive_from_the_one_mapping():
    assert AREA_REFERENCES == {k: v.area for k, v in AREA_REFERENCE_FIELDS.items()}
    assert DEFAULT_AREA_REFERENCE in AREA_REFERENCE_FIELDS


def test_each_reference_names_an_area_field_and_obstacle_polygons():
    area_fields = {f.name for f in fields(AreaRecord)}
    polygon_fields = {f.name for f in fields(ObstacleRecord)}
    for name, ref in AREA_REFERENCE_FIELDS.items():
        assert ref.area in area_fields, name
        assert ref.polygons in polygon_fields, name
    # contour_px measures the pixelated visible union: it draws the visible polygons, stated
    assert AREA_REFERENCE_FIELDS["contour"].polygons == AREA_REFERENCE_FIELDS["visible"].polygons
    assert AREA_REFERENCE_FIELDS["footprint"].polygons == "footprint_frame_px"
