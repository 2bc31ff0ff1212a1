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
from scenario_gen.export.crs import local_crs, utm_epsg
from scenario_gen.export.gis import NODATA

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


def test_reprojection_leaves_nodata_not_a_0m_border(gis, tmp_path) -> None:
    """gdalwarp into the UTM zone: pixels outside the terrain are NoData, none reads 0 m."""
    import rasterio

    scn, out = gis
    zone = utm_epsg(scn.geo.lat, scn.geo.lon)
    assert zone == 32616
    warped = tmp_path / "utm.tif"
    _run(gdal("gdalwarp"), "-q", "-t_srs", f"EPSG:{zone}", str(out / "terrain.tif"), str(warped))
    with rasterio.open(out / "terrain.tif") as ds:
        assert ds.nodata == NODATA
        lo, hi = float(ds.read(1).min()), float(ds.read(1).max())
    with rasterio.open(warped) as ds:
        assert ds.nodata == NODATA  # GDAL carried the source's NoData over
        z = ds.read(1)
    outside = z == NODATA
    assert 0.01 < outside.mean() < 0.5  # the rotated grid's corners
    assert ((z[~outside] >= lo - 0.01) & (z[~outside] <= hi + 0.01)).all()  # no fake 0 m


def test_utm_copy_has_an_epsg_code(gis) -> None:
    import rasterio
    from scipy import ndimage

    scn, out = gis
    p = scn.plants
    lat, lon, alt = scn.geo.enu_to_geodetic(p.x, p.y, scn.terrain.height_at(p.x, p.y))
    with rasterio.open(out / "terrain_utm.tif") as ds:
        assert ds.crs.to_epsg() == 32616 and ds.nodata == NODATA
        assert ds.res == pytest.approx((scn.terrain.spacing, scn.terrain.spacing))
        x, y = Transformer.from_crs("EPSG:4326", "EPSG:32616", always_xy=True).transform(lon, lat)
        col, row = ~ds.transform @ (x, y)
        got = ndimage.map_coordinates(ds.read(1).astype(float), [row - 0.5, col - 0.5], order=1)
    assert np.abs(got - alt).max() < 0.01  # bilinear over bilinear: mm on flat planting
    assert "EPSG:32616" in (out / "README.md").read_text()


def test_utm_zones() -> None:
    assert utm_epsg(36.5, -84.1) == 32616
    assert utm_epsg(-33.9, 18.4) == 32734  # Cape Town
    assert utm_epsg(60.4, 5.3) == 32632  # Bergen: Norway's widened zone 32
    assert utm_epsg(78.2, 15.6) == 32633  # Svalbard
    assert utm_epsg(84.5, 0.0) is None  # UPS


def test_geopackage_has_a_spatial_index(gis) -> None:
    import sqlite3

    scn, out = gis
    con = sqlite3.connect(out / "layers.gpkg")
    try:
        ext = con.execute(
            "SELECT table_name, column_name FROM gpkg_extensions "
            "WHERE extension_name = 'gpkg_rtree_index'"
        ).fetchall()
        assert sorted(ext) == sorted((n, "geom") for n in ("field", "rows", "plants", "route"))
        for name, _ in ext:
            n = con.execute(f'SELECT count(*) FROM "{name}"').fetchone()[0]
            assert con.execute(f'SELECT count(*) FROM "rtree_{name}_geom"').fetchone()[0] == n
        # each plant's box holds the plant
        got = con.execute(
            "SELECT p.fid, r.minx, r.maxx, r.miny, r.maxy FROM plants p "
            "JOIN rtree_plants_geom r ON r.id = p.fid ORDER BY p.fid"
        ).fetchall()
    finally:
        con.close()
    b = np.array(got)[:, 1:]
    lat, lon, _ = scn.geo.enu_to_geodetic(scn.plants.x, scn.plants.y, scn.plants.z)
    assert ((b[:, 0] <= lon) & (lon <= b[:, 1]) & (b[:, 2] <= lat) & (lat <= b[:, 3])).all()
    for name in ("field", "rows", "plants", "route"):  # GDAL finds and uses it
        sql = f"SELECT HasSpatialIndex('{name}', 'geom')"
        text = _run(gdal("ogrinfo"), "-q", str(out / "layers.gpkg"), "-sql", sql).stdout
        assert "HasSpatialIndex (Integer) = 1" in text, text


def test_a_dem_across_the_antimeridian_exports_its_geographic_copy(tmp_path: Path) -> None:
    """GDAL sizes a longitude/latitude grid over a footprint that crosses 180° at 0 pixels
    wide: the export failed ("Attempt to create 493x0 dataset"). The copy runs its longitudes
    on past 180° and holds the ground's heights."""
    import rasterio
    from rasterio.transform import from_origin

    from scenario_gen import generate

    from ..helpers import small

    res, n = 2e-5, 200  # ≈ 2 m pixels, 400 m across, centred on 180° at 17° S
    lon = 180.0 + (np.arange(n) - n / 2 + 0.5) * res
    lat = -17.0 - (np.arange(n) - n / 2 + 0.5) * res
    z = 50.0 + 300.0 * (lon[None, :] - 180.0) + 200.0 * (lat[:, None] + 17.0)  # a plane
    dem = tmp_path / "dem.tif"
    profile = {"driver": "GTiff", "width": n, "height": n, "count": 1, "dtype": "float32"}
    transform = from_origin(180.0 - n / 2 * res, -17.0 + n / 2 * res, res, res)
    with rasterio.open(dem, "w", crs="EPSG:4326", transform=transform, **profile) as ds:
        ds.write(z.astype(np.float32), 1)
    terrain = {"source": "dem", "path": str(dem), "site": "latlon", "lat": -17.0, "lon": 180.0}
    scn = generate(small(terrain=terrain), seed=0)
    from scenario_gen import save

    save(scn, tmp_path / "scn", preview=False)
    export(tmp_path / "scn", "gis", tmp_path / "gis", ExportOptions())
    p = scn.plants
    plat, plon, alt = scn.geo.enu_to_geodetic(p.x, p.y, scn.terrain.height_at(p.x, p.y))
    assert plon.min() < -179.99 and plon.max() > 179.99  # the field itself crosses
    with rasterio.open(tmp_path / "gis" / "terrain_dem_crs.tif") as ds:
        assert ds.crs.to_epsg() == 4326
        assert ds.bounds.left < 180.0 < ds.bounds.right  # one grid, on past 180°
        got = np.array(
            [v[0] for v in ds.sample(zip(np.where(plon < 0, plon + 360, plon), plat, strict=True))]
        )
    # a plane resampled bilinearly twice: what is left is float32 rounding of ≈ 50 m heights
    assert np.abs(got - alt).max() < 0.01
