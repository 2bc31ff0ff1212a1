"""A task: which route the robot follows, where it starts, and when the episode ends.

Termination is an ordered list of named checks; the first that fires names the episode's end
(``info["termination"]``). A new task is a ``Task`` subclass decorated with ``@task`` (no shared
code changes); a new check is a function decorated with ``@termination_check``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar

import numpy as np

from scenario_gen import Scenario

from ..config import TaskConfig
from ..interface import RobotInterface
from ..rewards import StepContext
from ..routes import RoutePath

Check = Callable[[StepContext, TaskConfig], bool]
TERMINATION_CHECKS: dict[str, Check] = {}


def termination_check(name: str) -> Callable[[Check], Check]:
    def register(fn: Check) -> Check:
        TERMINATION_CHECKS[name] = fn
        return fn

    return register


@termination_check("success")
def _success(c: StepContext, t: TaskConfig) -> bool:
    return c.route_left <= t.success_tolerance


@termination_check("corridor")
def _corridor(c: StepContext, t: TaskConfig) -> bool:
    return abs(c.cte) > c.corridor


@termination_check("off_terrain")
def _off_terrain(c: StepContext, t: TaskConfig) -> bool:
    return c.off_terrain


@termination_check("tip_over")
def _tip_over(c: StepContext, t: TaskConfig) -> bool:
    return c.tilt > math.radians(t.max_tilt_deg)


@termination_check("crops_hit")
def _crops_hit(c: StepContext, t: TaskConfig) -> bool:
    return c.crops_hit > t.max_crops_hit


@termination_check("progress")
def _progress(c: StepContext, t: TaskConfig) -> bool:
    return t.progress_time is not None and c.stalled >= t.progress_time


def _wrap(a: float) -> float:
    return float((a + math.pi) % (2 * math.pi) - math.pi)


class Task(ABC):
    """Route, start pose, corridor and termination of one kind of episode."""

    name: ClassVar[str]
    #: checked in this order each step; the first that fires ends the episode
    terminations: ClassVar[tuple[str, ...]] = (
        "success",
        "corridor",
        "off_terrain",
        "tip_over",
        "crops_hit",
        "progress",
    )
    options: ClassVar[tuple[str, ...]] = ()  # extra ``reset(options=...)`` keys it reads

    def __init__(self, cfg: TaskConfig, robot: RobotInterface) -> None:
        self.cfg = cfg
        self.robot = robot

    @abstractmethod
    def make_route(
        self, scn: Scenario, rng: np.random.Generator, options: dict[str, Any]
    ) -> RoutePath:
        """The reference route of this episode."""

    def corridor(self, scn: Scenario, furrow: bool) -> float:
        t = self.cfg
        if not furrow:
            return t.headland_corridor
        return t.corridor if t.corridor is not None else 0.5 * scn.rows.spacing

    def start_pose(
        self, route: RoutePath, rng: np.random.Generator, clearance: float, scn: Scenario
    ) -> tuple[float, float, float]:
        """At rest a little along the route, offset sideways and turned, never in the crop.

        The perturbation is drawn from N(0, start_lateral_std) and N(0, start_heading_std) and
        clipped so the wheels and chassis stay inside the lane: half the ``clearance`` (room
        each side of the lane centre before the robot touches a stalk) for the lateral offset,
        and the heading whose swing of the footprint's front corner uses the other half. A
        corridor narrower than the clearance takes its place (a start outside it would end the
        episode at its first step).
        """
        t = self.cfg
        s0 = min(0.3, 0.1 * route.length)
        ((x, y),) = route.sample(np.array([s0]))
        h = float(np.interp(s0, route.arc, np.unwrap(route.heading)))
        furrow = bool(route.lookup(np.array([s0]))[1][0])
        room = 0.5 * max(min(clearance, self.corridor(scn, furrow)), 0.0)
        lat = float(np.clip(rng.normal(0.0, t.start_lateral_std), -room, room))
        max_dh = math.degrees(math.atan2(room, 0.5 * self.robot.footprint[0]))
        dh = float(np.clip(rng.normal(0.0, t.start_heading_std_deg), -max_dh, max_dh))
        return x - lat * math.sin(h), y + lat * math.cos(h), _wrap(h + math.radians(dh))

    def check(self, c: StepContext) -> str | None:
        """Name of the first termination check that fires, or None."""
        for name in self.terminations:
            if TERMINATION_CHECKS[name](c, self.cfg):
                return name
        return None


TASKS: dict[str, type[Task]] = {}
T = TypeVar("T", bound=type[Task])


def task(cls: T) -> T:
    """Register a task under ``cls.name`` (the name ``register_scenario(task=...)`` takes)."""
    TASKS[cls.name] = cls
    return cls
