"""Drawn polygons to a field: holes by nesting, invalid shapes refused, exact round trip."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from shapely.geometry import Polygon, mapping

from baselines.studio import fields
from scenario_gen.errors import InputError
from scenario_gen.fieldfile import read_field


def _fc(*polys: Polygon) -> dict[str, object]:
    return {
        "type": "FeatureCollection",
        "features": [{"type": "Feature", "geometry": mapping(p), "properties": {}} for p in polys],
    }


def _sq(x0: float, y0: float, d: float) -> Polygon:
    return Polygon([(x0, y0), (x0 + d, y0), (x0 + d, y0 + d), (x0, y0 + d)])


def test_nested_polygons_are_holes_and_islands() -> None:
    outer, hole, island = _sq(0, 0, 10), _sq(2, 2, 6), _sq(4, 4, 2)
    geom = fields.combine(fields.polygons_of(_fc(outer, hole, island)))
    assert geom is not None
    assert geom.area == pytest.approx(100 - 36 + 4)
    assert not geom.contains(_sq(3, 3, 0.5).centroid) and geom.contains(_sq(4.5, 4.5, 0.5))


def test_self_intersection_is_refused_with_the_field_named() -> None:
    bowtie = {"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [1, 0], [0, 1], [0, 0]]]}
    with pytest.raises(InputError) as e:
        fields.polygons_of(bowtie)
    assert e.value.field == "field" and "Self-intersection" in str(e.value)


def test_projected_coordinates_are_refused() -> None:
    with pytest.raises(InputError, match="projected"):
        fields.polygons_of(mapping(_sq(500000, 4000000, 100)))


def test_normalised_geometry_is_what_the_generator_reads(tmp_path: Path) -> None:
    p = Polygon([(-84.2, 36.6), (-84.19971234567891, 36.60001), (-84.1997, 36.6003123456789)])
    geom, text = fields.normalise(p)
    f = tmp_path / "f.geojson"
    f.write_text(text)
    assert read_field(f).equals_exact(geom, 0.0)
    assert json.loads(text)["features"][0]["geometry"]["type"] == "Polygon"
