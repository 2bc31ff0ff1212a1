"""Terrain layers: elevations from the scenario's own source, images placed in Web-Mercator."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from baselines.studio import layers
from scenario_gen.dem import load_embedded
from scenario_gen.geodesy import GeoFrame
from scenario_gen.spec import TerrainSpec


def test_dem_elevation_at_pixel_centres_and_off_the_raster() -> None:
    dem = load_embedded()
    elev = layers.DemElevation(dem)
    rows, cols = np.array([10, 100, 200]), np.array([20, 150, 300])
    x, y = dem.pixel_to_crs(cols + 0.5, rows + 0.5)
    z = elev(np.asarray(x), np.asarray(y))  # EPSG:4326: x, y are lon, lat
    assert np.allclose(z, dem.elevation[rows, cols], atol=1e-6)
    west, south, _, _ = elev.extent
    assert np.isnan(elev(np.array([west - 0.01]), np.array([south + 0.1])))[0]


def test_plane_and_mesh_elevations_match_their_surfaces(tmp_path: Path) -> None:
    trimesh = pytest.importorskip("trimesh")
    spec = TerrainSpec(source="plane", slope_deg=10.0, aspect_deg=90.0, datum=(42.0, -5.0, 800.0))
    plane = layers.PlaneElevation(spec)
    geo = GeoFrame(42.0, -5.0, 800.0)
    lat, lon, _ = geo.enu_to_geodetic(np.array([0.0, 50.0]), np.array([0.0, 20.0]))
    z = plane(lon, lat)
    assert z[0] == pytest.approx(800.0) and z[1] == pytest.approx(
        800.0 - 50 * math.tan(math.radians(10)), abs=1e-3
    )
    gx, gy = np.meshgrid(np.linspace(-40, 40, 21), np.linspace(-40, 40, 21))
    v = np.column_stack([gx.ravel(), gy.ravel(), 0.05 * gx.ravel() - 0.02 * gy.ravel()])
    from scipy.spatial import Delaunay

    mesh = trimesh.Trimesh(v, Delaunay(v[:, :2]).simplices, process=False)
    path = tmp_path / "t.ply"
    mesh.export(path)
    m = layers.MeshElevation(str(path), (42.0, -5.0, 800.0), "z")
    lat, lon, _ = geo.enu_to_geodetic(np.array([10.0, 100.0]), np.array([-5.0, 0.0]))
    zm = m(lon, lat)
    assert zm[0] == pytest.approx(800.0 + 0.5 + 0.1, abs=1e-3) and np.isnan(zm[1])


def test_render_places_an_image_of_the_right_shape() -> None:
    from PIL import Image

    elev = layers.DemElevation(load_embedded())
    west, south, _, _ = elev.extent
    box = (west - 0.05, south + 0.1, west + 0.05, south + 0.15)  # half off the DEM
    layer = layers.render(elev, box, 200)
    assert layer is not None
    img = np.asarray(Image.open(io.BytesIO(layer.png)))
    (s, w), (n, e) = layer.bounds
    assert w == pytest.approx(west) and e == pytest.approx(west + 0.05)  # clipped to the DEM
    aspect = math.radians(e - w) / (float(layers.merc_y(n)) - float(layers.merc_y(s)))
    assert img.shape[1] / img.shape[0] == pytest.approx(aspect, rel=0.02)
    assert img[..., 3].min() < img[..., 3].max()  # contours and shading drawn, not blank
    assert layer.zmin < layer.zmax and layer.interval in (1, 2, 5, 10, 20, 50, 100, 200)


def test_contour_interval_is_nice() -> None:
    assert layers.nice_interval(13.0) == 2.0
    assert layers.nice_interval(840.0) == 100.0
    assert layers.nice_interval(0.3) == 0.05
