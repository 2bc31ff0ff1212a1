"""The dynamic window (XYThetaIterator) and the rollouts (StandardTrajectoryGenerator) against
literal ports of Nav2 Humble's loops."""

from __future__ import annotations

import numpy as np
import pytest

from policies.dwb.trajectories import Kinematics, dynamic_window, rollout, step_counts

from .dwb_reference import generate_trajectory, one_d_iterator

# the Summit-XL's limits (RobotInterface): 1 m/s, 1.5 rad/s, 0.6 m/s², 1.5 rad/s²
K = Kinematics(0.0, 1.0, 1.5, 0.0, 1.0, 0.0, 0.6, -0.6, 1.5, -1.5)


def test_window_is_current_velocity_plus_minus_acceleration_times_sim_time() -> None:
    tw = dynamic_window(0.2, 0.0, K, 1.7, 20, 20)
    vs, ws = np.unique(tw[:, 0]), np.unique(tw[:, 1])
    # v: [max(0, 0.2 - 0.6·1.7), min(1, 0.2 + 0.6·1.7)] = [0, 1]; ω: ±min(1.5, 1.5·1.7)
    assert vs.min() == 0.0 and vs.max() == pytest.approx(1.0)
    assert ws.min() == pytest.approx(-1.5) and ws.max() == pytest.approx(1.5)
    assert len(vs) == 20 and len(ws) == 21  # the iterator inserts ω = 0 when it steps over it
    assert not ((tw[:, 0] == 0) & (tw[:, 1] == 0)).any()  # (0, 0) is not a valid twist
    assert len(tw) == 20 * 21 - 1
    # a short horizon narrows the window around the current velocity
    tw = dynamic_window(0.5, 0.3, K, 0.1, 5, 5)
    np.testing.assert_allclose([tw[:, 0].min(), tw[:, 0].max()], [0.44, 0.56])
    np.testing.assert_allclose([tw[:, 1].min(), tw[:, 1].max()], [0.15, 0.45])
    # a current speed beyond the limits is clipped to them first
    tw = dynamic_window(1.4, 0.0, K, 0.1, 5, 5)
    assert tw[:, 0].max() == 1.0 and tw[:, 0].min() == pytest.approx(0.94)


@pytest.mark.parametrize("v0,w0", [(0.2, 0.0), (0.73, -0.4), (0.0, 1.5), (1.0, -1.5)])
def test_window_order_is_the_iterators(v0: float, w0: float) -> None:
    vs = one_d_iterator(v0, 0.0, 1.0, 0.6, -0.6, 1.7, 20)
    ws = one_d_iterator(w0, -1.5, 1.5, 1.5, -1.5, 1.7, 20)
    ref = [(v, w) for v in vs for w in ws if not (v == 0.0 and w == 0.0)]
    np.testing.assert_array_equal(dynamic_window(v0, w0, K, 1.7, 20, 20), np.array(ref))


def test_rollouts_are_generate_trajectory_bit_for_bit() -> None:
    pose, vel = (1.3, -0.4, 0.7), (0.45, 0.2)
    tw = dynamic_window(vel[0], vel[1], K, 1.7, 20, 20)
    counts = step_counts(tw, 1.7, 0.05, 0.025)
    ro = rollout(tw, pose, vel, K, 1.7, counts)
    acc = (K.acc_lim_x, K.decel_lim_x, K.acc_lim_theta, K.decel_lim_theta)
    for i in range(0, len(tw), 7):
        ref = np.array(generate_trajectory(pose, vel, tuple(tw[i]), acc, 1.7, 0.05, 0.025))
        assert ro.length[i] == len(ref)
        np.testing.assert_array_equal(ro.poses[i, : len(ref)], ref)
        assert (ro.poses[i, len(ref) :] == ref[-1]).all()  # padding repeats the last pose


def test_rollout_ramps_with_the_acceleration_limit() -> None:
    tw = np.array([[1.0, 0.0], [0.5, 0.5]])
    counts = step_counts(tw, 1.7, 0.05, 0.025)
    assert list(counts) == [34, 34]  # 1.7 m / 0.05 m; 0.85 rad / 0.025 rad
    ro = rollout(tw, (0.0, 0.0, 0.0), (0.0, 0.0), K, 1.7, counts)
    # from rest at 0.6 m/s², capped at the 1 m/s command: Σ_k min(1, 0.6·k·dt)·dt, 34 steps
    dt = 1.7 / 34
    ref = sum(min(1.0, 0.6 * k * dt) * dt for k in range(1, 35))
    assert ro.poses[0, -1, 0] == pytest.approx(ref, rel=1e-12)
    assert ro.poses[0, -1, 1] == 0.0
