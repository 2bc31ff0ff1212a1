import math

import numpy as np
import pytest

from scenario_gen import Terrain, generate, preset
from scenario_gen.generate import orientation

from .helpers import plane


def test_idw_is_exact_at_samples_and_for_plane_slopes() -> None:
    gx, gy = np.meshgrid(np.arange(50) * 0.1, np.arange(40) * 0.1)
    t = Terrain(0.3 * gx - 0.2 * gy + 1.0, 0.0, 0.0, 0.1)
    z, zx, zy = t.idw(gx[5:10, 5:10].ravel(), gy[5:10, 5:10].ravel())
    np.testing.assert_allclose(z, (0.3 * gx - 0.2 * gy + 1.0)[5:10, 5:10].ravel(), atol=1e-9)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(0.5, 4.4, (2, 500))
    _, zx, zy = t.idw(x, y)
    np.testing.assert_allclose(zx, 0.3, atol=1e-9)
    np.testing.assert_allclose(zy, -0.2, atol=1e-9)


def test_height_at_is_bilinear_and_clamps() -> None:
    t = Terrain(np.array([[0.0, 1.0], [2.0, 3.0]]), 10.0, 20.0, 2.0)
    assert t.height_at(11.0, 21.0) == pytest.approx(1.5)
    assert t.height_at(-100.0, 20.0) == pytest.approx(0.0)


def test_plant_z_equals_terrain_height_within_1cm() -> None:
    # Real DEM plus 12 cm furrow relief: IDW over 3 samples vs the bilinear surface the robot
    # drives on differ by the sub-grid curvature, well under a centimetre at 0.12 m spacing.
    scn = generate(preset("default"), seed=0)
    dz = scn.plants.z - scn.terrain.height_at(scn.plants.x, scn.plants.y)
    assert np.abs(dz).max() < 0.01


@pytest.mark.parametrize("slope,aspect", [(10.0, 0.0), (10.0, 90.0), (20.0, 225.0), (5.0, 137.0)])
def test_pitch_roll_match_a_tilted_plane(slope: float, aspect: float) -> None:
    scn = generate(plane(slope, aspect), seed=1)
    p = scn.plants
    g = math.tan(math.radians(slope))
    a = math.radians(aspect)
    zx, zy = -g * math.sin(a), -g * math.cos(a)  # analytic gradient of the plane
    normal = np.array([-zx, -zy, 1.0]) / math.hypot(1.0, g)
    roll, pitch = orientation(np.full(len(p), zx), np.full(len(p), zy), p.yaw)
    np.testing.assert_allclose(p.pitch, pitch, atol=math.radians(0.5))
    np.testing.assert_allclose(p.roll, roll, atol=math.radians(0.5))
    # and the plant's z axis R·e_z, R = Rz(yaw)·Ry(pitch)·Rx(roll), is the plane normal
    cy, sy = np.cos(p.yaw), np.sin(p.yaw)
    v = np.stack(
        [np.cos(p.roll) * np.sin(p.pitch), -np.sin(p.roll), np.cos(p.roll) * np.cos(p.pitch)],
        axis=1,
    )
    axis = np.stack([cy * v[:, 0] - sy * v[:, 1], sy * v[:, 0] + cy * v[:, 1], v[:, 2]], axis=1)
    angle = np.degrees(np.arccos(np.clip(axis @ normal, -1, 1)))
    assert angle.max() < 0.5
    # IDW over 3 grid nodes is not linear-exact: its error on a plane is below slope x spacing / 2
    bound = g * scn.terrain.spacing / 2
    assert np.abs(p.z - scn.terrain.height_at(p.x, p.y)).max() < bound


def test_lod_sets_grid_spacing() -> None:
    s19 = generate(plane(terrain={"lod": 19}), seed=0)
    s20 = generate(plane(terrain={"lod": 20}), seed=0)
    assert s19.terrain.spacing == pytest.approx(2 * s20.terrain.spacing)
    assert s20.terrain.spacing == pytest.approx(156543.03392 * math.cos(math.radians(42.6)) / 2**20)


def test_furrows_put_ridges_on_rows_and_furrows_in_lanes() -> None:
    scn = generate(plane(furrows={"enabled": True, "depth": 0.12, "roughness": 0.0}), seed=0)
    lanes = scn.lanes
    mid = lanes.mean(axis=1)  # lane centres: furrow bottoms
    rows_x, rows_y = scn.rows.to_enu(np.full(len(scn.rows.offsets), 0.0), scn.rows.offsets)
    z_lane = scn.terrain.height_at(mid[:, 0], mid[:, 1])
    z_row = scn.terrain.height_at(rows_x, rows_y)
    assert np.median(z_row) - np.median(z_lane) == pytest.approx(0.12, abs=0.015)
