"""robot_localization with ``two_d_mode: false`` (estimation/robot_localization_3d.py): its
transition and Jacobian, a leaning GNSS mast removed through the filter's roll, and the same
convergence as the planar filter on flat ground."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agrinav_gym.config import LocalisationConfig, RobotLocalizationConfig
from agrinav_gym.estimation import Readings, make_estimator
from agrinav_gym.estimation.robot_localization import RobotLocalizationEkf
from agrinav_gym.estimation.robot_localization_3d import (
    PITCH,
    ROLL,
    YAW,
    RobotLocalizationEkf3D,
)
from agrinav_gym.interface import GNSS_RTK_FIXED
from scenario_gen.obstacles import rotation

from .helpers import make
from .localisation_helpers import CHI, DT, drive

SETTLE = 200  # steps (10 s)
LEVER = np.array([-0.25, 0.0, 0.6])
SIGMA_FIXED = 0.01 / 1.1774  # the receiver's reported per-axis σ in RTK fixed


def rl(**kw: object) -> LocalisationConfig:
    return LocalisationConfig(
        kind="robot_localization",
        robot_localization=RobotLocalizationConfig(gps_lever_arm=True, **kw),  # type: ignore[arg-type]
    )


def test_two_d_mode_chooses_the_filter() -> None:
    assert type(make_estimator("robot_localization", rl(), CHI, DT)) is RobotLocalizationEkf
    est = make_estimator("robot_localization", rl(two_d_mode=False), CHI, DT)
    assert isinstance(est, RobotLocalizationEkf3D)
    assert est.name == "robot_localization"


def test_jacobian_is_the_transitions_derivative() -> None:
    """Every entry is the derivative of the transition, but one: ∂yaw/∂pitch carries
    robot_localization's sign for its yaw-rate term (Ekf::predict)."""
    est = RobotLocalizationEkf3D(rl(two_d_mode=False), CHI, DT)
    rng = np.random.default_rng(7)
    s = rng.normal(0.0, 0.5, 15)
    s[ROLL], s[PITCH], s[YAW] = 0.2, -0.3, 1.1
    dt = 0.05
    _, J = est.transition(s, dt)
    num = np.empty((15, 15))
    h = 1e-6
    for j in range(15):
        d = np.zeros(15)
        d[j] = h
        up, _ = est.transition(s + d, dt)
        down, _ = est.transition(s - d, dt)
        num[:, j] = (up - down) / (2 * h)
    vp, vy = s[10], s[11]
    cp, sp, sr, cr = math.cos(s[PITCH]), math.sin(s[PITCH]), math.sin(s[ROLL]), math.cos(s[ROLL])
    derivative = (sr * vp + cr * vy) * sp / cp**2 * dt
    assert num[YAW, PITCH] == pytest.approx(derivative, abs=1e-8)
    assert J[YAW, PITCH] == pytest.approx((sr * vp - cr * vy) * sp / cp**2 * dt, abs=1e-12)
    num[YAW, PITCH] = J[YAW, PITCH]
    np.testing.assert_allclose(J, num, atol=1e-8)


def test_transition_moves_along_the_tilted_body_axis() -> None:
    est = RobotLocalizationEkf3D(rl(two_d_mode=False), CHI, DT)
    s = np.zeros(15)
    s[PITCH], s[YAW], s[6] = math.radians(10.0), math.radians(30.0), 1.0  # 1 m/s forward
    new, _ = est.transition(s, 1.0)
    # pitched 10° heading 30°: cos 10° of the metre is horizontal, and a positive pitch points
    # the nose down (REP 103), so it descends sin 10°
    c, s10 = math.cos(math.radians(10.0)), math.sin(math.radians(10.0))
    heading = math.radians(30.0)
    assert new[:3] == pytest.approx([c * math.cos(heading), c * math.sin(heading), -s10])


def rolled(roll: float, new: bool) -> Readings:
    """A robot at rest at the origin facing east, rolled by ``roll`` (its IMU says so); the
    antenna is where the rolled mast puts it."""
    ant = rotation(roll, 0.0, 0.0) @ LEVER
    g = 9.80665
    return Readings(
        gnss_enu=ant,
        gnss_new=new,
        gnss_mode=GNSS_RTK_FIXED,
        gnss_sigma=np.full(3, SIGMA_FIXED),
        gnss_age=0.0,
        accel=np.array([0.0, g * math.sin(roll), g * math.cos(roll)]),
        gyro=np.zeros(3),
        rpy=np.array([roll, 0.0, 0.0]),
        odom=np.zeros(2),
        antenna_lever=LEVER,
    )


@pytest.mark.parametrize("roll_deg", [-12.0, 6.0, 12.0])
def test_a_leaning_mast_is_removed_through_the_filters_roll(roll_deg: float) -> None:
    roll = math.radians(roll_deg)
    errors = {}
    for two_d in (True, False):
        est = make_estimator("robot_localization", rl(two_d_mode=two_d), CHI, DT)
        est.reset(0.0, 0.0, 0.0, np.random.default_rng(0))
        for k in range(200):
            est.update(rolled(roll, new=k % 2 == 0), DT)
        errors[two_d] = est.pose[:2]
    # in two_d_mode the fix's lean stays in the estimate: the mast's height times sin(roll),
    # across the robot
    x2, y2 = errors[True]
    assert abs(x2) < 0.005
    assert y2 == pytest.approx(-LEVER[2] * math.sin(roll), abs=0.005)
    # with roll in the filter it is removed
    assert math.hypot(*errors[False]) < 0.005


@pytest.mark.parametrize(("yaw_rate", "accel"), [(False, False), (True, True)])
def test_converges_on_flat_ground_as_the_planar_filter(yaw_rate: bool, accel: bool) -> None:
    loc = rl(two_d_mode=False, fuse_imu_yaw_rate=yaw_rate, fuse_imu_acceleration=accel)
    for seed in range(3):
        d3 = drive("robot_localization", GNSS_RTK_FIXED, seed, loc=loc)
        e = d3.errors[SETTLE:, :2]
        rms3 = float(np.sqrt(np.mean(np.sum(e * e, axis=1))))
        assert abs(d3.errors[SETTLE:, 2]).max() < math.radians(3)
        assert rms3 < 0.06  # the planar filter's bound (test_robot_localization.py)
        P = d3.covariances
        assert np.allclose(P, np.transpose(P, (0, 2, 1)))
        assert (np.linalg.eigvalsh(P) > 0).all()


def test_env_runs_it_and_the_row_says_so() -> None:
    config = {
        "localisation": {
            "kind": "robot_localization",
            "robot_localization": {"two_d_mode": False, "gps_lever_arm": True},
        }
    }
    env = make(config=config)
    try:
        env.reset(seed=0)
        for _ in range(40):
            _, _, _, _, info = env.step(np.array([0.5, 0.0], np.float32))
        assert isinstance(env.unwrapped.estimator, RobotLocalizationEkf3D)
        # RTK fixed, the lever arm known: the fix's latency taken as current is what is left
        assert info["localisation"]["position_error"] < 0.05
        label = env.unwrapped.conditions()["localisation"]
        assert label.startswith("robot_localization (3D: imu roll and pitch, gps lever arm")
    finally:
        env.close()
