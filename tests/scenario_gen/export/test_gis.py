"""GIS export read back with GDAL's tools and rasterio: heights to 1 cm, plants to 1 mm."""

from __future__ import annotations

import csv
import io
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from pyproj import Transformer

from scenario_gen import GeoFrame, Scenario, load
from scenario_gen.export import ExportOptions, export
from scenario_gen.export.gis import local_crs

from .tools import gdal


@pytest.fixture(scope="module")
def gis(dem, tmp_path_factory) -> tuple[Scenario, Path]:
    _, src = dem
    out = tmp_path_factory.mktemp("gis") / "out"
    export(src, "gis", out, ExportOptions())
    return load(src), out


def _run(*cmd: str) -> subprocess.CompletedProcess[str]:
    r = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert r.returncode == 0 and "ERROR" not in r.stderr, (cmd, r.stderr)
    return r


def test_geotiff_heights_and_grid(gis) -> None:
    import rasterio

    scn, out = gis
    gdal("gdalinfo")
    info = json.loads(_run("gdalinfo", "-json", str(out / "terrain.tif")).stdout)
    assert info["size"] == [scn.terrain.shape[1], scn.terrain.shape[0]]
    t = scn.terrain
    with rasterio.open(out / "terrain.tif") as ds:
        z = ds.read(1)[::-1].astype(np.float64)  # back to rows south -> north
        # pixel centres are the terrain nodes, in metres of the ENU frame
        cx, cy = ds.xy(ds.height - 1, 0)
        assert (cx, cy) == pytest.approx((t.x0, t.y0), abs=1e-6)
        assert ds.res == pytest.approx((t.spacing, t.spacing), abs=1e-9)
        crs = ds.crs
    gx, gy = np.meshgrid(t.xs, t.ys)
    _, _, alt = scn.geo.enu_to_geodetic(gx, gy, t.heights)
    assert np.abs(z - alt).max() < 0.01
    # over a field this small, elevation = datum altitude + ENU height to well under 1 cm
    assert np.abs(z - (scn.geo.alt + t.heights)).max() < 0.01
    # the CRS written into the file puts the plants' lat/lon on their ENU x/y (1 mm)
    p = scn.plants
    lat, lon, _ = scn.geo.enu_to_geodetic(p.x, p.y, p.z)
    x, y = Transformer.from_crs("EPSG:4326", crs.to_wkt(), always_xy=True).transform(lon, lat)
    assert np.hypot(x - p.x, y - p.y).max() < 0.001


def test_local_crs_matches_enu_elsewhere() -> None:
    """The scale factor, not luck, makes the CRS match ENU: a high datum, a 1 km square."""
    geo = GeoFrame(46.5, 10.2, 2500.0)
    gx, gy = np.meshgrid(np.linspace(-500, 500, 21), np.linspace(-500, 500, 21))
    lat, lon, _ = geo.enu_to_geodetic(gx, gy, 0.0)
    x, y = Transformer.from_crs("EPSG:4326", local_crs(geo), always_xy=True).transform(lon, lat)
    assert np.hypot(x - gx, y - gy).max() < 0.002
    plain = f"+proj=tmerc +lat_0={geo.lat} +lon_0={geo.lon} +ellps=WGS84"
    x, y = Transformer.from_crs("EPSG:4326", plain, always_xy=True).transform(lon, lat)
    assert np.hypot(x - gx, y - gy).max() > 0.2  # h0·d/R ≈ 28 cm without it


def test_dem_crs_copy_overlays_the_dem(gis) -> None:
    import rasterio

    scn, out = gis
    assert scn.info["dem_crs"] == "EPSG:4326"
    p = scn.plants
    lat, lon, alt = scn.geo.enu_to_geodetic(p.x, p.y, scn.terrain.height_at(p.x, p.y))
    with rasterio.open(out / "terrain_dem_crs.tif") as ds:
        assert ds.crs.to_epsg() == 4326
        got = np.array([v[0] for v in ds.sample(zip(lon, lat, strict=True))], np.float64)
    # bilinear twice over 12 cm sine ridges 0.75 m apart: each pass errs by at most
    # h²/8·|z''| = 0.12²/8 · 0.06·(2π/0.75)² ≈ 8 mm
    assert np.abs(got - alt).max() < 0.02


def test_geopackage_layers_read_back_by_ogr(gis) -> None:
    scn, out = gis
    gdal("ogr2ogr")
    listing = _run("ogrinfo", "-so", "-q", str(out / "layers.gpkg")).stdout
    for name, kind in (
        ("field", "Polygon"),
        ("rows", "3D Line String"),
        ("plants", "3D Point"),
        ("route", "3D Line String"),
    ):
        assert f"{name} ({kind})" in listing
    text = _run(
        "ogr2ogr",
        "-f",
        "CSV",
        "/vsistdout/",
        str(out / "layers.gpkg"),
        "plants",
        "-lco",
        "GEOMETRY=AS_XYZ",
    ).stdout
    rows = list(csv.DictReader(io.StringIO(text)))
    p = scn.plants
    assert [int(r["plant_id"]) for r in rows] == list(range(len(p)))
    lon = np.array([float(r["X"]) for r in rows])
    lat = np.array([float(r["Y"]) for r in rows])
    alt = np.array([float(r["Z"]) for r in rows])
    x, y, z = scn.geo.geodetic_to_enu(lat, lon, alt)
    assert np.abs(np.column_stack([x - p.x, y - p.y, z - p.z])).max() < 0.001
    assert [r["species"] for r in rows] == p.species.tolist()
    # the preview's own reader agrees with GDAL's
    from scenario_gen.export.gpkg import read_geometries

    mine = np.array([g.coords[0] for g in read_geometries(out / "layers.gpkg", "plants")])
    np.testing.assert_allclose(mine, np.column_stack([lon, lat, alt]), rtol=0, atol=1e-12)
    n_rows = _run("ogrinfo", "-so", str(out / "layers.gpkg"), "rows").stdout
    assert f"Feature Count: {len(scn.rows.offsets)}" in n_rows


@pytest.mark.parametrize("driver,ext", [("GPKG", "gpkg"), ("ESRI Shapefile", "shp")])
def test_geojson_converts_with_ogr2ogr(gis, dem, tmp_path, driver, ext) -> None:
    scn, out = gis
    gdal("ogr2ogr")
    _, src = dem
    files = [out / f"{n}.geojson" for n in ("field", "rows", "plants", "route")]
    files += [src / f"{n}.geojson" for n in ("field", "route", "plants")]  # the scenario's own
    for i, f in enumerate(files):
        _run("ogr2ogr", "-f", driver, str(tmp_path / f"{i}_{f.stem}.{ext}"), str(f))
    count = _run("ogrinfo", "-so", "-al", str(tmp_path / f"2_plants.{ext}")).stdout
    assert f"Feature Count: {len(scn.plants)}" in count


def test_heights_are_labelled_as_what_they_are(gis, hill) -> None:
    """A DEM's heights are orthometric (the embedded USGS DEM's: NAVD88), not ellipsoidal: so
    say the GeoTIFF's band, the export's README and scenario.json; a plane's are ellipsoidal."""
    import rasterio

    from scenario_gen.dem import height_reference

    _, out = gis
    with rasterio.open(out / "terrain.tif") as ds:
        band = ds.descriptions[0]
    assert band == "elevation (m, orthometric, NAVD88 (the embedded USGS DEM's vertical datum))"
    assert "ellipsoidal" not in (out / "README.md").read_text()
    assert "orthometric, NAVD88" in (out / "README.md").read_text()
    _, hill_dir = hill
    heights = json.loads((hill_dir / "scenario.json").read_text())["crs"]["heights"]
    assert heights.startswith("ellipsoidal (WGS84)")
    compound = {"dem_crs": "EPSG:26916+5703"}  # UTM 16N + NAVD88 height, as a GeoTIFF may say
    assert height_reference("dem", compound).startswith(
        "orthometric, North American Vertical Datum 1988"
    )
    assert "names no vertical datum" in height_reference("dem", {"dem_crs": "EPSG:4326"})
