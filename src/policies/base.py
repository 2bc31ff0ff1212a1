"""One interface for every controller: built from the env's spaces and its public
``RobotInterface``, fed observations only."""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import RobotInterface
from scenario_gen.errors import InputError, Notice

from .params import Param, check_params

Obs = dict[str, NDArray[np.float32]]


class Policy(ABC):
    """``reset()`` at each episode start, then ``act(obs)`` -> an action in the env's space.

    Policies see what a real robot would: the observation dict, the env's public spaces and the
    ``RobotInterface`` (footprint, limits, camera calibration, observation layouts). Never the
    simulator, the true pose or the scenario's ground truth.
    """

    name: ClassVar[str] = "policy"
    requires: ClassVar[tuple[str, ...]] = ()
    #: the parameters a file may set and their ranges (controllers that take a file)
    PARAMS: ClassVar[dict[str, Param]] = {}
    #: pairs (a, b) of PARAMS whose a may not exceed b
    ORDERED: ClassVar[tuple[tuple[str, str], ...]] = ()

    @classmethod
    def defaults(cls) -> dict[str, Any]:
        """The constructor's default of every parameter in PARAMS."""
        import inspect

        return {
            n: p.default
            for n, p in inspect.signature(cls.__init__).parameters.items()
            if n in cls.PARAMS
        }

    @classmethod
    def check_file_params(cls, values: dict[str, Any]) -> None:
        """A parameter file's values, checked against PARAMS (and ORDERED, with the
        constructor's defaults for what the file leaves out) before anything is built."""
        check_params(cls.name, cls.PARAMS, values, cls.ORDERED, cls.defaults())

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        robot: RobotInterface,
        **params: Any,
    ) -> None:
        missing = [k for k in self.requires if k not in observation_space.spaces]
        if missing:
            raise InputError(
                "policy",
                self.name,
                f"needs observations {list(self.requires)}; "
                f"the env provides {list(observation_space.spaces)}",
            )
        if params:
            raise InputError(
                f"policy {self.name}",
                sorted(params),
                "unknown parameters for this policy",
            )
        self.observation_space = observation_space
        self.action_space = action_space
        self.robot = robot

    def keep_params(self, values: dict[str, Any]) -> None:
        """Remember the parameters as given, for ``changed_params``."""
        self._given = {k: v for k, v in values.items() if k in self.PARAMS}

    def changed_params(self, shown: tuple[str, ...]) -> str:
        """``; name value, ...`` for the parameters off the constructor's defaults that the
        description does not state already (a benchmark row names the config it ran)."""
        defaults = self.defaults()
        extra = [
            f"{k} {'null' if v is None else format(v, 'g') if isinstance(v, float) else v}"
            for k, v in getattr(self, "_given", {}).items()
            if k not in shown and v != defaults.get(k)
        ]
        return f"; {', '.join(extra)}" if extra else ""

    def note_above_robot(self, field: str, value: float, limit: float, unit: str) -> None:
        """Say that a configured limit is past the robot's own, which the env clips every
        command to (the controller plans with a speed it never gets)."""
        if value > limit:
            warnings.warn(
                Notice(
                    f"{self.name} {field} {value:g} {unit} is above the robot's {limit:g} "
                    f"{unit}: the env clips the command to {limit:g}"
                ),
                stacklevel=3,
            )

    def reset(self) -> None:  # noqa: B027  (stateless policies need nothing)
        pass

    def describe(self) -> str:
        """The controller and its configuration, as a benchmark row states it."""
        return self.name

    def clear_costmaps(self) -> None:  # noqa: B027  (most policies keep no costmap)
        """A navigator's recovery cleared the costmaps (``info["recovery"]``, Nav2's
        ClearEntireCostmap): forget what they held."""

    @abstractmethod
    def act(self, obs: Obs) -> NDArray[np.float32]: ...

    def _twist(self, v: float, w: float) -> NDArray[np.float32]:
        """A body twist in m/s and rad/s as the env's normalized, clipped action."""
        return self._clip(np.array([v / self.robot.v_max, w / self.robot.w_max]))

    def _clip(self, a: NDArray[np.float64]) -> NDArray[np.float32]:
        lo, hi = self.action_space.low, self.action_space.high
        return np.clip(a, lo, hi).astype(np.float32)
