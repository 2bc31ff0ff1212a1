import math

import numpy as np
import pytest
from pyproj import Geod

from scenario_gen import GeoFrame, ground_sample_distance
from scenario_gen.errors import ScenarioError


def test_gsd_matches_web_mercator_formula() -> None:
    # design.md, "Frames, units, randomness"
    assert ground_sample_distance(20, 42.6) == pytest.approx(0.11, abs=1e-3)
    assert ground_sample_distance(0, 0.0) == pytest.approx(156543.03392)
    assert ground_sample_distance(21, 42.6) == pytest.approx(ground_sample_distance(20, 42.6) / 2)


@pytest.mark.parametrize("lod", [-1, 23, 2.5])
def test_gsd_rejects_bad_lod(lod: object) -> None:
    with pytest.raises(ScenarioError, match="terrain.lod"):
        ground_sample_distance(lod, 10.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("lat,lon", [(36.55, -84.14), (-33.9, 151.2), (69.6, 18.9), (0.0, 179.99)])
def test_round_trip_is_sub_millimetre(lat: float, lon: float) -> None:
    geo = GeoFrame(lat, lon, 300.0)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-5000, 5000, (2, 2000))
    z = rng.uniform(-200, 200, 2000)
    la, lo, al = geo.enu_to_geodetic(x, y, z)
    x2, y2, z2 = geo.geodetic_to_enu(la, lo, al)
    err = np.sqrt((x - x2) ** 2 + (y - y2) ** 2 + (z - z2) ** 2)
    assert err.max() < 1e-3


def test_enu_distances_and_axes_are_geodesic() -> None:
    geo = GeoFrame(36.55, -84.14, 0.0)  # on the ellipsoid, so geodesics compare directly
    x, y, z = geo.geodetic_to_enu(36.55, -84.14, 0.0)
    assert abs(x) < 1e-6 and abs(y) < 1e-6 and abs(z) < 1e-6
    lat, lon, _ = geo.enu_to_geodetic(0.0, 1000.0, 0.0)  # 1 km north: same longitude
    assert lon == pytest.approx(-84.14, abs=1e-9) and lat > 36.55
    lat_e, lon_e, _ = geo.enu_to_geodetic(1000.0, 0.0, 0.0)
    _, _, d = Geod(ellps="WGS84").inv(-84.14, 36.55, float(lon_e), float(lat_e))
    assert d == pytest.approx(1000.0, abs=0.01)  # arc vs tangent differ by d³/3R² ≈ 8 µm
    # Earth curvature: a point 1 km away on the ellipsoid lies ≈ d²/2R below the tangent plane.
    _, _, zc = geo.geodetic_to_enu(float(lat_e), float(lon_e), 0.0)
    assert zc == pytest.approx(-(1000.0**2) / (2 * 6.371e6), rel=0.01)


def test_geoframe_pickles() -> None:
    import pickle

    geo = pickle.loads(pickle.dumps(GeoFrame(36.5, -84.1, 300.0)))
    lat, _lon, _alt = geo.enu_to_geodetic(10.0, 20.0, 1.0)
    assert math.isfinite(float(lat)) and geo.lat == 36.5


@pytest.mark.parametrize("lat,lon", [(91.0, 0.0), (0.0, 181.0), (float("nan"), 0.0)])
def test_bad_datum(lat: float, lon: float) -> None:
    with pytest.raises(ScenarioError, match="datum"):
        GeoFrame(lat, lon, 0.0)
