"""Skid-steer drive physics (sim.tyres): yaw-rate tracking, odometry slip, traction, no creep.

Each test drives a bare ``World`` on an analytic plane (milliseconds of setup); tolerances come
from the tyre model's derivation (docs/physics.md), not from fitting.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from agrinav_gym.config import RobotConfig, SoilConfig
from agrinav_gym.robot import RobotGeometry
from agrinav_gym.sim.tyres import in_place_turn_ratio
from agrinav_gym.sim.world import World
from scenario_gen import Terrain

A, B = 0.229, 0.235  # half wheelbase, half track (design.md "Physical facts")


def plane(slope_deg: float = 0.0) -> Terrain:
    """A 30 x 30 m plane rising towards +x at ``slope_deg``."""
    n, sp = 301, 0.1
    x = -15.0 + sp * np.arange(n)
    return Terrain(np.tile(x * math.tan(math.radians(slope_deg)), (n, 1)), -15.0, -15.0, sp)


@pytest.fixture
def world() -> Iterator[World]:
    w = World(RobotConfig())
    yield w
    w.close()


def drive(
    w: World, terrain: Terrain, v: float, om: float, seconds: float, yaw: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(yaw rates, positions, odometry ω with the nominal track) at the control rate."""
    w.load(terrain)
    w.place_robot(0.0, 0.0, yaw, terrain)
    w.drive(0.0, 0.0)
    w.step(w.cfg.physics_hz)  # settle 1 s on the springs
    sub = w.cfg.physics_hz // w.cfg.control_hz
    rates, pos, odom = [], [w.state().pos.copy()], []
    for _ in range(round(seconds * w.cfg.control_hz)):
        w.drive(v, om)
        w.step(sub)
        s = w.state()
        rates.append(float(s.ang[2]))
        pos.append(s.pos.copy())
        wl, wr = 0.5 * (s.wheels[0] + s.wheels[2]), 0.5 * (s.wheels[1] + s.wheels[3])
        odom.append((wr - wl) * w.geometry.wheel_radius / w.geometry.track)
    return np.asarray(rates), np.asarray(pos), np.asarray(odom)


@pytest.mark.parametrize("v,om", [(0.0, 0.5), (0.5, 0.5), (1.0, 0.2), (0.3, 1.0), (0.0, 1.5)])
def test_yaw_rate_follows_the_command(world: World, v: float, om: float) -> None:
    rates, _, _ = drive(world, plane(), v, om, 4.0)
    steady = rates[40:]  # after 2 s
    assert steady.mean() == pytest.approx(om, rel=0.10)
    assert steady.std() < 0.02 * om  # no stick-slip


def test_turn_rate_is_the_same_at_every_heading_and_physics_rate() -> None:
    # pybullet's own wheel friction failed both (docs/physics.md)
    means = []
    for hz, yaw in ((240, 0.0), (240, 0.4), (240, 0.8), (480, 0.0)):
        w = World(RobotConfig(physics_hz=hz))
        try:
            rates, _, _ = drive(w, plane(), 0.0, 0.5, 3.0, yaw=yaw)
        finally:
            w.close()
        means.append(rates[30:].mean())
    assert np.ptp(means) < 0.01 * np.mean(means)


def test_odometry_overestimates_the_yaw_rate_by_the_skid_ratio(world: World) -> None:
    chi = 1.0 / in_place_turn_ratio(SoilConfig(), 2 * A, 2 * B)
    # the band: the rigid-Coulomb limit 1 + (a/b)² (no resistance) up to the soil's χ
    assert 1.0 + (A / B) ** 2 <= chi < 2.3
    for v, om in ((0.0, 0.5), (0.5, 0.5)):
        rates, _, odom = drive(world, plane(), v, om, 4.0)
        ratio = odom[40:].mean() / rates[40:].mean()
        assert ratio == pytest.approx(chi, rel=0.1)


def test_turn_ratio_has_the_rigid_coulomb_limit() -> None:
    no_rr = SoilConfig(rolling_resistance=0.0, shear_modulus=0.002, contact_length=0.5)
    assert in_place_turn_ratio(no_rr, 2 * A, 2 * B) == pytest.approx(
        1.0 / (1.0 + (A / B) ** 2), rel=1e-3
    )
    # more resistance per unit of grip: a wider effective track
    soft = SoilConfig(rolling_resistance=0.12)
    assert in_place_turn_ratio(soft, 2 * A, 2 * B) < in_place_turn_ratio(SoilConfig(), 2 * A, 2 * B)


@pytest.mark.parametrize(
    "mu,slope,climbs",
    [
        (0.6, 12.0, True),
        (0.6, 25.0, True),  # below atan(μ − c_rr) = 28.4°
        (0.6, 30.0, False),  # a 30° grass slope
        (1.0, 30.0, True),  # atan(1 − 0.06) = 43.2°
    ],
)
def test_slope_traction_limit(mu: float, slope: float, climbs: bool) -> None:
    # 4WD on a slope θ: Σ traction ≤ μ N cos θ must beat m g sin θ + c_rr N cos θ
    soil = SoilConfig(friction=mu)
    assert (math.tan(math.radians(slope)) < mu - soil.rolling_resistance) == climbs
    w = World(RobotConfig(), soil)
    try:
        _, pos, _ = drive(w, plane(slope), 0.5, 0.0, 6.0)
    finally:
        w.close()
    along = (pos[-1, 0] - pos[0, 0]) / math.cos(math.radians(slope))
    if climbs:
        assert along > 0.3  # well above zero: climbing with slip
        assert pos[-1, 2] - pos[0, 2] == pytest.approx(
            (pos[-1, 0] - pos[0, 0]) * math.tan(math.radians(slope)), abs=0.02
        )
    else:
        assert abs(along) < 0.1  # wheels spin, the robot stays


def test_at_12_degrees_the_robot_climbs_with_the_predicted_slip(world: World) -> None:
    s, th = SoilConfig(), math.radians(12.0)
    share = (math.sin(th) + s.rolling_resistance * math.cos(th)) / (s.friction * math.cos(th))
    slip = -s.shear_modulus * math.log(1.0 - share) / s.contact_length  # steady j = l·slip
    _, pos, _ = drive(world, plane(12.0), 0.5, 0.0, 6.0)
    speed = (pos[-1, 0] - pos[-21, 0]) / math.cos(th)  # over the last second
    # tread speed 0.5 m/s on the loaded radius (a few mm of tyre deflection)
    assert speed == pytest.approx(0.5 * (1.0 - slip), rel=0.05)


@pytest.mark.parametrize("slope", [0.0, 10.0])
def test_no_creep_at_rest(world: World, slope: float) -> None:
    _, pos, _ = drive(world, plane(slope), 0.0, 0.0, 10.0)
    assert np.linalg.norm(pos[-1] - pos[0]) < 1e-3  # < 1 mm in 10 s after settling


def test_vertical_stiffness_beyond_the_stable_step_is_refused() -> None:
    from agrinav_gym.config import EnvConfig
    from scenario_gen.errors import InputError

    with pytest.raises(InputError, match="vertical_stiffness"):
        EnvConfig.from_dict({"robot": {"physics_hz": 60, "control_hz": 20}})


@pytest.mark.parametrize(
    "stiffness,damping,named",
    [
        (6e4, 0.0, "damping_ratio"),
        (6e4, 0.1, "damping_ratio"),
        (3e5, 0.3, "vertical_stiffness"),  # the default damping: the stiffness was changed
        (3e5, 2.0, "damping_ratio"),
    ],
)
def test_corner_damping_the_step_cannot_integrate_is_refused(
    stiffness: float, damping: float, named: str
) -> None:
    """These values rocked the robot over standing still (ζ = 0 is inside the old range);
    the error names the value the user changed."""
    from agrinav_gym.config import SoilConfig
    from scenario_gen.errors import InputError

    soil = SoilConfig(vertical_stiffness=stiffness, damping_ratio=damping)
    with pytest.raises(InputError) as info:
        World(RobotConfig(), soil)
    assert info.value.field == f"config.soil.{named}"


@pytest.mark.parametrize("stiffness", [5e3, 6e4, 3e5])
def test_the_least_damping_allowed_stands_still(stiffness: float) -> None:
    import math

    from agrinav_gym.config import SoilConfig
    from agrinav_gym.sim.tyres import MIN_DAMPING_PER_OMEGA_DT

    corner = 0.25 * RobotGeometry.from_urdf().mass
    zeta = 1.001 * MIN_DAMPING_PER_OMEGA_DT * math.sqrt(stiffness / corner) / 240.0
    w = World(RobotConfig(), SoilConfig(vertical_stiffness=stiffness, damping_ratio=zeta))
    try:
        w.load(plane(0.0))
        w.place_robot(0.0, 0.0, 0.0, plane(0.0))
        tilt = 0.0
        for _ in range(10 * 20):  # 10 s at 20 Hz control, standing
            w.drive(0.0, 0.0)
            w.step(12)
            s = w.state()
            tilt = max(tilt, abs(float(s.rpy[0])), abs(float(s.rpy[1])))
        assert math.degrees(tilt) < 2.0, math.degrees(tilt)
    finally:
        w.close()
