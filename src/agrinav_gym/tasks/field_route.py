"""The source paper's experiment: the scenario's zigzag over lanes with headland U-turns."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from scenario_gen import Scenario

from ..routes import RoutePath, scenario_route
from .base import Task, task


@task
class FieldRouteTask(Task):
    name: ClassVar[str] = "FieldRoute"

    def make_route(
        self, scn: Scenario, rng: np.random.Generator, options: dict[str, Any]
    ) -> RoutePath:
        return scenario_route(scn)
