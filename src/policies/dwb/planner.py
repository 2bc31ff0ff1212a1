"""DWBLocalPlanner (dwb_core, Humble): plan transform and pruning, the scoring loop, the choice.

``coreScoringAlgorithm`` scores the twists in the iterator's order and keeps the first with the
lowest Σ scale × score; a twist some critic rejects is illegal; no legal twist raises
NoLegalTrajectoriesException, on which the controller server publishes a zero twist and the
behaviour tree clears the local costmap before retrying. Short-circuit evaluation changes
which critics run, never the choice, so here every cheap critic scores every twist and the
footprint critic (the costly one) runs only on twists whose partial total can still win —
the same branch-and-bound argument that makes Nav2's short circuit exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

from .critics import (
    BaseObstacleCritic,
    Critic,
    Cycle,
    GoalAlignCritic,
    GoalDistCritic,
    ObstacleFootprintCritic,
    OscillationCritic,
    PathAlignCritic,
    PathDistCritic,
    PreferForwardCritic,
    RotateToGoalCritic,
)
from .params import FollowPathParams
from .trajectories import (
    Kinematics,
    Rollouts,
    dynamic_window,
    project_velocity,
    rollout,
    step_counts,
)

CHUNK = 24  # footprint evaluations per round of the branch-and-bound


def build_critic(name: str, p: FollowPathParams, footprint: FloatArray) -> Critic:
    if name == "RotateToGoal":
        return RotateToGoalCritic(p.RotateToGoal, p.xy_goal_tolerance, p.trans_stopped_velocity)
    if name == "Oscillation":
        return OscillationCritic(p.Oscillation)
    if name == "BaseObstacle":
        return BaseObstacleCritic(p.BaseObstacle)
    if name == "ObstacleFootprint":
        return ObstacleFootprintCritic(p.ObstacleFootprint, footprint)
    if name == "GoalAlign":
        return GoalAlignCritic(p.GoalAlign)
    if name == "PathAlign":
        return PathAlignCritic(p.PathAlign)
    if name == "PathDist":
        return PathDistCritic(p.PathDist)
    if name == "GoalDist":
        return GoalDistCritic(p.GoalDist)
    return PreferForwardCritic(p.PreferForward)


def transform_global_plan(
    plan: FloatArray,
    pose: tuple[float, float, float],
    costmap_half_size: float,
    p: FollowPathParams,
) -> tuple[FloatArray, FloatArray]:
    """DWBLocalPlanner::transformGlobalPlan: (the plan handed to the critics, the global plan
    after pruning). Both frames are the costmap's here (the route arrives in the robot frame)."""
    if len(plan) == 0:
        return plan, plan
    start_thr = min(costmap_half_size, p.prune_distance) if p.prune_plan else costmap_half_size
    end_thr = (
        min(costmap_half_size, p.forward_prune_distance)
        if p.shorten_transformed_plan
        else costmap_half_size
    )
    seg = np.hypot(np.diff(plan[:, 0]), np.diff(plan[:, 1]))
    cum = np.cumsum(seg)
    after = np.flatnonzero(cum > p.prune_distance)
    prune_point = int(after[0]) + 1 if len(after) else len(plan)
    d = np.hypot(plan[:, 0] - pose[0], plan[:, 1] - pose[1])
    near = np.flatnonzero(d[:prune_point] < start_thr)
    begin = int(near[0]) if len(near) else prune_point
    far = np.flatnonzero(d[begin:] > end_thr)
    end = begin + int(far[0]) if len(far) else len(plan)
    transformed = plan[begin:end]
    pruned = plan[begin:] if p.prune_plan else plan
    return transformed, pruned


@dataclass
class Evaluation:
    """One control cycle's scoring, for the figures and the tests."""

    rollouts: Rollouts
    total: FloatArray  # Σ scale × score (nan: not evaluated because it could not win)
    legal: NDArray[np.bool_]
    scores: dict[str, FloatArray] = field(default_factory=dict)
    rejected_by: list[str] = field(default_factory=list)  # critic that made each twist illegal
    best: int = -1  # index into the twists, -1: no legal trajectory
    plan: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))


class LocalPlanner:
    """The DWB controller plugin: critics, trajectory generator, scoring loop."""

    def __init__(self, p: FollowPathParams, kin: Kinematics, footprint: FloatArray) -> None:
        self.p = p
        self.kin = kin
        self.critics = [build_critic(name, p, footprint) for name in p.critics]

    def reset(self) -> None:
        """setPlan: every critic's reset (a new goal)."""
        for c in self.critics:
            c.reset()

    def rollouts(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> Rollouts:
        p = self.p
        tw = dynamic_window(vel[0], vel[1], self.kin, p.sim_time, p.vx_samples, p.vtheta_samples)
        counts = step_counts(
            tw,
            p.sim_time,
            p.linear_granularity,
            p.angular_granularity,
            p.discretize_by_time,
            p.time_granularity,
        )
        return rollout(tw, pose, vel, self.kin, p.sim_time, counts, p.include_last_point)

    def evaluate(self, cycle: Cycle, full: bool = False) -> Evaluation:
        """Prepare the critics and score the dynamic window's twists; ``full`` scores every
        critic on every twist (for figures) instead of stopping when the winner is certain."""
        for c in self.critics:
            c.prepare(cycle)  # a failed prepare only warns in Nav2
        ro = self.rollouts(cycle.pose, cycle.velocity)
        if len(cycle.plan) == 0:  # transformGlobalPlan throws: no command this cycle
            n = len(ro.twists)
            return Evaluation(ro, np.full(n, np.nan), np.zeros(n, bool), {}, ["empty plan"] * n)
        ro.cells = cycle.grid.world_to_map(ro.poses[..., 0], ro.poses[..., 1])
        n = len(ro.twists)
        legal = np.ones(n, bool)
        rejected = [""] * n
        parts: dict[str, FloatArray] = {}
        costly: list[Critic] = [
            c for c in self.critics if isinstance(c, ObstacleFootprintCritic) and c.scale
        ]
        for c in self.critics:
            if c.scale == 0.0 or (c in costly and not full):
                continue  # a zero-scale critic is skipped, its exceptions too
            s = c.score(ro, cycle)
            parts[c.name] = s.score
            for i in np.flatnonzero(legal & ~s.legal):
                rejected[i] = f"{c.name}: {s.reason}"
            legal &= s.legal
        if costly and not full:
            self._bound(ro, cycle, costly, parts, legal, rejected)
        total = self._total(parts, n)
        total[~legal] = np.nan
        ok = legal & np.isfinite(total)
        best = -1
        if ok.any():
            t = np.where(ok, total, np.inf)
            best = int(np.flatnonzero(t == t.min())[0])  # the first of equals, as Nav2 keeps
        return Evaluation(ro, total, legal, parts, rejected, best, cycle.plan)

    def _total(self, parts: dict[str, FloatArray], n: int) -> FloatArray:
        total = np.zeros(n)
        for c in self.critics:  # summed in the critics' order, as scoreTrajectory does
            if c.name in parts:
                total = total + parts[c.name] * c.scale
        return total

    def _bound(
        self,
        ro: Rollouts,
        cycle: Cycle,
        costly: list[Critic],
        parts: dict[str, FloatArray],
        legal: NDArray[np.bool_],
        rejected: list[str],
    ) -> None:
        """Score the costly critics on the twists, best partial total first, until no twist
        left can beat the best complete one (its partial total already exceeds it)."""
        n = len(ro.twists)
        partial = self._total(parts, n)
        for c in costly:
            parts[c.name] = np.full(n, np.nan)
        order = [int(i) for i in np.lexsort((np.arange(n), partial)) if legal[i]]
        best = math.inf
        k = 0
        while k < len(order) and partial[order[k]] <= best:
            idx = np.asarray(order[k : k + CHUNK])
            sub = ro.subset(idx)
            ok = np.ones(len(idx), bool)
            for c in costly:
                s = c.score(sub, cycle)
                parts[c.name][idx] = s.score
                for j in np.flatnonzero(ok & ~s.legal):
                    rejected[int(idx[j])] = f"{c.name}: {s.reason}"
                ok &= s.legal
            legal[idx] &= ok
            full = self._total({k2: v[idx] for k2, v in parts.items()}, len(idx))
            if ok.any():
                best = min(best, float(full[ok].min()))
            k += CHUNK

    def command(self, ev: Evaluation, cycle: Cycle) -> tuple[float, float]:
        """The chosen twist (what the controller publishes) and the critics' debrief."""
        if ev.best < 0:
            cmd = (0.0, 0.0)
        else:
            v, w = (float(x) for x in ev.rollouts.twists[ev.best])
            if self.p.limit_vel_cmd_in_traj:
                dt = float(ev.rollouts.dt[ev.best])
                v0, w0 = cycle.velocity
                k = self.kin
                v = project_velocity(v0, k.acc_lim_x, k.decel_lim_x, dt, v)
                w = project_velocity(w0, k.acc_lim_theta, k.decel_lim_theta, dt, w)
            cmd = (v, w)
        for c in self.critics:
            c.debrief(cmd, cycle)
        return cmd
