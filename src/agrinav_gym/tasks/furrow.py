"""Follow one lane between two crop rows, start to end."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from scenario_gen import Scenario
from scenario_gen.errors import InputError

from ..routes import RoutePath, lane_route
from .base import Task, task


@task
class FurrowFollowTask(Task):
    """One lane, drawn at random from the scenario's inner lanes unless ``options["lane"]``."""

    name: ClassVar[str] = "FurrowFollow"
    options: ClassVar[tuple[str, ...]] = ("lane",)

    def make_route(
        self, scn: Scenario, rng: np.random.Generator, options: dict[str, Any]
    ) -> RoutePath:
        n = len(scn.lanes)
        if n == 0:
            raise InputError("scenario", scn.spec.name, "has no lane (needs two rows)")
        lane = options.get("lane")
        if lane is None:
            return lane_route(scn, int(rng.integers(1, n - 1)) if n > 2 else 0)
        if isinstance(lane, bool) or not isinstance(lane, (int, np.integer)):
            raise InputError("options.lane", lane, f"allowed: an integer lane index 0..{n - 1}")
        if not 0 <= int(lane) < n:
            raise InputError("options.lane", lane, f"allowed: 0..{n - 1}")
        return lane_route(scn, int(lane))
