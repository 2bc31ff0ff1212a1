"""One interface for every controller: built from the env's spaces, fed observations only."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

Obs = dict[str, NDArray[np.float32]]


class Policy(ABC):
    """``reset()`` at each episode start, then ``act(obs)`` -> an action in the env's space.

    Policies see what a real robot would: the observation dict (and the env's public spaces).
    Never the simulator, the true pose or the scenario's ground truth.
    """

    name = "policy"
    requires: tuple[str, ...] = ()

    def __init__(
        self,
        observation_space: spaces.Dict,
        action_space: spaces.Box,
        v_max: float = 1.0,
        w_max: float = 1.5,
        **params: Any,
    ) -> None:
        """``v_max``/``w_max``: the env's speeds at action ±1 (its public robot config)."""
        missing = [k for k in self.requires if k not in observation_space.spaces]
        if missing:
            raise ValueError(
                f"policy {self.name!r} needs observations {list(self.requires)}; "
                f"the env provides {list(observation_space.spaces)}"
            )
        self.observation_space = observation_space
        self.action_space = action_space
        self.v_max, self.w_max = v_max, w_max

    def reset(self) -> None:  # noqa: B027  (stateless policies need nothing)
        pass

    @abstractmethod
    def act(self, obs: Obs) -> NDArray[np.float32]: ...

    def _twist(self, v: float, w: float) -> NDArray[np.float32]:
        """A body twist in m/s and rad/s as the env's normalized, clipped action."""
        return self._clip(np.array([v / self.v_max, w / self.w_max]))

    def _clip(self, a: NDArray[np.float64]) -> NDArray[np.float32]:
        lo, hi = self.action_space.low, self.action_space.high
        return np.clip(a, lo, hi).astype(np.float32)
