"""Field polygons from GeoPackage, Shapefile, KML and projected GeoJSON: the same field as the
WGS84 GeoJSON they were converted from (by GDAL's ogr2ogr, whose PROJ is not pyproj's), the
layer rules, and every bad file one InputError."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from scenario_gen import InputError, generate
from scenario_gen.fieldfile import read_field
from scenario_gen.geodesy import GeoFrame

from .export.tools import gdal, in_ci
from .helpers import plane

LAT, LON = 36.549167, -84.1425  # UTM zone 16N
#: ≈ 1 mm in degrees: what every reprojected copy must match the GeoJSON to
TOL_DEG = 1e-8


def _pyogrio() -> None:
    try:
        import pyogrio  # noqa: F401
    except ImportError:
        msg = "pyogrio not installed (pip install 'agrinav-gym[gis]')"
        if in_ci():
            pytest.fail(f"{msg}; CI must run this test", pytrace=False)
        pytest.skip(msg)


def _ring(geo: GeoFrame, pts: list[tuple[float, float]]) -> list[list[float]]:
    out = []
    for x, y in pts:
        lat, lon, _ = geo.enu_to_geodetic(x, y)
        out.append([round(float(lon), 9), round(float(lat), 9)])
    return out


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 30 x 22 m field with a hole, turned 20° (an axis-aligned one has two long-axis
    directions 180° apart, and which one GEOS reports flips at 1e-9° of noise), WGS84."""
    geo = GeoFrame(LAT, LON, 0.0)
    c, s = np.cos(np.radians(20)), np.sin(np.radians(20))

    def turn(pts: list[tuple[float, float]]) -> list[tuple[float, float]]:
        return [(x * c - y * s, x * s + y * c) for x, y in pts]

    outer = turn([(-15, -11), (15, -11), (15, 11), (-15, 11), (-15, -11)])
    hole = turn([(-2, -2), (-2, 2), (2, 2), (2, -2), (-2, -2)])
    feature = {
        "type": "Feature",
        "properties": {"name": "north"},
        "geometry": {"type": "Polygon", "coordinates": [_ring(geo, outer), _ring(geo, hole)]},
    }
    p = tmp_path_factory.mktemp("fields") / "field.geojson"
    p.write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    return p


def _ogr(*args: str) -> None:
    r = subprocess.run([gdal("ogr2ogr"), *args], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr


def _same(got: shapely.Geometry, ref: shapely.Geometry) -> None:
    assert got.geom_type == ref.geom_type
    assert shapely.hausdorff_distance(got, ref) < TOL_DEG
    assert len(got.interiors) == len(ref.interiors) == 1  # the hole survives every format


@pytest.mark.parametrize(
    "name,args",
    [
        ("utm.gpkg", ["-f", "GPKG", "-t_srs", "EPSG:32616", "-nln", "parcels"]),
        ("mercator.shp", ["-f", "ESRI Shapefile", "-t_srs", "EPSG:3857"]),
        ("field.kml", ["-f", "KML"]),
        ("nad83.gpkg", ["-f", "GPKG", "-t_srs", "EPSG:4269"]),
    ],
)
def test_gdal_formats_give_the_geojson_field(source, tmp_path, name, args) -> None:
    _pyogrio()
    out = tmp_path / name
    _ogr(*args, str(out), str(source))
    _same(read_field(out), read_field(source))


def test_projected_geojson_names_its_crs(source, tmp_path) -> None:
    """What ogr2ogr writes for a UTM layer (a GeoJSON 2008 "crs" member); read without GDAL."""
    out = tmp_path / "utm.geojson"
    _ogr("-f", "GeoJSON", "-lco", "RFC7946=NO", "-t_srs", "EPSG:32616", str(out), str(source))
    assert "urn:ogc:def:crs:EPSG::32616" in out.read_text()
    _same(read_field(out), read_field(source))
    # without its "crs" member the same coordinates are refused as projected
    data = json.loads(out.read_text())
    del data["crs"]
    out.write_text(json.dumps(data))
    with pytest.raises(InputError, match='look projected .*"crs" member'):
        read_field(out)


def test_a_gpkg_field_generates_the_geojson_scenario(source, tmp_path) -> None:
    _pyogrio()
    gpkg = tmp_path / "utm.gpkg"
    _ogr("-f", "GPKG", "-t_srs", "EPSG:32616", str(gpkg), str(source))
    a = generate(plane(field={"geojson": str(source)}), seed=1)
    b = generate(plane(field={"geojson": str(gpkg)}), seed=1)
    assert shapely.hausdorff_distance(a.field, b.field) < 0.001  # metres, ENU
    assert len(a.plants) == len(b.plants) > 100
    assert np.abs(a.plants.x - b.plants.x).max() < 0.001
    assert np.abs(a.plants.y - b.plants.y).max() < 0.001


def _layers(tmp_path: Path, source: Path) -> Path:
    """A GeoPackage with two polygon layers and a point layer."""
    gpkg = tmp_path / "farm.gpkg"
    _ogr("-f", "GPKG", "-nln", "north", str(gpkg), str(source))
    _ogr("-f", "GPKG", "-update", "-nln", "south", str(gpkg), str(source))
    _ogr("-f", "GPKG", "-update", "-nln", "wells", "-dialect", "SQLite", "-sql",
         "SELECT ST_Centroid(geometry) AS geometry FROM field", str(gpkg), str(source))  # fmt: skip
    return gpkg


def test_layer_choice_and_refusals(source, tmp_path) -> None:
    _pyogrio()
    gpkg = _layers(tmp_path, source)
    with pytest.raises(InputError) as e:
        read_field(gpkg)
    assert e.value.field == "field.layer" and "2 polygon layers (north, south)" in str(e.value)
    _same(read_field(gpkg, "south"), read_field(source))
    with pytest.raises(InputError) as e:
        read_field(gpkg, "east")
    assert e.value.field == "field.layer" and "north, south, wells" in str(e.value)
    with pytest.raises(InputError) as e:
        read_field(gpkg, "wells")
    assert e.value.field == "field.layer" and "no Polygon" in str(e.value)
    # a layer chosen in the spec reaches the reader; one without a field file is refused
    scn = generate(plane(field={"geojson": str(gpkg), "layer": "north"}), seed=1)
    assert len(scn.plants) > 100
    with pytest.raises(InputError, match="field.layer"):
        generate(plane(field={"layer": "north"}), seed=1)


def test_kml_folders_without_declared_types(source, tmp_path) -> None:
    """KML layers (folders) declare no geometry type: the one holding polygons is found."""
    _pyogrio()
    gpkg = _layers(tmp_path, source)
    kml = tmp_path / "farm.kml"
    _ogr("-f", "KML", str(kml), str(gpkg), "north", "wells")
    _same(read_field(kml), read_field(source))


def test_bad_files_are_one_input_error(source, tmp_path) -> None:
    _pyogrio()
    shp = tmp_path / "noprj.shp"
    _ogr("-f", "ESRI Shapefile", str(shp), str(source))
    shp.with_suffix(".prj").unlink()
    with pytest.raises(InputError, match="declares no CRS"):
        read_field(shp)
    fake = tmp_path / "fake.gpkg"
    fake.write_bytes(source.read_bytes())
    with pytest.raises(InputError, match="not a GeoPackage file"):
        read_field(fake)
    with pytest.raises(InputError, match="allowed: GeoJSON .* KML"):
        read_field(tmp_path / "field.dxf")
    with pytest.raises(InputError, match="a local file"):
        read_field("/vsicurl/https://example.org/f.gpkg")


def test_a_crs_that_gives_no_longitude_and_latitude_is_refused(source, tmp_path) -> None:
    """A CAD or survey grid (a .prj holding a LOCAL_CS) and GDAL's stand-ins for a missing CRS
    (a GeoPackage written without one reads as "Undefined geographic SRS") are one line each,
    not a PROJ traceback or a field placed by whatever its numbers happen to be."""
    _pyogrio()
    shp = tmp_path / "grid.shp"
    _ogr("-f", "ESRI Shapefile", str(shp), str(source))
    shp.with_suffix(".prj").write_text('LOCAL_CS["Farm grid",UNIT["metre",1]]')
    with pytest.raises(InputError, match="Engineering CRS 'Farm grid'"):
        read_field(shp)
    gpkg = tmp_path / "nocrs.gpkg"
    _ogr("-f", "GPKG", str(gpkg), str(source), "-a_srs", "None")
    with pytest.raises(InputError, match="'Undefined geographic SRS'"):
        read_field(gpkg)


def test_a_kml_whose_root_comes_after_a_long_comment_is_read(source, tmp_path) -> None:
    _pyogrio()
    kml = tmp_path / "f.kml"
    _ogr("-f", "KML", str(kml), str(source))
    text = kml.read_text()
    head = '<?xml version="1.0" encoding="utf-8"?>\n'
    body = text.split("?>", 1)[1] if text.startswith("<?xml") else text
    kml.write_text(head + "<!-- " + "exported by a farm management tool. " * 40 + "-->" + body)
    _same(read_field(kml), read_field(source))


def test_feature_and_layer_limits(source, tmp_path, monkeypatch) -> None:
    _pyogrio()
    from scenario_gen import fieldfile

    gpkg = _layers(tmp_path, source)
    monkeypatch.setattr(fieldfile, "MAX_FIELD_FEATURES", 0)
    with pytest.raises(InputError, match="over 0 features"):
        read_field(gpkg, "north")
    monkeypatch.setattr(fieldfile, "MAX_SCAN_LAYERS", 2)
    with pytest.raises(InputError, match="3 layers, more than the 2 searched"):
        read_field(gpkg)


def test_missing_pyogrio_names_the_extra(source, tmp_path, monkeypatch) -> None:
    gpkg = tmp_path / "f.gpkg"
    gpkg.write_bytes(b"SQLite format 3\x00" + bytes(100))
    monkeypatch.setitem(sys.modules, "pyogrio", None)
    with pytest.raises(InputError, match=r"needs pyogrio: pip install 'agrinav-gym\[gis\]'"):
        read_field(gpkg)


@pytest.mark.parametrize(
    "crs,match",
    [
        ({"type": "link", "properties": {"href": "http://x/crs"}}, "linked CRSs are not fetched"),
        ({"type": "name", "properties": {"name": "+proj=utm +zone=16"}}, "EPSG::<code>"),
        ({"type": "name", "properties": {"name": "EPSG:999999"}}, "not a CRS pyproj knows"),
        ({"type": "name", "properties": {"name": "EPSG:5703"}}, "Vertical CRS 'NAVD88 height'"),
        ({"type": "name", "properties": {"name": "EPSG:4978"}}, "Geocentric CRS"),
    ],
)
def test_geojson_crs_member_is_checked(tmp_path, crs, match) -> None:
    p = tmp_path / "f.geojson"
    square = [[[0, 0], [40, 0], [40, 40], [0, 40], [0, 0]]]
    p.write_text(json.dumps({"type": "Polygon", "crs": crs, "coordinates": square}))
    with pytest.raises(InputError, match=match):
        read_field(p)


def test_a_transformation_without_its_grid_is_refused(tmp_path) -> None:
    """NAD27 -> WGS84 needs a grid; PROJ's fallback would misplace the field by ~100 m."""
    from pyproj import CRS

    from scenario_gen.geodesy import best_transformer

    if not isinstance(best_transformer(CRS(4267), CRS(4326)), str):
        pytest.skip("this machine has the NAD27 grids")
    p = tmp_path / "nad27.geojson"
    ring = [[-84.14, 36.55], [-84.139, 36.55], [-84.139, 36.551], [-84.14, 36.55]]
    name = {"type": "name", "properties": {"name": "EPSG:4267"}}
    p.write_text(json.dumps({"type": "Polygon", "crs": name, "coordinates": [ring]}))
    with pytest.raises(InputError, match="grid .* is not installed"):
        read_field(p)


def test_unclosed_rings_are_closed_alike_in_kml_and_geojson(source, tmp_path) -> None:
    """A ring whose last point does not repeat its first (both specs ask for it; some tools
    omit it) is closed, in KML as in GeoJSON, and GDAL's warning about it is not passed on."""
    import re
    import warnings

    _pyogrio()
    data = json.loads(source.read_text())
    rings = data["features"][0]["geometry"]["coordinates"]
    for ring in rings:
        ring.pop()  # the repeated first point
    geojson = tmp_path / "open.geojson"
    geojson.write_text(json.dumps(data))
    kml = tmp_path / "open.kml"
    _ogr("-f", "KML", str(kml), str(source))

    def drop_last(m: re.Match[str]) -> str:
        points = m.group(2).split()
        assert points[0] == points[-1]
        return m.group(1) + " ".join(points[:-1]) + m.group(3)

    text, n = re.subn(r"(<coordinates>)(.*?)(</coordinates>)", drop_last, kml.read_text())
    assert n == 2  # the outer ring and the hole
    kml.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for path in (geojson, kml):
            _same(read_field(path), read_field(source))
