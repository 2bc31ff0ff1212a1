"""The tyre's contact across its tread (``soil.contact_width``, sim.tyres.TyreModel._tread):
discs across the tread, each a spring–damper under it, summed into one force. Checked against
what the geometry gives by hand: on level ground a tread presses as a point does; on a side
slope a level tread bears on its uphill side, and its force acts at the discs' load-weighted
mean."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from agrinav_gym.config import RobotConfig, SoilConfig
from agrinav_gym.sim.ridge_guidance import turn_ratios
from agrinav_gym.sim.tyres import MAX_SLICES, TyreModel, tread_slices
from agrinav_gym.sim.world import World
from scenario_gen import Terrain

R, KZ = 0.11, 6.0e4
UNIT = (0.0, 0.0, 0.0, 1.0)  # the wheel frame's y axis (the axle) along world y
ZERO = (0.0, 0.0, 0.0)


def side_slope(deg: float) -> Terrain:
    """A plane rising towards +y (across an axle along y) at ``deg``."""
    n, sp = 41, 0.05
    y = -1.0 + sp * np.arange(n)
    return Terrain(np.tile((y * math.tan(math.radians(deg)))[:, None], (1, n)), -1.0, -1.0, sp)


def contact(width: float, terrain: Terrain, z: float, v: tuple = ZERO, w: tuple = ZERO) -> tuple:
    """One wheel's (in contact, force xyz, point xyz) at (0, 0, z), axle along y, no shear."""
    soil = replace(SoilConfig(), contact_width=width, damping_ratio=0.3)
    model = TyreModel(soil, R, 12.0, 1 / 240, native=False)
    model.reset(terrain)
    link = ((0.0, 0.0, z), UNIT, ZERO, UNIT, ZERO, UNIT, v, w)
    return model.forces([link], [(0.0, 0.0, ZERO, 0.0)])


@pytest.mark.parametrize("v,w", [(ZERO, ZERO), ((0.3, 0.1, -0.05), (0.0, 4.0, -0.3))])
def test_on_level_ground_a_tread_presses_as_a_point_does(v: tuple, w: tuple) -> None:
    flat = side_slope(0.0)
    point, tread = contact(0.0, flat, 0.108, v, w), contact(0.15, flat, 0.108, v, w)
    assert point[0] == tread[0] == 1.0
    # the same spring (N = k_z δ, 2 mm in), the same damper, the same point on the ground:
    # the discs' offsets are symmetric about the centre, so their moments cancel (spin about
    # the axle and yaw move no disc along the normal)
    np.testing.assert_allclose(tread[1:], point[1:], rtol=1e-12, atol=1e-12)
    if v == ZERO:
        assert tread[3] == pytest.approx(KZ * 0.002, rel=1e-9)


def test_a_rolling_tread_loads_its_sinking_side() -> None:
    """A roll rate ω_x moves disc k (at y = o_k) down at −o_k·ω_x: its damper adds
    c_z/n · o_k·ω_x, so the force shifts by −(c_z/n)·ω_x·Σo_k²/N across the tread, which a
    point contact cannot do."""
    v, roll = (0.3, 0.1, -0.05), 0.2
    f = contact(0.15, side_slope(0.0), 0.108, v, (roll, 4.0, -0.3))
    n = tread_slices(0.15, 0.05)
    offs = 0.15 * ((np.arange(n) + 0.5) / n - 0.5)
    cz = 2 * 0.3 * math.sqrt(KZ * 12.0)
    total = KZ * 0.002 - cz * v[2]
    assert f[3] == pytest.approx(total, rel=1e-12)
    assert f[5] == pytest.approx(-cz / n * roll * (offs**2).sum() / total, rel=1e-9)


def test_on_a_side_slope_a_level_tread_bears_on_its_uphill_side() -> None:
    deg = 10.0
    a = math.radians(deg)
    n_hat = np.array([0.0, -math.sin(a), math.cos(a)])  # the plane's normal
    width, z = 0.15, 0.096  # every disc pressed in (the downhill one by ≈ 3 mm)
    slices = tread_slices(width, 0.05)
    f = contact(width, side_slope(deg), z)
    # by hand: disc k at y = o_k reaches r·cos(a) below its centre along the normal (the
    # normal leans out of its plane by a), its centre is (z − o_k·tan a)·cos a above the plane
    offs = width * ((np.arange(slices) + 0.5) / slices - 0.5)
    depth = R * math.cos(a) - (z - offs * math.tan(a)) * math.cos(a)
    assert (depth > 0).all()
    loads = KZ / slices * depth
    np.testing.assert_allclose(f[1:4], loads.sum() * n_hat, rtol=1e-9)
    # each disc's force acts where its lowest point (straight below its centre: the disc is
    # upright) comes up the normal onto the plane; the resultant at their load-weighted mean
    # (all forces parallel): towards the uphill edge, where the ground comes up to the tread
    pts = [np.array([0.0, o, z - R]) + d * n_hat for o, d in zip(offs, depth, strict=True)]
    mean = np.average(pts, axis=0, weights=loads)
    np.testing.assert_allclose(f[4:7], mean, atol=1e-12)
    assert f[5] > 0.01  # well into the uphill half of the tread


def test_slices_resolve_the_grid_and_stay_bounded() -> None:
    assert tread_slices(0.0, 0.05) == 0  # a point contact
    assert tread_slices(0.15, 0.05) == 6  # 2.5 cm discs on a 5 cm grid
    assert tread_slices(0.15, 1.0) == 3
    assert tread_slices(0.5, 0.001) == MAX_SLICES


def test_a_robot_on_treads_stands_still_and_drives_straight() -> None:
    w = World(RobotConfig(), replace(SoilConfig(), contact_width=0.15))
    try:
        flat = side_slope(0.0)
        w.load(flat)
        w.place_robot(0.0, 0.0, 0.0, flat)
        w.drive(0.0, 0.0)
        w.step(2 * w.cfg.physics_hz)
        s = w.state()
        assert abs(s.rpy[0]) < 0.01 and abs(s.rpy[1]) < 0.01  # level: no rocking over
        assert np.hypot(*s.pos[:2]) < 0.005  # no creep
        for _ in range(40):
            w.drive(0.5, 0.0)
            w.step(w.cfg.physics_hz // w.cfg.control_hz)
        s = w.state()
        assert s.vel[0] == pytest.approx(0.5, rel=0.1)
        assert abs(s.pos[1]) < 0.01 and abs(s.rpy[2]) < 0.01
    finally:
        w.close()


def test_ridges_guide_a_tread_less_as_they_grow_too() -> None:
    soil = replace(SoilConfig(), contact_width=0.15)
    ratios = turn_ratios([0.0, 0.05, 0.12], soil)
    assert ratios[0] == 1.0
    assert ratios[0] - 0.05 > ratios[1] > ratios[2] + 0.05, ratios
