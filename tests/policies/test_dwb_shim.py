"""Nav2's RotationShimController in front of DWB: when it turns, how fast, when it hands over,
and what the Nav2 export writes for it."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from policies import make_policy
from policies.dwb.costmap import LETHAL, Grid, rectangle_footprint
from policies.dwb.params import DWBParams, RotationShimParams, _shipped
from policies.dwb.shim import RotationShim, footprint_cost
from scenario_gen.errors import InputError

DT = 0.05
W_MAX, ALPHA = 1.5, 3.0
FOOT = rectangle_footprint(0.72, 0.62)


def _shim(**kw: float) -> RotationShim:
    return RotationShim(RotationShimParams(enabled=True, **kw), W_MAX, ALPHA, DT, FOOT)


def _line(angle: float, length: float = 3.0) -> np.ndarray:
    s = np.arange(0.0, length, 0.05)
    return np.column_stack([s * math.cos(angle), s * math.sin(angle)])


def _free_map() -> tuple[Grid, np.ndarray]:
    return Grid(-1.5, -1.5, 60, 60, 0.05), np.zeros((60, 60), np.uint8)


def test_a_plan_off_the_heading_turns_the_robot_in_place_at_the_acceleration_limit() -> None:
    shim, (grid, cost) = _shim(), _free_map()
    shim.set_plan(_line(math.pi / 2))  # the new leg starts 90° to the left
    w = shim.command((0.0, 0.0, 0.0), 0.0, grid, cost)
    assert w == pytest.approx(ALPHA * DT)  # one control period of angular acceleration
    w = shim.command((0.0, 0.0, 0.0), 1.4, grid, cost)
    assert w == pytest.approx(W_MAX)  # then the turn's rate, never more
    # to the right: the same, mirrored
    shim.set_plan(_line(-math.pi / 2))
    assert shim.command((0.0, 0.0, 0.0), 0.0, grid, cost) == pytest.approx(-ALPHA * DT)


def test_within_the_threshold_dwb_drives_until_the_next_plan() -> None:
    shim, (grid, cost) = _shim(), _free_map()
    shim.set_plan(_line(math.pi / 2))
    # the robot has turned to 50° off the plan: still above 45°, still turning
    assert shim.command((0.0, 0.0, math.radians(40)), 1.5, grid, cost) is not None
    # 44° off: handed over, and it stays with DWB whatever the heading until a new plan
    assert shim.command((0.0, 0.0, math.radians(46)), 1.5, grid, cost) is None
    assert shim.command((0.0, 0.0, 0.0), 0.0, grid, cost) is None
    shim.set_plan(_line(math.pi / 2))
    assert shim.command((0.0, 0.0, 0.0), 0.0, grid, cost) is not None


def test_a_plan_shorter_than_the_sampling_distance_goes_to_dwb() -> None:
    shim, (grid, cost) = _shim(), _free_map()
    shim.set_plan(_line(math.pi / 2, length=0.45))
    assert shim.command((0.0, 0.0, 0.0), 0.0, grid, cost) is None


def test_a_turn_into_an_obstacle_is_left_to_dwb_as_nav2_checks_it() -> None:
    """isCollisionFree simulates the turn for simulate_ahead_time, but stops where the plan
    would be handed over — for a turn to the right only (Nav2's sign)."""
    grid, cost = _free_map()
    # a lethal cell where a front corner is after turning 10° that way, on both sides
    for sign in (1, -1):
        a = sign * math.radians(10)
        cx, cy = FOOT[np.argmax(FOOT[:, 0] + sign * FOOT[:, 1])]  # front-left / front-right
        x, y = cx * math.cos(a) - cy * math.sin(a), cx * math.sin(a) + cy * math.cos(a)
        mx, my, _ = grid.world_to_map(np.array([x]), np.array([y]))
        cost[mx[0], my[0]] = LETHAL
        assert footprint_cost(grid, cost, FOOT, (0.0, 0.0, a)) == LETHAL
    assert footprint_cost(grid, cost, FOOT, (0.0, 0.0, 0.0)) < LETHAL
    left, right = _shim(), _shim()
    left.set_plan(_line(math.radians(50)))  # 5° past the threshold
    right.set_plan(_line(math.radians(-50)))
    # left: checked for the whole second, meets the cell → DWB drives
    assert left.command((0.0, 0.0, 0.0), 1.5, grid, cost) is None
    # right: checked only for the 5° before the hand-over → turns
    assert right.command((0.0, 0.0, 0.0), -1.5, grid, cost) is not None


def test_dwb_configs_can_change_a_shipped_one(tmp_path: Path) -> None:
    f = tmp_path / "tuned_shim.yaml"
    f.write_text("base: tuned\nrotation_shim: {enabled: true}\n")
    p = DWBParams.load(f)
    tuned = DWBParams.load("tuned")
    assert p.rotation_shim.enabled and not tuned.rotation_shim.enabled
    assert p.FollowPath == tuned.FollowPath and p.local_costmap == tuned.local_costmap
    f.write_text("base: fast\n")
    with pytest.raises(InputError, match="dwb.base.*nav2, furrow, tuned"):
        DWBParams.load(f)
    shipped = Path(__file__).parents[2] / "benchmarks"
    for name, base in (("dwb_tuned_shim", "tuned"), ("dwb_furrow_shim", "furrow")):
        q = DWBParams.load(shipped / f"{name}.yaml")
        assert q.rotation_shim.enabled and q.FollowPath == DWBParams.load(base).FollowPath


def test_dwb_with_the_shim_turns_in_place_toward_a_new_leg_and_then_drives_it() -> None:
    from .test_dwb_controller import _route_obs

    env = gym.make("AgriNav/FurrowFollow-v3", observations=["gps", "imu", "odom", "route"])
    try:
        plain = make_policy("dwb:furrow", env)
        pi = make_policy(
            "dwb:furrow", env, params={**_shipped("furrow"), "rotation_shim.enabled": True}
        )
        assert "rotation shim" in pi.describe() and "rotation shim" not in plain.describe()
        obs, _ = env.reset(seed=0)
        pi.reset()
        leg = dict(obs, route=_route_obs([(0.0, 0.4 * k) for k in range(1, 11)]))  # 90° left
        a = pi.act(leg)
        assert a[0] == 0.0 and a[1] > 0.0 and pi.shim is not None and pi.shim.turning
        ahead = dict(obs, route=_route_obs([(0.4 * k, 0.0) for k in range(1, 11)]))
        pi.act(ahead)  # the same heading as the robot: DWB's command
        assert not pi.shim.turning
    finally:
        env.close()


def test_the_nav2_export_writes_the_shim_with_dwb_as_its_primary() -> None:
    from scenario_gen.export.ros_config import REPLAN_HZ, SHIM_PLUGIN, follow_path

    env = gym.make("AgriNav/FurrowFollow-v3", observations=["gps", "imu", "odom", "route"])
    try:
        from policies.dwb.policy import resolved_config

        pi = make_policy(
            "dwb:furrow", env, params={**_shipped("furrow"), "rotation_shim.enabled": True}
        )
        cfg = resolved_config(pi.p, env.unwrapped.interface)
        robot = env.unwrapped.interface
    finally:
        env.close()
    out = follow_path(cfg)
    assert out["plugin"] == SHIM_PLUGIN and out["primary_controller"] == "dwb_core::DWBLocalPlanner"
    assert out["rotate_to_heading_angular_vel"] == robot.w_max
    assert out["max_angular_accel"] == robot.alpha_max
    assert out["angular_dist_threshold"] == 0.785 and "PathDist" in out  # DWB's, same namespace
    # the simulated shim re-arms at the exported tree's replanning rate
    assert RotationShimParams().plan_frequency == REPLAN_HZ
    cfg["rotation_shim"]["plan_frequency"] = 1.0
    with pytest.raises(InputError, match="rotation_shim.plan_frequency"):
        follow_path(cfg)
    cfg["rotation_shim"]["enabled"] = False
    assert follow_path(cfg)["plugin"] == "dwb_core::DWBLocalPlanner"
