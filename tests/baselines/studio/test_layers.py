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


def test_the_studio_keeps_recent_layer_images_and_terrains_within_bounds(tmp_path: Path) -> None:
    """A drawing session renders a new detail layer each time the field moves and may switch
    terrains: the server keeps the newest within its budget, not every one ever made."""
    from baselines.studio import shared
    from baselines.studio.session import Terrain

    studio = shared.Studio(preset="default", terrain=Terrain(), workspace=tmp_path)
    size = 1024 * 1024
    count = 3 * shared.IMAGE_BYTES // size
    bounds = ((0.0, 0.0), (1.0, 1.0))
    urls = [
        studio.image_url(layers.Layer(i.to_bytes(4, "big") * (size // 4), bounds, 0, 1, 1))
        for i in range(count)
    ]
    kept = sum(len(png) for png in studio.images.values())
    assert kept <= shared.IMAGE_BYTES and len(studio.images) >= shared.IMAGE_BYTES // size - 1
    # the newest are those kept, and a layer served again is the newest once more
    newest = [u.split("/")[-1][:-4] for u in urls[-len(studio.images) :]]
    assert list(studio.images) == newest
    first_kept = newest[0]
    studio.image_url(layers.Layer(studio.images[first_kept], bounds, 0, 1, 1))
    assert list(studio.images)[-1] == first_kept

    session = studio.new_session()
    opened = []
    for slope in range(shared.ELEVATIONS + 2):
        session.set("terrain.source", "plane")
        session.set("terrain.slope_deg", float(slope))
        opened.append(studio.elevation(session))
    assert len(studio.elevations) == shared.ELEVATIONS
    assert studio.elevation(session) is opened[-1]  # the newest stays open
