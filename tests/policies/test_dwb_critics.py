"""DWB critics on hand-made trajectories, scored as Nav2 Humble's C++ scores them.

Every expected number is worked out here by hand from the C++ (cell indices, Manhattan cell
distances, getScale's resolution × 0.5 factor, the inflation formula), or compared with a literal
port of the C++ loop in ``dwb_reference``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from policies.dwb.costmap import INSCRIBED, LETHAL, Grid, compute_cost, inflate
from policies.dwb.critics import (
    BaseObstacleCritic,
    Cycle,
    GoalAlignCritic,
    ObstacleFootprintCritic,
    OscillationCritic,
    PathAlignCritic,
    PathDistCritic,
    RotateToGoalCritic,
    line_cells,
    manhattan_field,
)
from policies.dwb.params import (
    BaseObstacleParams,
    GoalAlignParams,
    InflationLayerParams,
    ObstacleFootprintParams,
    OscillationParams,
    PathAlignParams,
    PathDistParams,
    RotateToGoalParams,
)
from policies.dwb.trajectories import Rollouts

from .dwb_reference import costmap_queue_manhattan, inflation_layer, line_iterator


def rollouts(
    *trajs: list[tuple[float, float, float]], twists: list[tuple[float, float]] | None = None
) -> Rollouts:
    """Hand-made trajectories (poses as listed), padded as the generator pads them."""
    m = max(len(t) for t in trajs)
    poses = np.array([t + [t[-1]] * (m - len(t)) for t in trajs], dtype=np.float64)
    tw = np.array(twists if twists is not None else [(0.5, 0.0)] * len(trajs), np.float64)
    return Rollouts(tw, poses, np.array([len(t) for t in trajs]), np.full(len(trajs), 0.1))


def straight_plan(y: float, x0: float, x1: float, step: float = 0.05) -> np.ndarray:
    xs = np.arange(x0, x1 + 1e-9, step)
    return np.column_stack([xs, np.full(len(xs), y), np.zeros(len(xs))])


GRID = Grid(0.0, 0.0, 20, 20, 0.1)  # 2 m × 2 m, 10 cm cells


def cycle(
    plan: np.ndarray,
    pose: tuple[float, float, float],
    goal: tuple[float, float, float],
    costmap: np.ndarray | None = None,
    grid: Grid = GRID,
) -> Cycle:
    cm = np.zeros((grid.size_x, grid.size_y), np.uint8) if costmap is None else costmap
    return Cycle(pose, (0.3, 0.0), goal, plan, grid, cm)


# ----------------------------------------------------------------------------- map grid
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_manhattan_propagation_is_costmap_queue(seed: int) -> None:
    """The taxicab transform equals Humble's CostmapQueue flood fill, cell for cell."""
    rng = np.random.default_rng(seed)
    g = Grid(0.0, 0.0, 23, 17, 0.05)
    k = int(rng.integers(1, 12))
    src = [
        (int(x), int(y))
        for x, y in zip(rng.integers(0, 23, k), rng.integers(0, 17, k), strict=True)
    ]
    # plus a plan-like run of cells, as PathDist enqueues
    src += [(i, 8 + i // 4) for i in range(3, 19)]
    ref = costmap_queue_manhattan(23, 17, src)
    mx = np.array([s[0] for s in src])
    my = np.array([s[1] for s in src])
    np.testing.assert_array_equal(manhattan_field(g, mx, my), ref)


def test_path_dist_counts_manhattan_cells_from_the_plan() -> None:
    plan = straight_plan(0.55, 0.05, 1.95)  # every pose in cell row my = 5
    c = cycle(plan, (0.55, 0.55, 0.0), (1.95, 0.55, 0.0))
    crit = PathDistCritic(PathDistParams(scale=32.0))
    assert crit.prepare(c)
    ro = rollouts(
        [(0.55, 0.55, 0.0), (0.75, 0.75, 0.5), (1.0, 0.95, 0.7)],  # ends in cell (10, 9)
        [(0.55, 0.55, 0.0), (1.23, 0.12, -0.3)],  # ends in cell (12, 1)
        [(0.55, 0.55, 0.0), (-0.01, 0.5, 3.1), (0.3, 0.5, 3.1)],  # a pose off the map
    )
    s = crit.score(ro, c)
    # last pose: |9 - 5| = 4 cells, |1 - 5| = 4 cells; off the grid is illegal
    np.testing.assert_array_equal(s.legal, [True, True, False])
    np.testing.assert_array_equal(s.score[:2], [4.0, 4.0])
    # getScale: resolution × 0.5 × scale
    assert crit.scale == pytest.approx(0.1 * 0.5 * 32.0)
    crit_sum = PathDistCritic(PathDistParams(scale=32.0, aggregation_type="sum"))
    crit_sum.prepare(c)
    # cells (5,5) 0, (7,7) 2, (10,9) 4: summed over the poses
    assert crit_sum.score(ro, c).score[0] == 0 + 2 + 4


def test_goal_align_scores_the_forward_point_against_the_shifted_goal() -> None:
    plan = straight_plan(0.55, 0.05, 1.05)
    pose, goal = (0.25, 0.55, 0.0), (1.05, 0.55, 0.0)
    c = cycle(plan, pose, goal)
    crit = GoalAlignCritic(GoalAlignParams(scale=24.0, forward_point_distance=0.1))
    assert crit.prepare(c)
    # the local goal moves 0.1 m along robot -> goal: (1.15, 0.55), cell (11, 5)
    ro = rollouts(
        [(0.25, 0.55, 0.0), (0.8, 0.75, math.pi / 2)],  # forward point (0.8, 0.85): cell (8, 8)
        [(0.25, 0.55, 0.0), (0.9, 0.55, 0.0)],  # forward point (1.0, 0.55): cell (10, 5)
        [(0.25, 0.55, 0.0), (1.95, 0.55, 0.0)],  # forward point (2.05, 0.55): off the map
    )
    s = crit.score(ro, c)
    np.testing.assert_array_equal(s.legal, [True, True, False])
    np.testing.assert_array_equal(s.score[:2], [3 + 3, 1 + 0])
    assert crit.scale == pytest.approx(0.1 * 0.5 * 24.0)


def test_path_align_is_silent_within_its_forward_distance_of_the_goal() -> None:
    plan = straight_plan(0.55, 0.05, 1.05)
    crit = PathAlignCritic(PathAlignParams(scale=32.0, forward_point_distance=0.1))
    crit.prepare(cycle(plan, (0.5, 0.55, 0.0), (1.05, 0.55, 0.0)))
    assert crit.scale == pytest.approx(1.6)
    crit.prepare(cycle(plan, (0.98, 0.55, 0.0), (1.05, 0.55, 0.0)))
    assert crit.scale == 0.0


# ----------------------------------------------------------------------------- obstacles
FINE = Grid(0.0, 0.0, 40, 40, 0.05)
R_IN = 0.318  # inscribed radius of the padded 0.724 × 0.616 footprint


def lethal_at_20_20() -> np.ndarray:
    layer = np.zeros((40, 40), np.uint8)
    layer[20, 20] = LETHAL
    return inflate(
        layer, 0.05, R_IN, InflationLayerParams(cost_scaling_factor=3.0, inflation_radius=0.55)
    )


def test_inflation_is_nav2_compute_cost() -> None:
    cm = lethal_at_20_20()
    assert cm[20, 20] == LETHAL
    assert cm[20, 26] == INSCRIBED  # 6 cells = 0.30 m <= 0.318
    # 8 cells = 0.40 m: 252·exp(-3 (0.40 - 0.318)) = 197.08 -> 197
    assert cm[20, 28] == int(252 * math.exp(-3.0 * (0.40 - R_IN))) == 197
    # (3, 7) cells: hypot = 7.616 cells = 0.3808 m -> 209.0
    assert cm[23, 27] == int(252 * math.exp(-3.0 * (0.05 * math.hypot(3, 7) - R_IN)))
    assert cm[20, 32] == 0  # 12 cells = 0.60 m: beyond ceil(0.55 / 0.05) = 11 cells
    np.testing.assert_array_equal(compute_cost(np.array([0.0, 6.0]), 0.05, R_IN, 3.0), [254, 253])


def test_obstacle_footprint_takes_the_outline_s_highest_cost() -> None:
    cm = lethal_at_20_20()
    c = cycle(np.zeros((0, 3)), (1.0, 1.0, 0.0), (1.0, 1.0, 0.0), cm, FINE)
    square = np.array([[0.1, 0.1], [0.1, -0.1], [-0.1, -0.1], [-0.1, 0.1]])
    fp = ObstacleFootprintCritic(ObstacleFootprintParams(scale=0.02), square)
    base = BaseObstacleCritic(BaseObstacleParams(scale=0.02))
    ro = rollouts(
        # outline's lower edge y = 1.425 lies in cell row 28: nearest (20, 28), 8 cells -> 197;
        # the centre cell (20, 30), 10 cells = 0.5 m -> 145
        [(1.025, 1.525, 0.0)],
        # lower edge y = 1.0 crosses the lethal cell (20, 20)
        [(1.025, 1.1, 0.0)],
    )
    s = fp.score(ro, c)
    np.testing.assert_array_equal(s.legal, [True, False])
    assert s.score[0] == 197
    b = base.score(ro, c)
    assert b.legal[0] and b.score[0] == int(252 * math.exp(-3.0 * (0.5 - R_IN))) == 145


def test_only_the_outline_counts_for_obstacle_footprint_the_centre_for_base_obstacle() -> None:
    cm = lethal_at_20_20()
    c = cycle(np.zeros((0, 3)), (1.0, 1.0, 0.0), (1.0, 1.0, 0.0), cm, FINE)
    big = np.array([[0.2, 0.2], [0.2, -0.2], [-0.2, -0.2], [-0.2, 0.2]])
    ro = rollouts([(1.025, 1.025, 0.0)])  # the lethal cell inside, the outline 4 cells away
    s = ObstacleFootprintCritic(ObstacleFootprintParams(scale=0.02), big).score(ro, c)
    assert s.legal[0] and s.score[0] == INSCRIBED  # 4 cells = 0.2 m: inscribed, yet legal
    b = BaseObstacleCritic(BaseObstacleParams(scale=0.02)).score(ro, c)
    assert not b.legal[0]  # the centre sits on the lethal cell
    ins = rollouts([(1.025, 1.325, 0.0)])  # centre (20, 26): inscribed -> illegal for the circle
    assert not BaseObstacleCritic(BaseObstacleParams()).score(ins, c).legal[0]


def test_line_cells_is_nav2_line_iterator() -> None:
    rng = np.random.default_rng(3)
    p = rng.integers(0, 30, (200, 4))
    x, y, live = line_cells(p[:, 0], p[:, 1], p[:, 2], p[:, 3])
    for i, (x0, y0, x1, y1) in enumerate(p):
        ref = line_iterator(int(x0), int(y0), int(x1), int(y1))
        got = list(zip(x[i][live[i]].tolist(), y[i][live[i]].tolist(), strict=True))
        assert got == ref


# ----------------------------------------------------------------------------- stateful critics
def test_oscillation_forbids_the_reverse_sign_until_the_robot_has_moved() -> None:
    osc = OscillationCritic(OscillationParams())
    ro = rollouts(
        [(0, 0, 0)], [(0, 0, 0)], [(0, 0, 0)], twists=[(0.3, 0.0), (-0.2, 0.0), (0.0, -0.5)]
    )

    def step(pose: tuple[float, float, float], cmd: tuple[float, float]) -> np.ndarray:
        c = cycle(np.zeros((0, 3)), pose, (5.0, 0.0, 0.0))
        osc.prepare(c)
        legal = osc.score(ro, c).legal
        osc.debrief(cmd, c)
        return legal

    np.testing.assert_array_equal(step((0, 0, 0), (0.3, 0.0)), [True, True, True])
    # forward, then backward: x flipped to negative -> forward is now oscillating
    step((0.0, 0, 0), (-0.2, 0.0))
    np.testing.assert_array_equal(step((0.01, 0, 0), (-0.2, 0.0)), [False, True, True])
    # ω flips are tracked only while |v| <= x_only_threshold (0.05)
    step((0.01, 0, 0), (0.0, 0.5))
    step((0.01, 0, 0), (0.0, -0.5))
    np.testing.assert_array_equal(step((0.02, 0, 0), (0.0, -0.5)), [False, True, True])
    # 6 cm from the pose of the last flip (> oscillation_reset_dist 0.05): flags cleared
    np.testing.assert_array_equal(step((0.08, 0.0, 0.0), (0.0, -0.5)), [False, True, True])
    np.testing.assert_array_equal(step((0.08, 0.0, 0.0), (0.0, -0.5)), [True, True, True])


def test_rotate_to_goal_slows_then_turns_in_place() -> None:
    crit = RotateToGoalCritic(RotateToGoalParams(), xy_goal_tolerance=0.25, stopped=0.25)
    ro = rollouts(
        [(0, 0, 0), (0.1, 0, 0.2)], [(0, 0, 0), (0.0, 0, 0.5)], twists=[(0.2, 0.1), (0.0, 0.3)]
    )
    far = Cycle(
        (0.0, 0.0, 0.0),
        (0.5, 0.0),
        (2.0, 0.0, 0.6),
        np.zeros((0, 3)),
        GRID,
        np.zeros((20, 20), np.uint8),
    )
    crit.prepare(far)
    np.testing.assert_array_equal(crit.score(ro, far).score, [0.0, 0.0])
    near = Cycle(
        (1.9, 0.0, 0.0),
        (0.3, 0.0),
        (2.0, 0.0, 0.6),
        np.zeros((0, 3)),
        GRID,
        np.zeros((20, 20), np.uint8),
    )
    crit.prepare(near)  # in the window at 0.3 m/s: slowing down
    s = crit.score(ro, near)
    assert s.legal.all()
    np.testing.assert_allclose(s.score, [0.2**2 * 5.0 + 0.4, 0.0 + 0.1])
    stopped = Cycle(
        (1.9, 0.0, 0.0),
        (0.1, 0.0),
        (2.0, 0.0, 0.6),
        np.zeros((0, 3)),
        GRID,
        np.zeros((20, 20), np.uint8),
    )
    crit.prepare(stopped)  # below trans_stopped_velocity: rotate only
    s = crit.score(ro, stopped)
    np.testing.assert_array_equal(s.legal, [False, True])
    assert s.score[1] == pytest.approx(0.1)


def test_inflation_matches_nav2_s_wavefront_on_crop_rows() -> None:
    """The exact distance transform gives the cells Nav2's wavefront gives, on rows of crop
    canopies (discs of 2-4 cells every 0.18 m) and scattered points."""
    rng = np.random.default_rng(5)
    layer = np.zeros((60, 60), np.uint8)
    for row in (10, 30, 50):
        for cx in range(2, 60, 4):
            r = rng.integers(1, 4)
            cy = row + rng.integers(-1, 2)
            xx, yy = np.meshgrid(np.arange(60), np.arange(60), indexing="ij")
            layer[(xx - cx) ** 2 + (yy - cy) ** 2 <= r * r] = LETHAL
    layer[rng.integers(0, 60, 15), rng.integers(0, 60, 15)] = LETHAL
    p = InflationLayerParams(cost_scaling_factor=3.0, inflation_radius=0.55)
    ref = inflation_layer(layer, 0.05, R_IN, 3.0, 0.55)
    np.testing.assert_array_equal(inflate(layer, 0.05, R_IN, p), ref)
