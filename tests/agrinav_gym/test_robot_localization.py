"""robot_localization as a Nav2 user runs it (estimation/robot_localization.py): convergence
under RTK fixed, Mahalanobis rejection, lagged data as robot_localization handles it, the
navsat lever arm, and ``ekf-oracle`` as another name for ``ekf``."""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import pytest

from agrinav_gym.config import LocalisationConfig, RobotLocalizationConfig
from agrinav_gym.estimation import Readings, make_estimator
from agrinav_gym.estimation.robot_localization import RobotLocalizationEkf
from agrinav_gym.interface import GNSS_NONE, GNSS_RTK_FIXED, GNSS_RTK_FLOAT

from .helpers import make
from .localisation_helpers import CHI, DT, drive

SETTLE = 200  # steps (10 s)
LEVER = np.array([-0.25, 0.0, 0.6])
SIGMA_FIXED = 0.01 / 1.1774  # the receiver's reported per-axis σ in RTK fixed


def rl(**kw: object) -> LocalisationConfig:
    return LocalisationConfig(
        kind="robot_localization", robot_localization=RobotLocalizationConfig(**kw)
    )


@pytest.mark.parametrize(("yaw_rate", "accel"), [(False, False), (True, False), (True, True)])
def test_converges_under_rtk_fixed(yaw_rate: bool, accel: bool) -> None:
    loc = rl(gps_lever_arm=True, fuse_imu_yaw_rate=yaw_rate, fuse_imu_acceleration=accel)
    rms = []
    for seed in range(4):
        d = drive("robot_localization", GNSS_RTK_FIXED, seed, loc=loc)
        e = d.errors[SETTLE:, :2]
        rms.append(float(np.sqrt(np.mean(np.sum(e * e, axis=1)))))
        assert abs(d.errors[SETTLE:, 2]).max() < math.radians(3)
    # a few cm: the fix's 1 cm plus the fix's latency, which the filter takes as current
    assert np.mean(rms) < 0.06


def test_recovers_from_a_position_error_under_rtk_fixed() -> None:
    est = RobotLocalizationEkf(rl(gps_lever_arm=True), CHI, DT)
    rng = np.random.default_rng(0)
    est.reset(0.0, 0.0, 0.0, rng)
    est.update(still(np.zeros(2), new=True), DT)
    for k in range(1, 400):
        if k == 100:  # knock the estimate 1 m off
            est.s[0] += 1.0
        est.update(still(np.zeros(2), new=k % 2 == 0), DT)
        if k == 140:  # 2 s later (20 fixes) it is back within centimetres
            assert math.hypot(*est.pose[:2]) < 0.02
    assert math.hypot(*est.pose[:2]) < 0.01


def still(
    antenna_xy: np.ndarray, new: bool, age: float = 0.0, mode: str = GNSS_RTK_FIXED
) -> Readings:
    """One control step of a robot at rest at the origin facing east (antenna behind it)."""
    ant = np.array([antenna_xy[0] + LEVER[0], antenna_xy[1], LEVER[2]])
    return Readings(
        gnss_enu=ant,
        gnss_new=new,
        gnss_mode=mode,
        gnss_sigma=np.full(3, SIGMA_FIXED),
        gnss_age=age,
        accel=np.array([0.0, 0.0, 9.81]),
        gyro=np.zeros(3),
        rpy=np.zeros(3),
        odom=np.zeros(2),
        antenna_lever=LEVER,
    )


@pytest.mark.parametrize("threshold", [None, 5.0])
def test_mahalanobis_rejection_drops_an_injected_jump(threshold: float | None) -> None:
    est = RobotLocalizationEkf(rl(gps_lever_arm=True, gps_rejection_threshold=threshold), CHI, DT)
    est.reset(0.0, 0.0, 0.0, np.random.default_rng(1))
    est.update(still(np.zeros(2), new=True), DT)
    for k in range(1, 101):
        est.update(still(np.zeros(2), new=k % 2 == 0), DT)
    assert math.hypot(*est.pose[:2]) < 1e-3
    est.update(still(np.array([0.0, 1.0]), new=True), DT)  # a 1 m multipath jump
    moved = math.hypot(*est.pose[:2])
    if threshold is None:  # robot_localization's default: every reading is fused
        assert moved > 0.5 and est.rejected["gps"] == 0
    else:
        assert moved < 1e-3 and est.rejected["gps"] == 1
    # the next good fixes are accepted again either way
    for k in range(20):
        est.update(still(np.zeros(2), new=k % 2 == 0), DT)
    assert math.hypot(*est.pose[:2]) < (0.05 if threshold is None else 1e-3)


def _imu(accel_body: np.ndarray, roll: float, pitch: float, odom_v: float = 0.0) -> Readings:
    """A step whose IMU reads the body acceleration ``accel_body`` plus gravity's reaction
    at attitude (roll, pitch), and whose odometry reads ``odom_v``."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    up = np.array([-sp, sr * cp, cr * cp])  # the world's up axis in the body frame
    r = still(np.zeros(2), new=False)
    return replace(
        r,
        accel=accel_body + 9.81 * up,
        rpy=np.array([roll, pitch, 0.0]),
        odom=np.array([odom_v, 0.0]),
    )


def test_fused_acceleration_is_the_specific_force_less_gravity() -> None:
    tilt = {"roll": math.radians(-3.0), "pitch": math.radians(6.0)}

    def at_rest(**kw: object) -> RobotLocalizationEkf:
        est = RobotLocalizationEkf(rl(fuse_imu_acceleration=True, **kw), CHI, DT)
        est.reset(0.0, 0.0, 0.0, np.random.default_rng(0))
        for _ in range(100):  # standing 6° nose-up and 3° to the side: gravity alone
            est.update(_imu(np.zeros(3), **tilt), DT)
        return est

    est = at_rest()
    assert abs(est.s[6]) < 1e-3 and abs(est.s[7]) < 1e-3  # nothing left once it is removed
    v = 0.0
    for _ in range(60):  # speeding up at 0.5 m/s² on the same slope, odometry following
        v += 0.5 * DT
        est.update(_imu(np.array([0.5, 0.0, 0.0]), odom_v=v, **tilt), DT)
    assert est.s[6] == pytest.approx(0.5, abs=0.05) and abs(est.s[7]) < 0.02
    # a 3 g knock: fused by default, dropped (and counted as the IMU's) behind a 5σ gate
    for gate in (None, 5.0):
        est = at_rest(imu_accel_rejection_threshold=gate)
        est.update(_imu(np.array([30.0, 0.0, 0.0]), **tilt), DT)
        if gate is None:
            assert est.s[6] > 1.0 and est.rejected["imu"] == 0
        else:
            assert abs(est.s[6]) < 1e-3 and est.rejected["imu"] == 1


def test_a_late_fix_is_fused_as_if_current_by_default() -> None:
    # driving at 0.8 m/s, a fix 0.1 s old is 8 cm behind the robot: fused into the current
    # state (smooth_lagged_data off), it pulls the estimate back along the track
    lag, smooth = [], []
    for seed in range(4):
        for loc, out in (
            (rl(gps_lever_arm=True), lag),
            (rl(gps_lever_arm=True, smooth_lagged_data=True, history_length_s=1.0), smooth),
        ):
            d = drive("robot_localization", GNSS_RTK_FIXED, seed, loc=loc)
            out.append(float(np.mean(d.along_across()[SETTLE:, 0])))
    assert np.mean(lag) < -0.02  # behind: part of speed × latency
    assert abs(np.mean(smooth)) < 0.01  # applied at its epoch: no lag


def _sequence(
    est: RobotLocalizationEkf, fix_at: int, deliver_at: int, steps: int
) -> list[np.ndarray]:
    """The robot drives east at 0.5 m/s; the receiver has a fix at the start and one taken at
    step ``fix_at``, delivered at ``deliver_at``. The states after each step."""
    est.reset(0.0, 0.0, 0.0, np.random.default_rng(2))
    out = []
    for k in range(steps):
        x = 0.5 * DT * k
        new = k == 0 or k == deliver_at
        taken = 0.5 * DT * fix_at + 0.003  # the second fix is 3 mm off
        r = still(np.array([x if k == 0 else taken, 0.0]), new, age=(deliver_at - fix_at) * DT)
        r = replace(r, odom=np.array([0.5, 0.0]), gnss_age=0.0 if k == 0 else r.gnss_age)
        est.update(r, DT)
        out.append(est.s.copy())
    return out


def test_smooth_lagged_data_applies_a_late_fix_at_its_epoch() -> None:
    cfg = rl(gps_lever_arm=True, smooth_lagged_data=True, history_length_s=1.0)
    on_time = _sequence(RobotLocalizationEkf(cfg, CHI, DT), 10, 10, 20)
    late = _sequence(RobotLocalizationEkf(cfg, CHI, DT), 10, 12, 20)
    for k in range(12, 20):  # once delivered, the late fix has done what the timely one did
        assert np.allclose(late[k], on_time[k], rtol=0, atol=1e-12)
    assert not np.allclose(late[10], on_time[10])


def test_without_smoothing_a_late_fix_corrects_the_current_state() -> None:
    cfg = rl(gps_lever_arm=True)
    est = RobotLocalizationEkf(cfg, CHI, DT, native=False)  # the reference's own steps below
    before = _sequence(est, 10, 12, 12)[-1]  # the state after step 11
    t_last = est.t_last
    # what robot_localization does with the fix (stamped two steps ago) at step 12: a
    # correction of the state at its last time, then the step's odometry and IMU
    expect = copy.deepcopy(est)
    r = replace(
        still(np.array([0.5 * DT * 10 + 0.003, 0.0]), True, age=2 * DT),
        odom=np.array([0.5, 0.0]),
    )
    expect.k += 1
    fix = expect._gps(r, (expect.k - 2) * DT)
    assert fix.time < t_last
    expect._correct(fix)
    assert expect.t_last == t_last  # no prediction back, no clock change
    for m in (expect._odom(r, expect.k * DT), expect._imu_orientation(r, expect.k * DT)):
        expect._process(m)
    est.update(r, DT)
    assert np.array_equal(est.s, expect.s)
    assert not np.array_equal(est.s, before)


def test_navsat_without_a_lever_arm_takes_the_antenna_as_base_link() -> None:
    d = drive("robot_localization", GNSS_RTK_FIXED, 0, loc=rl())
    along, across = d.along_across()[SETTLE:].T
    # the antenna is 0.25 m behind base_link: the estimate is that far back along the track
    assert np.mean(along) == pytest.approx(-0.25, abs=0.08)
    assert np.sqrt(np.mean(across**2)) < 0.05  # across the track the rows do not see it


def test_first_fix_sets_the_datum_when_the_receiver_starts_without_one() -> None:
    est = RobotLocalizationEkf(rl(gps_lever_arm=True), CHI, DT)
    est.reset(3.0, -2.0, 0.0, np.random.default_rng(3))  # the start prior, 0.5 m σ
    est.update(still(np.zeros(2), new=False, mode=GNSS_NONE), DT)
    assert math.hypot(est.pose[0] - 3.0, est.pose[1] + 2.0) < 2.5
    for _ in range(1, 10):
        est.update(still(np.zeros(2), new=False, mode=GNSS_NONE), DT)
    est.update(still(np.zeros(2), new=True), DT)
    assert est.anchored and math.hypot(*est.pose[:2]) < 1e-9


def test_covariance_stays_symmetric_positive() -> None:
    d = drive("robot_localization", "standalone", 3, seconds=20.0, loc=rl())
    P = d.covariances
    assert np.allclose(P, np.transpose(P, (0, 2, 1)))
    assert (np.linalg.eigvalsh(P) > 0).all()


def test_ekf_oracle_is_another_name_for_ekf() -> None:
    a, b = drive("ekf", GNSS_RTK_FLOAT, 4, seconds=5.0), drive("ekf-oracle", GNSS_RTK_FLOAT, 4, 5.0)
    assert np.array_equal(a.errors, b.errors)
    assert make_estimator("ekf-oracle").name == "ekf-oracle"
    assert make_estimator("ekf").name == "ekf"


@pytest.mark.parametrize("kind", ["robot_localization", "ekf-oracle"])
def test_env_runs_the_estimator(kind: str) -> None:
    env = make(config={"localisation": {"kind": kind}})
    try:
        env.reset(seed=0)
        for _ in range(40):
            _, _, _, _, info = env.step(np.array([0.5, 0.0], np.float32))
        loc = info["localisation"]
        assert loc["estimator"] == kind
        # RTK fixed: the oracle within centimetres; robot_localization without the lever arm
        # within the 0.25 m antenna offset plus the latency it takes as current
        assert loc["position_error"] < (0.03 if kind == "ekf-oracle" else 0.4)
        assert env.unwrapped.conditions()["localisation"].startswith(kind)
    finally:
        env.close()


def test_a_row_names_what_robot_localization_sets_beyond_its_defaults() -> None:
    tuned = {
        "gps_lever_arm": True,
        "smooth_lagged_data": True,
        "history_length_s": 1.0,
        "gps_rejection_threshold": 5.0,
        "fuse_imu_acceleration": True,
    }
    for rl, says in (({}, "robot_localization (defaults)"), (tuned, "gps gate 5σ")):
        env = make(
            config={"localisation": {"kind": "robot_localization", "robot_localization": rl}}
        )
        try:
            label = env.unwrapped.conditions()["localisation"]
        finally:
            env.close()
        assert says in label
    assert "gps lever arm, smooth_lagged_data 1 s" in label and "imu acceleration" in label
