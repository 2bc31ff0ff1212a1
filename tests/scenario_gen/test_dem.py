import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin
from rasterio.warp import Resampling, calculate_default_transform, reproject

from scenario_gen import ScenarioError, generate
from scenario_gen.dem import fill_small_holes, load_embedded
from scenario_gen.errors import Notice

from .helpers import plane, small

SITE = {"site": "latlon", "lat": 36.5492, "lon": -84.1425}


def _write_4326(
    path: Path,
    elev: np.ndarray,
    west: float,
    north: float,
    d: float,
    nodata: float | None = None,
    dtype: str = "float32",
) -> None:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=elev.shape[0],
        width=elev.shape[1],
        count=1,
        dtype=dtype,
        crs="EPSG:4326",
        transform=from_origin(west, north, d, d),
        nodata=nodata,
    ) as ds:
        ds.write(elev.astype(dtype), 1)


@pytest.fixture(scope="module")
def tiffs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    dem = load_embedded()
    d = tmp_path_factory.mktemp("dem")
    a, _, west, _, e, north = tuple(dem.transform)[:6]
    # a 40 x 40 pixel (≈3 x 3.7 km) window around the site, as an int16 EPSG:4326 GeoTIFF
    r0, c0 = int((north - SITE["lat"]) / -e) - 20, int((SITE["lon"] - west) / a) - 20
    sub = dem.elevation[r0 : r0 + 40, c0 : c0 + 40]
    geo = d / "dem_4326.tif"
    _write_4326(geo, sub, west + c0 * a, north + r0 * e, a, dtype="int16")
    utm = d / "dem_utm16n.tif"
    with rasterio.open(geo) as src:
        tr, w, h = calculate_default_transform(
            src.crs, "EPSG:32616", src.width, src.height, *src.bounds, resolution=30.0
        )
        with rasterio.open(
            utm,
            "w",
            driver="GTiff",
            height=h,
            width=w,
            count=1,
            dtype="float32",
            crs="EPSG:32616",
            transform=tr,
            nodata=-9999.0,
        ) as dst:
            reproject(
                rasterio.band(src, 1),
                rasterio.band(dst, 1),
                dst_nodata=-9999.0,
                resampling=Resampling.cubic,
            )
    return {"geo": geo, "utm": utm}


def test_embedded_dem_is_north_up_with_the_documented_bounds() -> None:
    dem = load_embedded()
    a, _b, west, _d, e, north = tuple(dem.transform)[:6]
    rows, cols = dem.shape
    assert (rows, cols) == (344, 403)
    assert north == pytest.approx(36.7329, abs=1e-3) and e < 0  # row 0 is the northern edge
    assert north + rows * e == pytest.approx(36.4463, abs=1e-3)
    assert west == pytest.approx(-84.41375) and west + cols * a == pytest.approx(-84.0779, abs=1e-3)
    # sampling a pixel centre returns that pixel's value (bicubic interpolates, not smooths)
    lon, lat = dem.pixel_to_crs(np.array([100.5]), np.array([200.5]))
    z = dem.sample_lonlat(lon, lat, "test")
    assert z[0] == pytest.approx(dem.elevation[200, 100], abs=1e-6)


def test_geotiff_in_4326_and_utm_give_the_same_field(tiffs: dict[str, Path]) -> None:
    a = generate(small(terrain={"source": "dem", "path": str(tiffs["geo"]), **SITE}), seed=0)
    b = generate(small(terrain={"source": "dem", "path": str(tiffs["utm"]), **SITE}), seed=0)
    la, lo, al = a.geo.enu_to_geodetic(a.plants.x, a.plants.y, a.plants.z)
    lb, lob, alb = b.geo.enu_to_geodetic(b.plants.x, b.plants.y, b.plants.z)
    from pyproj import Geod

    _, _, horizontal = Geod(ellps="WGS84").inv(lo, la, lob, lb)
    assert len(a.plants) == len(b.plants)
    assert np.max(horizontal) < 0.5
    assert np.max(np.abs(al - alb)) < 0.5  # a 30 m cubic reprojection of a 90 m DEM
    assert a.terrain.shape == b.terrain.shape


def test_small_nodata_holes_are_filled_and_large_ones_refused(tmp_path: Path) -> None:
    gx, gy = np.meshgrid(np.arange(60), np.arange(60))
    elev = (300 + 0.5 * gx + 0.2 * gy).astype(np.float32)
    elev[30:32, 30:32] = -9999  # 4 pixels: filled
    elev[5:20, 40:55] = -9999  # 225 pixels: refused under a field
    path = tmp_path / "holes.tif"
    _write_4326(path, elev, -84.2, 36.6, 1 / 1200, nodata=-9999)
    terrain = {"source": "dem", "path": str(path), "site": "latlon", "fill_max_pixels": 64}
    with pytest.warns(Notice, match=r"% of the terrain grid lies over nodata holes"):
        filled = generate(
            small(terrain={**terrain, "lat": 36.6 - 30.5 / 1200, "lon": -84.2 + 30.5 / 1200}),
            seed=0,
        )
    # recorded: the filled ground is interpolated, not measured (the small field's grid lies
    # within 2 of the hole's 93 m pixels, all of which the bicubic surface reads)
    assert filled.info["dem_filled_share"] == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", Notice)
        away = generate(
            small(terrain={**terrain, "lat": 36.6 - 50.5 / 1200, "lon": -84.2 + 10.5 / 1200}),
            seed=0,
        )
    assert away.info.get("dem_filled_share", 0.0) == 0.0  # absent: nothing filled near it
    assert np.isfinite(filled.terrain.heights).all()
    # the filled surface continues the plane (inverse-distance fill), to within a metre
    expect = 300 + 0.5 * 30.5 + 0.2 * 30.5
    assert filled.geo.alt == pytest.approx(expect, abs=1.0)
    with pytest.raises(ScenarioError, match="nodata hole"):
        generate(
            small(
                terrain={
                    "source": "dem",
                    "path": str(path),
                    "site": "latlon",
                    "lat": 36.6 - 12 / 1200,
                    "lon": -84.2 + 47 / 1200,
                }
            ),
            seed=0,
        )


def test_fill_small_holes_keeps_large_ones() -> None:
    a = np.ones((20, 20))
    a[2, 2] = np.nan
    a[10:18, 10:18] = np.nan
    out = fill_small_holes(a, 4)
    assert np.isfinite(out[2, 2]) and out[2, 2] == pytest.approx(1.0)
    assert np.isnan(out[10:18, 10:18]).all()


def test_field_off_the_dem_is_refused(tiffs: dict[str, Path]) -> None:
    with pytest.raises(ScenarioError, match="off the DEM"):
        generate(
            small(
                terrain={
                    "source": "dem",
                    "path": str(tiffs["geo"]),
                    "site": "latlon",
                    "lat": 40.0,
                    "lon": -84.14,
                }
            ),
            seed=0,
        )


def test_a_field_file_with_its_coordinates_swapped_gets_a_hint(
    tiffs: dict[str, Path], tmp_path: Path
) -> None:
    import json

    lonlat = [[-84.1426, 36.5491], [-84.1422, 36.5491], [-84.1422, 36.5494], [-84.1426, 36.5491]]
    for order, hinted in ((lambda c: [c[1], c[0]], True), (lambda c: [c[0] + 3, c[1]], False)):
        path = tmp_path / "field.geojson"
        path.write_text(
            json.dumps({"type": "Polygon", "coordinates": [[order(c) for c in lonlat]]})
        )
        with pytest.raises(ScenarioError) as info:
            generate(small(terrain={"source": "dem", "path": str(tiffs["geo"])},
                           field={"geojson": str(path)}), seed=0)  # fmt: skip
        assert "off the DEM" in str(info.value)
        assert ("coordinates swapped" in str(info.value)) == hinted


def test_site_selection_flattest_and_steepest() -> None:
    flat = generate(small(), seed=0)
    steep = generate(
        small(terrain={"site": "steepest", "max_slope_deg": 15.0}, furrows={"enabled": False}),
        seed=0,
    )

    def slope(scn) -> float:
        zy, zx = np.gradient(scn.terrain.heights, scn.terrain.spacing)
        return float(np.degrees(np.arctan(np.hypot(zx, zy))).mean())

    assert slope(steep) > 5.0 > 1.0 > slope(generate(small(furrows={"enabled": False}), 0))
    assert flat.geo.alt < steep.geo.alt


@pytest.mark.parametrize("degrees", [0.0, 7.0, 14.0])
def test_the_scenario_measures_its_fields_own_slope(degrees: float) -> None:
    """info.slope_deg is the ground's slope over the field: a plane's everywhere, before ridges
    (the crests and flanks of furrows are not the field's slope)."""
    scn = generate(plane(degrees, 30.0, furrows={"enabled": True, "depth": 0.12}), seed=0)
    s = scn.info["slope_deg"]
    # bilinear over a plane's samples is the plane: exact up to the grid's float rounding
    assert s["median"] == pytest.approx(degrees, abs=0.05)
    assert s["max"] == pytest.approx(degrees, abs=0.05)
    assert scn.summary()["slope_deg"] == s


@pytest.mark.parametrize("bands,dtype,needle", [(3, "uint8", "3 bands"), (1, "complex64", "real")])
def test_a_raster_that_is_not_one_elevation_band_is_refused(
    tmp_path: Path, bands: int, dtype: str, needle: str
) -> None:
    """An RGB image or a complex product used to be read as elevation without a word."""
    path = tmp_path / "not_a_dem.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=20,
        width=20,
        count=bands,
        dtype=dtype,
        crs="EPSG:4326",
        transform=from_origin(-84.15, 36.56, 0.001, 0.001),
    ) as ds:
        for b in range(1, bands + 1):
            ds.write(np.ones((20, 20), dtype), b)
    with pytest.raises(ScenarioError, match=needle):
        generate(small(terrain={"source": "dem", "path": str(path)}), seed=0)


def _whole_metres(path: Path, slope_deg: float, lake: bool) -> Path:
    """A 30 m UTM DEM of a plain rising ``slope_deg`` eastward, stored in whole metres as many
    national DEMs are; ``lake``: a 10 x 10 pixel basin held at one level in the middle."""
    n = 120
    x = np.arange(n) * 30.0
    z = 250.0 + np.tan(np.radians(slope_deg)) * np.broadcast_to(x, (n, n))
    z = np.round(z)
    if lake:
        z[50:60, 50:60] = z[50:60, 50:60].min() - 3.0  # the water's surface, below its shore
    with rasterio.open(
        path, "w", driver="GTiff", height=n, width=n, count=1, dtype="int16",
        crs="EPSG:32616", transform=from_origin(500_000.0, 4_000_000.0, 30.0, 30.0),
    ) as ds:  # fmt: skip
        ds.write(z.astype(np.int16), 1)
    return path


@pytest.mark.parametrize("slope_deg", [0.2, 0.5])
def test_a_gentle_slope_in_whole_metres_is_farmland_and_a_basin_is_water(
    tmp_path: Path, slope_deg: float
) -> None:
    """Rounded to whole metres a gentle slope is a staircase of flat terraces, each lower on
    its downhill side; it used to be taken for water everywhere, and no field could be sited
    on the flattest land there is. A flat basin in it stays water."""
    from scenario_gen.dem import load_geotiff, water_mask

    plain = load_geotiff(_whole_metres(tmp_path / "plain.tif", slope_deg, lake=False), 64)
    # the lowest terrace runs off the raster's west edge, where its rim cannot be seen: kept
    # out as a shore would be (at 0.2° a terrace is 1 m / (30 m · tan 0.2°) = 9.5 pixels wide)
    assert not water_mask(plain.elevation)[:, 12:].any()
    lake = load_geotiff(_whole_metres(tmp_path / "lake.tif", slope_deg, lake=True), 64)
    water = water_mask(lake.elevation)
    assert water[51:59, 51:59].all() and water[:, 12:].sum() <= 100  # the basin only
    for site in ("flattest", "steepest"):
        scn = generate(
            small(terrain={"source": "dem", "path": str(tmp_path / "plain.tif"), "site": site}),
            seed=0,
        )
        assert scn.info["dem"] == "plain.tif"


def test_the_embedded_dems_water_is_all_its_flat_areas() -> None:
    """Every flat area of the embedded DEM (a float raster) lies in a basin, so telling
    terraces from water leaves its mask, and every field the benchmark sites on it, as they
    were when every flat area of 12 pixels or more counted as water."""
    from scipy import ndimage

    from scenario_gen.dem import _nearest_fill, water_mask

    e = _nearest_fill(load_embedded().elevation)
    inner = e[1:-1, 1:-1]
    same = np.zeros(e.shape, bool)
    same[1:-1, 1:-1] = (
        (inner == e[:-2, 1:-1]) & (inner == e[2:, 1:-1])
        & (inner == e[1:-1, :-2]) & (inner == e[1:-1, 2:])
    )  # fmt: skip
    labels, n = ndimage.label(same)
    big = np.bincount(labels.ravel()) >= 12
    big[0] = False
    every_flat = ndimage.binary_dilation(big[labels])
    assert n >= 5 and every_flat.any()
    np.testing.assert_array_equal(water_mask(e), every_flat)


def test_a_vertical_unit_without_a_geotiff_is_refused() -> None:
    with pytest.raises(ScenarioError, match="terrain.vertical_unit"):
        generate(small(terrain={"vertical_unit": "ft"}), seed=0)


def test_a_raster_stored_past_180_degrees_is_reached_by_ordinary_longitudes(
    tmp_path: Path,
) -> None:
    """A geographic DEM stored 179.994..180.006° (the 0..360° convention): its flattest site
    comes back as a longitude in -180..180, and a site given at -179.9995° reads the pixel
    stored at 180.0005°."""
    n = 120
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    z = 50.0 + 0.2 * xx + 0.1 * yy + 3.0 * np.sin(xx / 15.0) * np.cos(yy / 20.0)
    path = tmp_path / "e360.tif"
    _write_4326(path, z, 179.994, -16.98, 1e-4)
    flat = generate(small(terrain={"source": "dem", "path": str(path)}), seed=0)
    assert -180.0 <= flat.geo.lon <= 180.0
    site = {"site": "latlon", "lat": -16.98605, "lon": -179.99945}
    scn = generate(small(terrain={"source": "dem", "path": str(path), **site}), seed=0)
    # the datum's altitude is the raster's value at the pixel stored at 180.00055°
    col, row = (180.00055 - 179.994) / 1e-4 - 0.5, (16.98605 - 16.98) / 1e-4 - 0.5
    assert (col, row) == pytest.approx((65.0, 60.0))
    assert scn.geo.alt == pytest.approx(z[60, 65], abs=1e-3)


def test_window_slopes_of_a_tall_geographic_dem_use_each_rows_width(tmp_path: Path) -> None:
    """A uniform 5° east-facing slope stored in degrees from 20° to 60° N: a pixel is half as
    wide at 60° as at 20°, and every window still measures 5°, not cos(lat)/cos(40°) of it."""
    from pyproj import Geod

    from scenario_gen.dem import load_geotiff

    d, rows, cols = 0.005, 8000, 24
    lat = 60.0 - (np.arange(rows) + 0.5) * d
    width = Geod(ellps="WGS84").inv(np.zeros(rows), lat, np.full(rows, d), lat)[2]
    z = np.arange(cols)[None, :] * width[:, None] * np.tan(np.radians(5.0))
    path = tmp_path / "tall.tif"
    _write_4326(path, z + 100.0, 10.0, 60.0, d)
    mean, bad = load_geotiff(path, 64).window_slopes(2_000.0)
    assert mean[~bad] == pytest.approx(5.0, abs=0.05)


def test_nodata_under_a_latlon_site_is_named_for_what_it_is(tmp_path: Path) -> None:
    """A 1 km nodata block in a UTM DEM, a site read as a window around the field: inside the
    block the window holds nothing valid; on its edge the block runs out of the window, so no
    fill limit fills it, and the message says to move the field, not to raise the limit."""
    from pyproj import Transformer

    rows = cols = 300
    yy, xx = np.mgrid[0:rows, 0:cols].astype(np.float64)
    z = 300.0 + 0.05 * xx + 0.02 * yy
    z[100:200, 100:200] = np.nan
    path = tmp_path / "hole.tif"
    x0, y0 = 700_000.0, 4_050_000.0
    with rasterio.open(
        path, "w", driver="GTiff", height=rows, width=cols, count=1, dtype="float32",
        crs="EPSG:32616", transform=from_origin(x0, y0, 10.0, 10.0), nodata=np.nan,
    ) as ds:  # fmt: skip
        ds.write(z.astype(np.float32), 1)
    to_ll = Transformer.from_crs("EPSG:32616", "EPSG:4326", always_xy=True)

    def site(col: float, row: float, fill: int = 64) -> dict:
        lon, lat = to_ll.transform(x0 + 10.0 * col, y0 - 10.0 * row)
        return {"source": "dem", "path": str(path), "site": "latlon", "lat": lat, "lon": lon,
                "fill_max_pixels": fill}  # fmt: skip

    with pytest.raises(ScenarioError, match="window read around the field holds no valid"):
        generate(small(terrain=site(150, 150)), seed=0)
    for fill in (64, 20_000):  # the block is 10,000 pixels: no limit can count it from here
        with pytest.raises(ScenarioError, match="reaches beyond the window") as e:
            generate(small(terrain=site(100, 150, fill)), seed=0)
        assert "raise the fill limit" not in str(e.value)


def test_a_dem_of_one_height_is_a_flat_test_surface_with_the_field_in_its_middle(
    tmp_path: Path,
) -> None:
    """One level everywhere was all "water" to the site search, and no site was found; it is
    a flat surface, and every window ties, so the field goes to the middle."""
    n = 120
    path = tmp_path / "flat.tif"
    with rasterio.open(
        path, "w", driver="GTiff", height=n, width=n, count=1, dtype="int16",
        crs="EPSG:32616", transform=from_origin(500_000.0, 4_000_000.0, 10.0, 10.0),
    ) as ds:  # fmt: skip
        ds.write(np.full((n, n), 250, np.int16), 1)
    from pyproj import Transformer

    lon, lat = Transformer.from_crs("EPSG:32616", "EPSG:4326", always_xy=True).transform(
        500_000.0 + 605.0,
        4_000_000.0 - 605.0,  # the middle pixel's centre
    )
    for site in ("flattest", "steepest"):
        scn = generate(small(terrain={"source": "dem", "path": str(path), "site": site}), seed=0)
        assert (scn.geo.lat, scn.geo.lon) == pytest.approx((lat, lon), abs=1e-7)
        assert scn.geo.alt == pytest.approx(250.0)


def _raster(path: Path, crs: object, **extra: object) -> None:
    with rasterio.open(
        path, "w", driver="GTiff", height=30, width=30, count=1, dtype="float32", crs=crs,
        **extra,
    ) as ds:  # fmt: skip
        ds.write(np.ones((30, 30), np.float32), 1)


def test_a_local_crs_and_a_gcp_only_raster_are_named_for_what_they_are(
    tmp_path: Path, recwarn: pytest.WarningsRecorder
) -> None:
    from rasterio.control import GroundControlPoint

    local = tmp_path / "local.tif"
    wkt = 'LOCAL_CS["site grid",UNIT["metre",1],AXIS["Easting",EAST],AXIS["Northing",NORTH]]'
    _raster(local, rasterio.crs.CRS.from_wkt(wkt), transform=from_origin(0, 300, 10, 10))
    gcps = tmp_path / "gcps.tif"
    _raster(gcps, None)
    with rasterio.open(gcps, "r+") as ds:
        points = [GroundControlPoint(r, c, -84.1 + c * 1e-4, 36.5 - r * 1e-4) for r, c in
                  ((0, 0), (0, 29), (29, 0))]  # fmt: skip
        ds.gcps = (points, rasterio.crs.CRS.from_epsg(4326))
    bare = tmp_path / "bare.tif"
    _raster(bare, None)
    recwarn.clear()  # writing them warns; reading them must not
    with pytest.raises(ScenarioError, match="local \\(engineering\\) CRS 'site grid'"):
        generate(small(terrain={"source": "dem", "path": str(local)}), seed=0)
    with pytest.raises(ScenarioError, match="has no CRS"):
        generate(small(terrain={"source": "dem", "path": str(bare)}), seed=0)
    with pytest.raises(ScenarioError, match="ground control points only"):
        generate(small(terrain={"source": "dem", "path": str(gcps)}), seed=0)
    # the georeference is refused in one line, without rasterio's warning before it
    assert not [w for w in recwarn if "geotransform" in str(w.message)]


def test_a_dem_whose_datum_needs_a_missing_grid_is_refused_naming_its_regions_grid(
    tmp_path: Path,
) -> None:
    """NAD27 in Iowa: without its grids PROJ's best is good to 7 m and its candidates
    disagree by more, so the DEM is refused as a field file in that CRS is, naming the grid
    that covers Iowa (a Canadian grid's box reaches 42° N too, and PROJ lists it first)."""
    from pyproj import CRS, Transformer

    from scenario_gen.dem import load_geotiff
    from scenario_gen.geodesy import best_transformer

    if not isinstance(best_transformer(CRS(26715), CRS(4326)), str):
        pytest.skip("this machine has the NAD27 grids")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # pyproj: best not available
        x0, y0 = Transformer.from_crs(4326, 26715, always_xy=True).transform(-93.0, 42.0)
    path = tmp_path / "nad27.tif"
    with rasterio.open(
        path, "w", driver="GTiff", height=60, width=60, count=1, dtype="float32",
        crs="EPSG:26715", transform=from_origin(x0 - 300.0, y0 + 300.0, 10.0, 10.0),
    ) as ds:  # fmt: skip
        ds.write(np.full((60, 60), 300.0, np.float32), 1)
    for need in (None, (-93.001, 41.999, -92.999, 42.001)):
        with pytest.raises(ScenarioError, match="cannot be placed in WGS84") as e:
            load_geotiff(path, 64, need)
        assert e.value.field == "terrain.path" and "us_noaa_conus.tif" in str(e.value)
        assert "ca_nrc" not in str(e.value)
