"""Fields, rows and routes across longitude ±180° are cut there in GeoJSON and GeoPackage."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import shape

import scenario_gen as sg
from scenario_gen.antimeridian import cut_geometry, split_line, unwrap_lon
from scenario_gen.geojson import field_features, route_features, row_features


def test_unwrap_keeps_consecutive_longitudes_within_180_degrees() -> None:
    np.testing.assert_allclose(unwrap_lon([179.9, -179.9, -179.8]), [179.9, 180.1, 180.2])
    np.testing.assert_allclose(unwrap_lon([10.0, 20.0]), [10.0, 20.0])


def test_an_unwrapped_closed_ring_stays_closed_to_the_bit() -> None:
    """Whole turns are added, not steps summed: a ring whose steps do not sum to exactly zero
    in floating point still ends where it began (GEOS refuses an open ring)."""
    lon = np.array([179.99990043, -179.99998311, -179.99990123, 179.99998765, 179.99990043])
    u = unwrap_lon(lon)
    assert u[-1] == u[0]
    assert np.all(np.abs(np.diff(u)) <= 180.0)
    ring = [[x, y] for x, y in zip(lon, [0.0, 0.0, 1e-4, 1e-4, 0.0], strict=True)]
    out = cut_geometry({"type": "Polygon", "coordinates": [ring]})
    assert out["type"] == "MultiPolygon"  # cut in two, not refused by GEOS


def test_a_line_across_the_antimeridian_is_cut_on_it_with_heights_interpolated() -> None:
    lines = split_line([[179.9, 10.0, 100.0], [-179.9, 10.2, 200.0]])
    assert len(lines) == 2
    (_, a1), (b0, _) = lines
    assert a1[0] == 180.0 and b0[0] == -180.0  # the cut, on both sides
    assert a1[1] == pytest.approx(10.1) and a1[2] == pytest.approx(150.0) and a1[1:] == b0[1:]
    assert split_line([[10.0, 0.0], [11.0, 1.0]]) == [[[10.0, 0.0], [11.0, 1.0]]]


def test_a_polygon_across_the_antimeridian_becomes_two_with_the_same_area() -> None:
    ring = [[179.5, 0.0], [-179.5, 0.0], [-179.5, 1.0], [179.5, 1.0], [179.5, 0.0]]
    out = cut_geometry({"type": "Polygon", "coordinates": [ring]})
    assert out["type"] == "MultiPolygon"
    parts = list(shape(out).geoms)
    assert len(parts) == 2 and sum(p.area for p in parts) == pytest.approx(1.0)
    for p in parts:
        x0, _, x1, _ = p.bounds
        assert -180.0 <= x0 and x1 <= 180.0 and x1 - x0 == pytest.approx(0.5)


@pytest.fixture(scope="module")
def across() -> sg.Scenario:
    """A small field at 60° N whose datum sits 5 m west of the antimeridian."""
    spec = sg.preset(
        "default",
        terrain={"source": "plane", "datum": [60.0, 179.99991, 10.0], "margin": 4.0},
        field={"width": 6.0, "length": 14.0},
        layout={"headland": 2.0},
    )
    return sg.generate(spec, 0)


def test_a_generated_field_across_the_antimeridian_is_written_cut(across: sg.Scenario) -> None:
    (field,) = field_features(across)
    assert field["geometry"]["type"] == "MultiPolygon"
    area = sum(p.area for p in shape(field["geometry"]).geoms)
    lonlat = across.field_lonlat
    # the file's vertices are rounded to 1e-8° (≈ 1 mm on a 6 m field: ≤ 0.1 % of the area)
    assert area == pytest.approx(shape(cut_geometry(lonlat.__geo_interface__)).area, rel=1e-3)
    r = across.route
    rlat, rlon, _ = across.geo.enu_to_geodetic(r.xyz[:, 0], r.xyz[:, 1], r.xyz[:, 2])
    lines = route_features(across, rlat, rlon) + row_features(across)
    assert any(f["geometry"]["type"] == "MultiLineString" for f in lines)
    for f in [field, *lines]:
        lon = np.array(_positions(f["geometry"]["coordinates"]))[:, 0]
        assert (np.abs(lon) <= 180.0).all()
        for part in shape(f["geometry"]).geoms if "Multi" in f["geometry"]["type"] else []:
            x0, _, x1, _ = part.bounds
            assert x1 - x0 < 1.0  # each part stays on its side


def _positions(c: object) -> list[list[float]]:
    if isinstance(c, list) and c and isinstance(c[0], float):
        return [c]
    return [p for x in c for p in _positions(x)]  # type: ignore[attr-defined]


def test_the_gis_export_writes_multi_layers_gdal_reads(across: sg.Scenario, tmp_path: Path) -> None:
    pyogrio = pytest.importorskip("pyogrio")
    from scenario_gen.export import ExportOptions, export_scenario

    export_scenario(across, "gis", tmp_path / "gis", ExportOptions())
    layers = dict(pyogrio.list_layers(tmp_path / "gis" / "layers.gpkg"))
    assert layers["field"] == "MultiPolygon" and layers["route"] == "MultiLineString Z"
    doc = json.loads((tmp_path / "gis" / "field.geojson").read_text())
    assert doc["features"][0]["geometry"]["type"] == "MultiPolygon"


def test_a_field_cut_at_the_antimeridian_reads_back_whole(
    across: sg.Scenario, tmp_path: Path
) -> None:
    """The field.geojson a scenario writes (two halves either side of ±180°, as RFC 7946 asks)
    is read back as the one field it was, centred where it was, and generates the same
    plants and route (the halves' plain centroid lay on the far side of the world, and two
    parts broke every row at the meridian)."""
    from scenario_gen.fieldfile import read_field

    out = sg.save(across, tmp_path / "scn", preview=False)
    field = read_field(out / "field.geojson")
    assert field.geom_type == "Polygon"
    x0, _, x1, _ = field.bounds
    assert x0 < 180.0 < x1 and x1 - x0 < 1.0
    spec = across.spec.replace(
        {"field": {"geojson": str(out / "field.geojson")}, "terrain": {"datum": None}}
    )
    again = sg.generate(spec, 0)
    assert abs(again.geo.lon - across.geo.lon) < 1e-4  # metres, not 180°
    assert len(again.plants) == len(across.plants)
    assert again.route.length == pytest.approx(across.route.length, abs=0.05)
