"""Memory bounds checked before allocating, and DEMs that lie about themselves."""

import re
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin
from rasterio.windows import Window

from scenario_gen import ScenarioError, generate
from scenario_gen.bounds import (
    MAX_DEM_PIXELS,
    MAX_PLANTS,
    MAX_ROUTE_WAYPOINTS,
    MAX_TERRAIN_SAMPLES,
)
from scenario_gen.dem import load_geotiff

from .helpers import plane, small

FLAT = {"enabled": False, "roughness": 0.0}


@pytest.mark.parametrize(
    "overrides,field,bound",
    [
        (  # 40 million plants (7.5 km² at 0.75 x 0.25 m), on a terrain small enough to allow it
            {
                "field": {"width": 3000.0, "length": 2500.0},
                "layout": {"row_spacing": 0.75, "plant_spacing": 0.25},
                "terrain": {"lod": 14},
            },
            "layout.plant_spacing/row_spacing",
            f"{MAX_PLANTS:,}",
        ),
        (  # 100 weeds per m² over a hectare
            {"field": {"width": 100.0, "length": 110.0}, "layout": {"weed_density": 100.0}},
            "layout.weed_density",
            f"{MAX_PLANTS:,}",
        ),
        (  # 1,000 lanes of 700 m at 5 mm: 1.4e8 waypoints
            {
                "field": {"width": 800.0, "length": 700.0},
                "layout": {"plant_spacing": 50.0},
                "route": {"lanes": 1000, "spacing": 0.005},
                "terrain": {"lod": 14},
            },
            "route.lanes/spacing",
            f"{MAX_ROUTE_WAYPOINTS:,}",
        ),
        (  # a square kilometre at 0.11 m: 80 million samples (sparse plants: within bounds)
            {"field": {"width": 1000.0, "length": 1000.0}, "layout": {"plant_spacing": 2.0}},
            "terrain.lod",
            f"{MAX_TERRAIN_SAMPLES:,}",
        ),
    ],
)
def test_absurd_sizes_are_refused_with_the_bound(overrides: dict, field: str, bound: str) -> None:
    furrows = FLAT if "terrain" in overrides else {}
    with pytest.raises(ScenarioError) as info:
        generate(plane(**overrides, furrows=furrows or FLAT), seed=0)
    assert info.value.field == field and bound in str(info.value), str(info.value)


def test_candidate_grid_is_bounded_for_a_thin_diagonal_field(tmp_path: Path) -> None:
    # few plants, but a bounding box holding 7.6 M grid positions: refused before the meshgrid
    from shapely.geometry import LineString

    from scenario_gen.layout import layout
    from scenario_gen.spec import LayoutSpec

    field = LineString([(0, 0), (1000, 1000)]).buffer(1.0)
    rng = np.random.default_rng(0)
    with pytest.raises(ScenarioError, match="candidate positions"):
        layout(field, LayoutSpec(headland=0.0, edge_margin=0.0), 0.0, rng, rng, rng)


# ----------------------------------------------------------------------------- DEMs
def _tif(
    path: Path,
    elev: np.ndarray,
    crs: str,
    transform,
    nodata: float | None = None,
    dtype: str = "float32",
) -> Path:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=elev.shape[0],
        width=elev.shape[1],
        count=1,
        dtype=dtype,
        crs=crs,
        transform=transform,
        nodata=nodata,
    ) as ds:
        ds.write(elev.astype(dtype), 1)
    return path


def _slope(n: int = 60) -> np.ndarray:
    gx, gy = np.meshgrid(np.arange(n), np.arange(n))
    return 300 + 0.5 * gx + 0.2 * gy


D = 1 / 1200  # 3 arc-seconds
WEST, NORTH = -84.2, 36.6
CENTRE = {"site": "latlon", "lat": NORTH - 30.5 * D, "lon": WEST + 30.5 * D}


def _dem_spec(path: Path, **terrain: object):
    return small(terrain={"source": "dem", "path": str(path), **CENTRE, **terrain})


@pytest.fixture(scope="module")
def sparse_20k(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20,000 x 20,000 pixels of 1 m in UTM 16N, stored sparse: only a 1 km block holds data."""
    path = tmp_path_factory.mktemp("sparse") / "big.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=20_000,
        width=20_000,
        count=1,
        dtype="int16",
        crs="EPSG:32616",
        transform=from_origin(730_000, 4_060_000, 1.0, 1.0),
        nodata=-9999,
        tiled=True,
        blockxsize=512,
        blockysize=512,
        compress="deflate",
        SPARSE_OK=True,
    ) as ds:
        block = (300 + np.arange(1024)[None, :] + np.zeros((1024, 1))).astype("int16")
        ds.write(block, 1, window=Window(9728, 9728, 1024, 1024))
    return path


def _utm_site(col: float, row: float) -> dict[str, float]:
    from pyproj import Transformer

    lon, lat = Transformer.from_crs("EPSG:32616", "EPSG:4326", always_xy=True).transform(
        730_000 + col, 4_060_000 - row
    )
    return {"site": "latlon", "lat": lat, "lon": lon}


def test_a_huge_dem_is_refused_before_it_is_read(sparse_20k: Path) -> None:
    assert sparse_20k.stat().st_size < 200_000  # the file is small; its raster is 400 M pixels
    with pytest.raises(ScenarioError) as info:
        generate(small(terrain={"source": "dem", "path": str(sparse_20k)}), seed=0)
    msg = str(info.value)
    assert info.value.field == "terrain.path"
    assert "20000x20000 = 400,000,000 pixels" in msg and f"{MAX_DEM_PIXELS:,}" in msg
    assert "terrain.site=latlon" in msg


def test_a_huge_dem_is_usable_through_a_window(sparse_20k: Path) -> None:
    site = _utm_site(10_240, 10_240)
    scn = generate(
        small(terrain={"source": "dem", "path": str(sparse_20k), **site}, furrows=FLAT), seed=0
    )
    # the block rises 1 m per metre eastward (UTM east is 1.1° off true east here)
    zy, zx = np.gradient(scn.terrain.heights, scn.terrain.spacing)
    assert np.median(zx) == pytest.approx(1.0, abs=0.01)
    assert np.median(np.abs(zy)) == pytest.approx(0.02, abs=0.01)


def test_window_samples_like_the_whole_raster(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    elev = _slope(200) + rng.normal(0, 3, (200, 200))
    path = _tif(tmp_path / "rough.tif", elev, "EPSG:4326", from_origin(WEST, NORTH, D, D))
    whole = load_geotiff(path, 64)
    lon0, lat0 = WEST + 50 * D, NORTH - 70 * D
    part = load_geotiff(path, 64, (lon0, lat0, lon0 + 10 * D, lat0 + 10 * D))
    assert part.elevation.size < whole.elevation.size / 10
    lon = rng.uniform(lon0, lon0 + 10 * D, 500)
    lat = rng.uniform(lat0, lat0 + 10 * D, 500)
    np.testing.assert_allclose(
        part.sample_lonlat(lon, lat, "t"), whole.sample_lonlat(lon, lat, "t"), atol=1e-6
    )


def test_geographic_values_in_a_projected_crs_are_refused(tmp_path: Path) -> None:
    # lon/lat degrees labelled UTM: "pixels" of 0.8 mm
    path = _tif(
        tmp_path / "mislabelled.tif", _slope(), "EPSG:32616", from_origin(WEST, NORTH, D, D)
    )
    with pytest.raises(ScenarioError) as info:
        generate(_dem_spec(path), seed=0)
    assert info.value.field == "terrain.path"
    assert re.search(r"pixels of 0\.00083\d m", str(info.value)), str(info.value)
    assert "mislabelled" in str(info.value)


def test_projected_values_in_a_geographic_crs_are_refused(tmp_path: Path) -> None:
    path = _tif(
        tmp_path / "metres.tif", _slope(), "EPSG:4326", from_origin(730_000, 4_060_000, 30, 30)
    )
    with pytest.raises(ScenarioError, match="outside longitude/latitude"):
        generate(_dem_spec(path), seed=0)


@pytest.mark.parametrize("sentinel", [-32768.0, -9999.0, -3.4028235e38])
def test_untagged_sentinels_are_nodata(tmp_path: Path, sentinel: float) -> None:
    elev = _slope()
    elev[33:35, 28:30] = sentinel  # 4 pixels next to the field: a small hole, filled
    path = _tif(tmp_path / "untagged.tif", elev, "EPSG:4326", from_origin(WEST, NORTH, D, D))
    scn = generate(_dem_spec(path), seed=0)
    assert scn.terrain.relief < 3.0  # no 32 km pit under the field


def test_untagged_sentinel_block_under_the_field_is_a_hole(tmp_path: Path) -> None:
    elev = _slope()
    elev[20:45, 20:45] = -32768
    path = _tif(tmp_path / "block.tif", elev, "EPSG:4326", from_origin(WEST, NORTH, D, D), None)
    with pytest.raises(ScenarioError, match="nodata hole"):
        generate(_dem_spec(path), seed=0)


@pytest.mark.parametrize("value", [12_000.0, -800.0, -32768.0])
def test_absurd_elevations_are_refused(tmp_path: Path, value: float) -> None:
    elev = _slope()
    elev[28, 33] = value  # next to the field: in the window read
    # tagged with a different nodata value, so -32768 is not a sentinel here
    path = _tif(tmp_path / "absurd.tif", elev, "EPSG:4326", from_origin(WEST, NORTH, D, D), -9999)
    with pytest.raises(ScenarioError) as info:
        generate(_dem_spec(path), seed=0)
    assert info.value.field == "terrain.path"
    assert f"holds elevation {value:.6g} at pixel (row 28, col 33)" in str(info.value)
    assert "[-500, 9000]" in str(info.value)
