"""The compiled robot_localization filter (``render/csrc/rl.c``) against its numpy twin
(``estimation/robot_localization.py``), reading for reading, on the synthetic drive's sensors:
the same state to rounding, the same readings rejected, the same late fixes replayed."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from agrinav_gym.config import LocalisationConfig, RobotLocalizationConfig
from agrinav_gym.estimation import Readings
from agrinav_gym.estimation.robot_localization import RobotLocalizationEkf
from agrinav_gym.interface import GNSS_RTK_FIXED, GNSS_RTK_FLOAT, GNSS_STANDALONE
from agrinav_gym.render import native

from .helpers import make
from .localisation_helpers import CHI, DT, drive

pytestmark = pytest.mark.skipif(not native.available(), reason="compiled kernels not built")

#: how far the two may drift apart over a drive: numpy's BLAS and LAPACK sum and pivot in
#: another order than the kernel's loops, a few ulps a step that the filter does not amplify
#: (measured ≤ 1e-15 m over 6,561 updates of recorded benchmark episodes)
TOL = 1e-9


def rl(**kw: Any) -> LocalisationConfig:
    return LocalisationConfig(
        kind="robot_localization", robot_localization=RobotLocalizationConfig(**kw)
    )


class Twin:
    """Both filters on the same readings; the numpy one's pose drives the rest."""

    name = "robot_localization"

    def __init__(self, loc: LocalisationConfig) -> None:
        self.ref = RobotLocalizationEkf(loc, CHI, DT, native=False)
        self.kernel = RobotLocalizationEkf(loc, CHI, DT, native=True)
        self.worst_s = self.worst_p = 0.0
        self.reverts = 0
        revert = self.ref._revert

        def counted(time: float) -> Any:
            self.reverts += 1
            return revert(time)

        self.ref._revert = counted  # type: ignore[method-assign]

    def reset(self, x: float, y: float, yaw: float, rng: np.random.Generator) -> None:
        # each takes its child stream from its own copy, as it would alone
        self.ref.reset(x, y, yaw, copy.deepcopy(rng))
        self.kernel.reset(x, y, yaw, rng)

    def update(self, r: Readings, dt: float) -> None:
        a, b = self.ref, self.kernel
        a.update(r, dt)
        b.update(r, dt)
        assert (a.k, a.t_last, a.anchored, a.rejected) == (b.k, b.t_last, b.anchored, b.rejected)
        self.worst_s = max(self.worst_s, float(np.max(np.abs(a.s - b.s))))
        scale = max(1.0, float(np.max(np.abs(a.P))))
        self.worst_p = max(self.worst_p, float(np.max(np.abs(a.P - b.P))) / scale)

    @property
    def pose(self) -> tuple[float, float, float]:
        return self.ref.pose

    @property
    def covariance(self) -> np.ndarray:
        return self.ref.covariance


CASES = {
    # robot_localization's defaults: no lever arm, late fixes fused as current, no gates
    "defaults": (rl(), GNSS_RTK_FIXED, 0.1),
    # the benchmark's setup (baselines.suites.RTK_NAV2) under a float solution
    "benchmark": (
        rl(
            gps_lever_arm=True,
            smooth_lagged_data=True,
            history_length_s=1.0,
            gps_rejection_threshold=5.0,
        ),
        GNSS_RTK_FLOAT,
        0.1,
    ),
    # every reading gated tightly, the IMU's rate and acceleration fused: rejections happen
    "gated": (
        rl(
            gps_lever_arm=True,
            fuse_imu_yaw_rate=True,
            fuse_imu_acceleration=True,
            odom_rejection_threshold=1.0,
            imu_rejection_threshold=1.0,
            imu_accel_rejection_threshold=1.0,
            gps_rejection_threshold=1.0,
        ),
        GNSS_STANDALONE,
        0.1,
    ),
    # fixes a third of a second late in a half-second history: reverts and replays
    "late fixes": (
        rl(smooth_lagged_data=True, history_length_s=0.5, fuse_imu_yaw_rate=True),
        GNSS_RTK_FIXED,
        0.35,
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_kernel_is_the_numpy_filter_to_rounding(case: str) -> None:
    loc, mode, latency = CASES[case]
    twin = Twin(loc)
    drive("robot_localization", mode, 3, seconds=30.0, latency=latency, estimator=twin)
    assert twin.worst_s < TOL and twin.worst_p < TOL
    if case == "gated":
        assert sum(twin.ref.rejected.values()) > 0
    if case in ("benchmark", "late fixes"):
        assert twin.reverts > 0


def test_the_env_runs_the_kernel_and_its_rollout_is_the_numpy_filters() -> None:
    """Where the extension is built the env's robot_localization is the kernel; an episode
    with the numpy twin swapped in keeps the same estimates to rounding over the same moves,
    and the same true poses to the bit: the policy's float32 action absorbs the rounding."""
    poses, truth = {}, {}
    for twin in (False, True):
        env = make(config={"localisation": {"kind": "robot_localization"}})
        try:
            u = env.unwrapped
            assert u.estimator.native
            if twin:
                u.estimator = RobotLocalizationEkf(
                    u.cfg.localisation, u.world.skid_factor, u.dt, False
                )
            env.reset(seed=4)
            est, true = [], []
            for _ in range(150):
                _, _, term, trunc, _ = env.step(np.array([0.6, 0.0], np.float32))
                est.append(u.estimator.pose)
                true.append(u.state.pos.copy())
                if term or trunc:
                    break
            poses[twin], truth[twin] = np.asarray(est), np.asarray(true)
        finally:
            env.close()
    assert len(poses[True]) == len(poses[False]) > 50
    assert np.max(np.abs(poses[True] - poses[False])) < TOL
    np.testing.assert_array_equal(truth[True], truth[False])


def test_a_history_too_short_for_the_queue_is_refused_not_overrun() -> None:
    """The kernel's rings are sized from history_length_s; if they were too small it says so
    (a KernelError) instead of writing past them."""
    est = RobotLocalizationEkf(rl(smooth_lagged_data=True, history_length_s=1.0), CHI, DT, True)
    est.reset(0.0, 0.0, 0.0, np.random.default_rng(0))
    est._filter.capacity = 2  # a deliberately short ring (the kernel checks, numpy does not)
    r = Readings(
        np.zeros(3), True, GNSS_RTK_FIXED, np.full(3, 0.01), 0.0, np.array([0.0, 0.0, 9.8]),
        np.zeros(3), np.zeros(3), np.array([0.5, 0.0]), np.zeros(3),
    )  # fmt: skip
    with pytest.raises(native.KernelError, match="rl_update"):
        for _ in range(10):
            est.update(r, DT)
    assert math.isfinite(est.pose[0])
