"""A ground that yields (``soil.cohesion_kpa``, sim.terramechanics): each tread disc bears at
most the soil's bearing capacity on the slope under it, and the ground under a disc pressed
past it is cut down. Checked against the textbook bearing factors, a hand-computed disc on a
slope, a rigid ground where the capacity is never reached, and the ridges' guidance."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from agrinav_gym.config import RobotConfig, SoilConfig
from agrinav_gym.sim.ridge_guidance import ridged_plane, turn_ratio
from agrinav_gym.sim.terramechanics import (
    WONG_SOILS,
    bearing_capacity,
    bearing_factors,
    bekker_sinkage,
    disc_bearing,
    with_measured_soil,
)
from agrinav_gym.sim.tyres import TyreModel, tread_slices
from agrinav_gym.sim.world import World
from scenario_gen import Terrain
from scenario_gen.errors import InputError

TREAD = replace(SoilConfig(), contact_width=0.15)
R = 0.11
UNIT = (0.0, 0.0, 0.0, 1.0)  # the axle along world y
ZERO = (0.0, 0.0, 0.0)


def side_slope(deg: float) -> Terrain:
    n, sp = 41, 0.05
    y = -1.0 + sp * np.arange(n)
    return Terrain(np.tile((y * math.tan(math.radians(deg)))[:, None], (1, n)), -1.0, -1.0, sp)


@pytest.mark.parametrize(
    "phi,expected",
    # Vesić's table (Nc, Nq, Nγ), as printed to two decimals in foundation-engineering texts
    [(10.0, (8.35, 2.47, 1.22)), (20.0, (14.83, 6.40, 5.39)), (30.0, (30.14, 18.40, 22.40))],
)
def test_bearing_factors_are_the_textbooks(phi: float, expected: tuple) -> None:
    np.testing.assert_allclose(bearing_factors(phi), expected, atol=0.006)


def test_the_capacity_falls_with_the_slope_and_never_goes_negative() -> None:
    soil = with_measured_soil(TREAD, "sandy loam 15 % (LLL)")
    nc, nq, ng = bearing_factors(29.0)
    # by hand on level ground: a 0.10 × 0.15 m patch, B/L = 2/3, γ = 1.3 t/m³ · g
    level = 1.72 * nc * (1 + (2 / 3) * nq / nc) + 0.5 * 1.3 * 9.81 * 0.1 * ng * (1 - 0.4 * 2 / 3)
    assert bearing_capacity(soil, 0.0) == pytest.approx(level, rel=1e-12)
    caps = [bearing_capacity(soil, d) for d in (0.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0)]
    assert all(a > b for a, b in itertools.pairwise(caps[:5]))
    assert caps[-2] == caps[-1] == 0.0  # tan β ≥ 1: (1 − tan β)² is no capacity at all
    # φ 10°: at 25° g_c is negative and outweighs the weight term; clamped, not a pull
    wet = with_measured_soil(TREAD, "clayey soil 55 % (Thailand)")
    assert bearing_capacity(wet, 20.0) > 0.0 and bearing_capacity(wet, 25.0) == 0.0


def test_a_rigid_ground_needs_no_tread_but_a_yielding_one_does() -> None:
    assert disc_bearing(SoilConfig(), 6) is None
    with pytest.raises(InputError, match="config.soil.cohesion_kpa.*contact_width"):
        World(RobotConfig(), replace(SoilConfig(), cohesion_kpa=1.72))


def _disc_on_slope(soil: SoilConfig, deg: float, z: float) -> tuple[TyreModel, tuple, Terrain]:
    model = TyreModel(soil, R, 12.0, 1 / 240, native=False)
    terrain = side_slope(deg)
    model.reset(terrain)
    link = ((0.0, 0.0, z), UNIT, ZERO, UNIT, ZERO, UNIT, ZERO, ZERO)
    return model, model.forces([link], [(0.0, 0.0, ZERO, 0.0)]), terrain


def test_a_disc_pressed_past_the_capacity_bears_it_and_cuts_the_ground() -> None:
    """A level tread on a 10° slope, its discs pressed 3–25 mm in: on a firm soil the rigid
    ground's forces; on a loam whose capacity the uphill disc alone exceeds, that disc bears
    the capacity on a 10° slope (the others their springs) and the ground under it is cut
    (the uphill disc comes last, so no other disc stands on its cut)."""
    deg, z = 10.0, 0.096
    rigid = _disc_on_slope(TREAD, deg, z)[1]
    firm = _disc_on_slope(with_measured_soil(TREAD, "heavy clay 25 % (WES)"), deg, z)
    assert firm[1] == rigid  # 1.6 MPa: never reached
    assert np.array_equal(firm[0].ground, firm[2].heights)  # nothing cut
    weak_soil = with_measured_soil(TREAD, "Grenville loam 24 %")
    model, weak, terrain = _disc_on_slope(weak_soil, deg, z)
    n = tread_slices(0.15, 0.05)
    cap = disc_bearing(weak_soil, n).limit(math.tan(math.radians(deg)))  # type: ignore[union-attr]
    a = math.radians(deg)
    offs = 0.15 * ((np.arange(n) + 0.5) / n - 0.5)
    depth = R * math.cos(a) - (z - offs * math.tan(a)) * math.cos(a)
    spring = TREAD.vertical_stiffness / n * depth
    assert (spring > cap).tolist() == [False] * (n - 1) + [True]
    expected = np.minimum(spring, cap).sum()
    np.testing.assert_allclose(np.linalg.norm(weak[1:4]), expected, rtol=1e-12)
    assert np.linalg.norm(weak[1:4]) < np.linalg.norm(rigid[1:4])
    cut = terrain.heights - model.ground
    assert cut.min() == 0.0 and cut.max() > 0.0  # lowered only, and somewhere
    assert np.count_nonzero(cut) <= 4  # one cell's corners: under the yielding disc
    model.reset(terrain)
    assert np.array_equal(model.ground, terrain.heights)  # a reset restores the ground


def test_on_level_ground_a_soil_that_holds_the_robot_changes_nothing() -> None:
    """Sandy loam on level ground bears 76 kPa; the robot presses 8.5 kPa: every bit as on the
    rigid ground, standing and driving."""
    rows = []
    for soil in (TREAD, with_measured_soil(TREAD, "sandy loam 15 % (LLL)")):
        w = World(RobotConfig(), soil)
        try:
            flat = side_slope(0.0)
            w.load(flat)
            w.place_robot(0.0, 0.0, 0.0, flat)
            w.drive(0.0, 0.0)
            w.step(w.cfg.physics_hz)
            for _ in range(20):
                w.drive(0.5, 0.3)
                w.step(12)
            s = w.state()
            rows.append(np.concatenate([s.pos, s.rpy, s.vel, s.ang]))
            assert np.array_equal(w.tyres.ground, flat.heights)
        finally:
            w.close()
    assert np.array_equal(rows[0], rows[1])


def test_ridges_that_yield_guide_less() -> None:
    """12 cm ridges: a clay too firm to yield guides as the rigid ground does; sand lets most
    of a deliberate turn through, where the rigid ridges hold it."""
    rigid = turn_ratio(0.12, TREAD)
    assert turn_ratio(0.12, with_measured_soil(TREAD, "heavy clay 25 % (WES)")) == rigid
    sand = turn_ratio(0.12, with_measured_soil(TREAD, "dry sand (LLL)"))
    assert rigid < 0.3 and sand > rigid + 0.3, (rigid, sand)


SANDY_LOAM = with_measured_soil(TREAD, "sandy loam 15 % (LLL)")


def _drive(terrain: Terrain, yaw: float, command: tuple[float, float], steps: int) -> tuple:
    """Drive the robot on sandy loam from (−5, 0.5) at ``yaw``; its end state and the deepest
    cut the tyres made."""
    w = World(RobotConfig(), SANDY_LOAM)
    try:
        w.load(terrain)
        w.place_robot(-5.0, 0.5, yaw, terrain)
        for _ in range(steps):
            w.drive(*command)
            w.step(12)
        return w.state(), float((terrain.heights - w.tyres.ground).max())
    finally:
        w.close()


def _rut_bound(hill_rise: float) -> float:
    """How far below the field a cut can reach: the 12 cm ridges, the rise of the hill across
    one grid cell, and a disc's elastic sinkage at level ground's capacity."""
    n = tread_slices(SANDY_LOAM.contact_width, 0.05)
    level = disc_bearing(SANDY_LOAM, n).limit(0.0)  # type: ignore[union-attr]
    return 0.12 + hill_rise + level / (SANDY_LOAM.vertical_stiffness / n)


def test_a_drive_on_yielding_ridges_cuts_ruts_no_deeper_than_the_ridges() -> None:
    _, cut = _drive(ridged_plane(0.12, size=14.0), 0.0, (0.8, 0.2), 60)
    assert 0.01 < cut < _rut_bound(0.0)  # the flanks gave way, down to the furrow


def test_climbing_across_yielding_ridges_the_robot_does_not_dig_itself_in() -> None:
    """Up a 6° hill, crossing 12 cm ridges at 40°: a cut bench bears as level ground and the
    ruts' walls stand at the field's slope, so the robot climbs on (with walls that gave way
    the wheels dug in: 1.6 m of the commanded 3 m) and its ruts stay within the bound."""
    ridged = ridged_plane(0.12, size=14.0)
    x = ridged.x0 + ridged.spacing * np.arange(ridged.shape[1])
    slope = math.tan(math.radians(6.0))
    terrain = Terrain(ridged.heights + slope * x[None, :], ridged.x0, ridged.y0, ridged.spacing)
    s, cut = _drive(terrain, 0.7, (0.6, 0.0), 100)
    assert math.hypot(s.pos[0] + 5.0, s.pos[1] - 0.5) > 2.0  # of 3 m commanded
    assert 0.01 < cut < _rut_bound(terrain.spacing * slope)


def test_bekker_sinkage_inverts_the_rigid_wheel_load() -> None:
    """n = 1: the front arc's integral is 2/3, so W = b k √(2r) z^1.5 · 2/3 by hand."""
    soil = replace(WONG_SOILS["dry sand (LLL)"], n=1.0)
    z = bekker_sinkage(soil, 127.0, R, 0.15)
    k = (soil.k_c / 0.15 + soil.k_phi) * 1000.0
    assert 0.15 * k * math.sqrt(2 * R) * z**1.5 * 2.0 / 3.0 == pytest.approx(127.0, rel=1e-12)
    assert bekker_sinkage(soil, 254.0, R, 0.15) > z
