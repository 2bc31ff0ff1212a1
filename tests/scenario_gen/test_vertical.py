"""Heights: every DEM read and every export says ellipsoidal or orthometric; a declared
vertical datum is converted where PROJ has the geoid grid locally, and labelled where not."""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyproj
import pytest
import rasterio
from pyproj import CRS
from rasterio.transform import from_origin

from scenario_gen import generate, save
from scenario_gen.dem import load_embedded, load_geotiff
from scenario_gen.errors import InputError
from scenario_gen.export import ExportOptions, export
from scenario_gen.vertical import ELLIPSOIDAL, ORTHOMETRIC, UNDECLARED, of_scenario

from .helpers import plane, small

LAT, LON = 36.5492, -84.1425
N = -30.0  # the fake geoid's undulation, metres


def _dem(path: Path, crs: str, scale: float = 1.0) -> Path:
    """A 40 x 40 window of the embedded DEM around the site, labelled ``crs``, values / scale."""
    dem = load_embedded()
    a, _, west, _, e, north = tuple(dem.transform)[:6]
    r0, c0 = int((north - LAT) / -e) - 20, int((LON - west) / a) - 20
    sub = dem.elevation[r0 : r0 + 40, c0 : c0 + 40] / scale
    with rasterio.open(
        path, "w", driver="GTiff", height=40, width=40, count=1, dtype="float32",
        crs=rasterio.crs.CRS.from_user_input(crs),
        transform=from_origin(west + c0 * a, north + r0 * e, a, a),
    ) as ds:  # fmt: skip
        ds.write(sub.astype(np.float32), 1)
    return path


@pytest.fixture
def geoid(tmp_path: Path) -> Iterator[None]:
    """EGM96 as PROJ looks it up (its old name, egm96_15.gtx): a constant N over the site, in
    a folder added to PROJ's search path for this test only."""
    grids = tmp_path / "grids"
    grids.mkdir()
    rows = cols = 11  # 1° x 1° at 0.1°, south-west corner first
    head = struct.pack(">4d2i", 36.0, -85.0, 0.1, 0.1, rows, cols)
    (grids / "egm96_15.gtx").write_bytes(head + np.full(rows * cols, N, ">f4").tobytes())
    old = pyproj.datadir.get_data_dir()
    pyproj.datadir.append_data_dir(str(grids))
    try:
        yield
    finally:
        pyproj.datadir.set_data_dir(old)


def _no_real_grid() -> None:
    from scenario_gen.geodesy import best_transformer

    if pyproj.network.is_network_enabled():
        pytest.skip("PROJ's network access is on here")
    if not isinstance(best_transformer(CRS("EPSG:4326+5773"), CRS(4979)), str):
        pytest.skip("this machine has the EGM96 grid installed")


def test_undeclared_and_embedded_heights_are_labelled(tmp_path) -> None:
    assert load_embedded().heights.reference == ORTHOMETRIC
    dem = load_geotiff(_dem(tmp_path / "plain.tif", "EPSG:4326"), 64)
    assert dem.heights.reference == UNDECLARED
    assert "not declared" in dem.heights.label()
    scn = generate(plane(), seed=0)
    assert of_scenario(scn.info).reference == ELLIPSOIDAL
    assert "not recorded" in of_scenario({}).label()  # a scenario from before: said so


def test_declared_datum_without_its_grid_stays_orthometric(tmp_path) -> None:
    _no_real_grid()
    plain = load_geotiff(_dem(tmp_path / "plain.tif", "EPSG:4326"), 64)
    dem = load_geotiff(_dem(tmp_path / "egm96.tif", "EPSG:4326+5773"), 64)
    h = dem.heights
    assert (h.reference, h.datum, h.crs) == (ORTHOMETRIC, "EGM96 height", "EPSG:5773")
    assert "us_nga_egm96_15.tif is not installed" in h.label()
    assert dem.crs.to_epsg() == 4326  # the horizontal part
    np.testing.assert_array_equal(dem.elevation, plain.elevation)


def test_declared_datum_with_its_grid_becomes_ellipsoidal(tmp_path, geoid) -> None:
    plain = load_geotiff(_dem(tmp_path / "plain.tif", "EPSG:4326"), 64)
    dem = load_geotiff(_dem(tmp_path / "egm96.tif", "EPSG:4326+5773"), 64)
    assert dem.heights.reference == ELLIPSOIDAL
    assert "converted from EGM96 height" in dem.heights.label()
    np.testing.assert_allclose(dem.elevation, plain.elevation + N, atol=1e-3)


def test_network_access_is_never_used_for_a_grid(tmp_path, geoid) -> None:
    was = pyproj.network.is_network_enabled()
    pyproj.network.set_network_enabled(True)
    try:
        dem = load_geotiff(_dem(tmp_path / "egm96.tif", "EPSG:4326+5773"), 64)
    finally:
        pyproj.network.set_network_enabled(was)
    assert dem.heights.reference == ORTHOMETRIC
    assert "network access is on" in dem.heights.note


def test_vertical_feet_become_metres(tmp_path) -> None:
    ft = 1200.0 / 3937.0  # US survey foot
    plain = load_geotiff(_dem(tmp_path / "plain.tif", "EPSG:4326"), 64)
    dem = load_geotiff(_dem(tmp_path / "ft.tif", "EPSG:4326+6360", scale=ft), 64)
    if dem.heights.reference == ORTHOMETRIC:  # no GEOID18 grid here
        np.testing.assert_allclose(dem.elevation, plain.elevation, atol=1e-3)
        # the heights kept are metres: recorded in NAVD88's metre CRS, not the file's feet
        assert dem.heights.crs == "EPSG:5703" and dem.heights.datum == "NAVD88 height"


def test_a_gis_export_of_a_dem_in_feet_declares_the_metres_it_writes(tmp_path) -> None:
    """Its GeoTIFFs hold metres: their vertical CRS and band unit say so, and the export read
    back as a DEM gives the scenario's heights (the DEM's feet CRS made them 0.3048 × less)."""
    _no_real_grid()
    ft = 1200.0 / 3937.0
    tif = _dem(tmp_path / "ft.tif", "EPSG:4326+6360", scale=ft)
    terrain = {"source": "dem", "path": str(tif), "site": "latlon", "lat": LAT, "lon": LON}
    scn = generate(small(terrain=terrain), seed=0)
    save(scn, tmp_path / "scn", preview=False)
    export(tmp_path / "scn", "gis", tmp_path / "gis", ExportOptions())
    for name in ("terrain.tif", "terrain_utm.tif", "terrain_dem_crs.tif"):
        with rasterio.open(tmp_path / "gis" / name) as ds:
            vert = CRS.from_wkt(ds.crs.to_wkt()).sub_crs_list[1]
            assert vert.to_epsg() == 5703 and vert.axis_info[0].unit_name == "metre", name
            assert ds.units == ("metre",), name
    back = load_geotiff(tmp_path / "gis" / "terrain.tif", 64)
    lat, lon, alt = scn.geo.enu_to_geodetic(scn.plants.x, scn.plants.y, scn.plants.z)
    np.testing.assert_allclose(back.sample_lonlat(lon, lat, "plants"), alt, atol=0.05)


def test_a_raster_of_depths_is_refused(tmp_path) -> None:
    tif = _dem(tmp_path / "depth.tif", "EPSG:4326+6357")  # NAVD88 depth: positive down
    with pytest.raises(InputError, match="declares depths") as e:
        load_geotiff(tif, 64)
    assert e.value.field == "terrain.path"


def _band(path: Path, **meta: tuple) -> Path:
    """Set band metadata (units, scales, offsets) on a written GeoTIFF."""
    with rasterio.open(path, "r+") as ds:
        for key, value in meta.items():
            setattr(ds, key, value)
    return path


def test_the_band_unit_and_gdal_scale_and_offset_are_applied(tmp_path) -> None:
    plain = load_geotiff(_dem(tmp_path / "plain.tif", "EPSG:4326"), 64)
    feet = _band(_dem(tmp_path / "ft.tif", "EPSG:4326", scale=0.3048), units=("ft",))
    np.testing.assert_allclose(load_geotiff(feet, 64).elevation, plain.elevation, atol=1e-3)
    # decimetres above 100 m, as GDAL's scale and offset say (value · 0.1 + 100)
    dm = _dem(tmp_path / "dm.tif", "EPSG:4326", scale=0.1)
    with rasterio.open(dm, "r+") as ds:
        ds.write(ds.read(1) - 1000.0, 1)
    _band(dm, scales=(0.1,), offsets=(100.0,))
    np.testing.assert_allclose(load_geotiff(dm, 64).elevation, plain.elevation, atol=1e-3)
    bad = _band(_dem(tmp_path / "fur.tif", "EPSG:4326"), units=("furlong",))
    with pytest.raises(InputError, match="band unit 'furlong'"):
        load_geotiff(bad, 64)
    with pytest.raises(InputError, match="terrain.vertical_unit"):  # the file says feet
        load_geotiff(feet, 64, vertical_unit="m")


def test_a_dem_in_a_feet_crs_must_say_what_its_heights_are_in(tmp_path) -> None:
    """California's state plane (US survey feet) with heights of no declared unit: metres
    would be a guess that makes a 3° field 10°, so it is refused until terrain.vertical_unit
    says; each answer scales the heights by its unit."""
    z = load_embedded().elevation[100:140, 100:140]
    path = tmp_path / "ca.tif"
    with rasterio.open(
        path, "w", driver="GTiff", height=40, width=40, count=1, dtype="float32",
        crs="EPSG:2227", transform=from_origin(6_000_000.0, 2_100_000.0, 30.0, 30.0),
    ) as ds:  # fmt: skip
        ds.write(z.astype(np.float32), 1)
    with pytest.raises(InputError, match="terrain.vertical_unit") as e:
        load_geotiff(path, 64)
    assert "US survey foot" in str(e.value)
    metres = load_geotiff(path, 64, vertical_unit="m").elevation
    np.testing.assert_allclose(metres, z, atol=1e-3)
    us_ft = load_geotiff(path, 64, vertical_unit="us_ft").elevation
    np.testing.assert_allclose(us_ft, z * 1200.0 / 3937.0, atol=1e-3)


def test_gis_export_labels_orthometric_heights(tmp_path) -> None:
    """Not converted: the GeoTIFFs carry the vertical CRS (a compound CRS), every README and
    the GeoPackage say orthometric, none says ellipsoidal of these values."""
    _no_real_grid()
    tif = _dem(tmp_path / "egm96.tif", "EPSG:4326+5773")
    terrain = {"source": "dem", "path": str(tif), "site": "latlon", "lat": LAT, "lon": LON}
    spec = small(terrain=terrain)
    scn = generate(spec, seed=0)
    save(scn, tmp_path / "scn", preview=False)
    out = tmp_path / "gis"
    export(tmp_path / "scn", "gis", out, ExportOptions())
    for name in ("terrain.tif", "terrain_utm.tif", "terrain_dem_crs.tif"):
        with rasterio.open(out / name) as ds:
            crs = CRS.from_wkt(ds.crs.to_wkt())
            assert crs.is_compound and crs.sub_crs_list[1].to_epsg() == 5773, name
            assert ds.descriptions[0].startswith("elevation (m): orthometric (EGM96 height)")
            assert ds.tags()["AGRINAV_HEIGHTS"].startswith("orthometric")
    readme = (out / "README.md").read_text()
    assert "Heights (the datum's alt and every altitude written here): orthometric" in readme
    assert "ellipsoidal like" not in readme and "with ellipsoidal heights" not in readme
    import sqlite3

    con = sqlite3.connect(out / "layers.gpkg")
    try:
        desc = con.execute("SELECT description FROM gpkg_contents").fetchall()
    finally:
        con.close()
    assert all("heights orthometric (EGM96 height)" in d for (d,) in desc)
    meta = (tmp_path / "scn" / "scenario.json").read_text()
    assert "heights: orthometric (EGM96 height)" in meta
