"""What many tests share: tiny fields (each env builds its world in milliseconds) and one
rollout loop."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

#: A 6 × 14 m field with a 2 m headland on a 4 m terrain margin: a few lanes, seconds to drive.
TINY: dict[str, Any] = {
    "field": {"width": 6.0, "length": 14.0},
    "layout": {"headland": 2.0},
    "terrain": {"margin": 4.0},
}
#: ``TINY`` on a plane with no furrows and no roughness: nothing but the controller steers.
FLAT: dict[str, Any] = {
    **TINY,
    "terrain": {"source": "plane", "margin": 4.0},
    "furrows": {"enabled": False, "roughness": 0.0},
}
#: The robot put down on the lane centre, facing along it.
STILL = {"task": {"start_lateral_std": 0.0, "start_heading_std_deg": 0.0}}


@dataclass
class Rollout:
    info: dict[str, Any]  # the last step's
    steps: int = 0
    total_reward: float = 0.0
    ctes: list[float] = field(default_factory=list)  # the true cross-track error per step

    @property
    def success(self) -> bool:
        return bool(self.info.get("is_success"))


def drive(
    env: gym.Env,
    policy: Any,
    seed: int,
    options: dict[str, Any] | None = None,
    max_steps: int | None = None,
) -> Rollout:
    """One episode: ``env.reset(seed)``, then ``policy`` (a ``Policy``, reset after the env, or
    a function of the observation) until the episode ends or ``max_steps``."""
    act: Callable[[Any], Any] = policy.act if hasattr(policy, "act") else policy
    obs, info = env.reset(seed=seed, options=options)
    if hasattr(policy, "reset"):
        policy.reset()
    out = Rollout(info)
    while max_steps is None or out.steps < max_steps:
        obs, reward, term, trunc, out.info = env.step(act(obs))
        out.steps += 1
        out.total_reward += float(reward)
        out.ctes.append(float(out.info["cte"]))
        if term or trunc:
            break
    return out
