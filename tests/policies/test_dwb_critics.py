"""DWB critics on hand-made trajectories, scored as Nav2 scores them (distances in cells)."""

import math

import numpy as np
import pytest

from policies.dwb import (
    REJECT,
    DWBParams,
    base_obstacle,
    goal_align,
    goal_dist,
    oscillation,
    path_align,
    path_dist,
    rollout,
    rotate_to_goal,
    velocity_samples,
)

RES = 0.05
PLAN = np.column_stack([np.linspace(0, 3, 61), np.zeros(61)])  # straight along x, 5 cm apart


def traj(*end_poses: tuple[float, float, float]) -> np.ndarray:
    """Trajectories from the origin to each end pose (only the ends matter to these critics)."""
    return np.array([[[0.0, 0.0, 0.0], list(e)] for e in end_poses])


def test_path_dist_counts_cells_from_the_last_pose() -> None:
    t = traj((1.0, 0.10, 0.0), (1.0, -0.25, 0.0), (1.0, 0.0, 0.0))
    np.testing.assert_allclose(path_dist(t, PLAN, RES), [2.0, 5.0, 0.0])


def test_goal_dist_counts_cells_to_the_local_goal() -> None:
    t = traj((1.0, 0.0, 0.0), (2.0, 0.0, 0.0))
    np.testing.assert_allclose(goal_dist(t, np.array([3.0, 0.0]), RES), [40.0, 20.0])


def test_align_critics_score_the_forward_point() -> None:
    # facing 90° off the path, the point 0.3 m ahead is 0.3 m (6 cells) from it
    t = traj((1.0, 0.0, math.pi / 2), (1.0, 0.0, 0.0))
    np.testing.assert_allclose(path_align(t, PLAN, RES, 0.3), [6.0, 0.0], atol=1e-9)
    goal = np.array([3.0, 0.0])
    np.testing.assert_allclose(
        goal_align(t, goal, RES, 0.3), [math.hypot(2.0, 0.3) / RES, (2.0 - 0.3) / RES]
    )


def test_rotate_to_goal_only_near_the_goal() -> None:
    twists = np.array([[0.3, 0.0], [0.0, 0.5]])
    t = traj((0.5, 0.0, 0.0), (0.0, 0.0, 0.4))
    far = rotate_to_goal(t, twists, np.array([2.0, 0.0]), 0.0, 0.25)
    np.testing.assert_array_equal(far, [0.0, 0.0])
    near = rotate_to_goal(t, twists, np.array([0.1, 0.0]), 0.5, 0.25)
    assert near[0] == REJECT  # no translating once inside the xy tolerance
    assert near[1] == pytest.approx(0.1)  # |0.4 - 0.5| rad left to turn


def test_oscillation_rejects_flips_until_the_robot_moves() -> None:
    twists = np.array([[0.5, 0.4], [0.5, -0.4], [0.5, 0.0]])
    np.testing.assert_array_equal(oscillation(twists, (0.5, 0.3), 0.0, 0.05), [0.0, REJECT, 0.0])
    np.testing.assert_array_equal(oscillation(twists, (0.5, 0.3), 0.06, 0.05), [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(oscillation(twists, None, 0.0, 0.05), [0.0, 0.0, 0.0])


def test_base_obstacle_sums_costs_and_rejects_lethal() -> None:
    grid = np.zeros((40, 40))
    grid[20, 20] = 254.0  # lethal at (1.0, 0.0) with origin (0, -1)
    grid[10, 20] = 100.0  # cost 100 at (0.5, 0.0)
    origin = np.array([0.0, -1.0])
    t = np.array(
        [
            [[0.0, 0.0, 0.0], [0.51, 0.0, 0.0], [1.01, 0.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.51, 0.0, 0.0], [0.9, 0.3, 0.0]],
        ]
    )
    score = base_obstacle(t, grid, origin, 0.05)
    assert score[0] == REJECT and score[1] == pytest.approx(100.0)


def test_dynamic_window_and_rollout_respect_acceleration() -> None:
    p = DWBParams()
    tw = velocity_samples(0.2, 0.0, p)
    assert tw.shape == (p.vx_samples * p.vtheta_samples, 2)
    # window: current ± acc × sim_time, clipped to the limits
    assert tw[:, 0].min() == pytest.approx(0.0) and tw[:, 0].max() == pytest.approx(
        min(1.0, 0.2 + 0.6 * 1.7)
    )
    poses = rollout(np.array([[1.0, 0.0]]), 0.0, 0.0, p)
    # from rest at 0.6 m/s² for 1.7 s (never reaching 1 m/s): ½·a·t² ahead, straight
    assert poses[0, -1, 0] == pytest.approx(0.5 * 0.6 * 1.7**2, rel=0.05)
    assert abs(poses[0, -1, 1]) < 1e-12
    arc = rollout(np.array([[0.5, 0.5]]), 0.5, 0.5, p)
    # constant twist: a circle of radius v/ω = 1 m through the origin, integrated with forward
    # Euler steps as Nav2's computeNewPosition does (≈1 % radial drift over 0.85 rad)
    x, y = arc[0, -1, 0], arc[0, -1, 1]
    assert math.hypot(x, y - 1.0) == pytest.approx(1.0, rel=0.02)
    assert arc[0, -1, 2] == pytest.approx(0.5 * 1.7)
