"""Controllers behind one interface: DWB, regulated pure pursuit, a depth furrow follower, PPO.

``make_policy("dwb" | "rpp" | "depth" | "ppo:PATH", env)`` builds one from an env's spaces and
its public configuration (speed limits, camera calibration); policies see observations only.
"""

from __future__ import annotations

import math
from typing import Any

from .base import Policy
from .depth_follower import DepthFurrowFollower
from .dwb import DWB
from .ppo import PPOPolicy
from .rpp import RegulatedPurePursuit

POLICIES: dict[str, type[Policy]] = {
    "dwb": DWB,
    "rpp": RegulatedPurePursuit,
    "depth": DepthFurrowFollower,
    "ppo": PPOPolicy,
}


def make_policy(spec: str, env: Any, **params: Any) -> Policy:
    """``spec`` is a policy name, or ``ppo:PATH`` for a trained checkpoint."""
    name, _, path = spec.partition(":")
    if name not in POLICIES:
        raise ValueError(f"policy: got {spec!r}; allowed: {', '.join(POLICIES)} (ppo:PATH)")
    u = env.unwrapped
    cfg = u.cfg  # public env configuration: limits and sensor calibration, not simulator state
    r, d = cfg.robot, cfg.depth
    kwargs: dict[str, Any] = {
        "v_max": r.v_max,
        "w_max": r.w_max,
        "control_dt": 1.0 / r.control_hz,
        "camera": {
            "hfov": math.radians(d.hfov_deg),
            "vfov": math.radians(d.vfov_deg),
            "x": r.camera_x,
            "height": r.camera_height,
            "pitch": math.radians(r.camera_pitch_deg),
        },
        **params,
    }
    if name == "ppo":
        if not path:
            raise ValueError("policy: ppo needs a checkpoint, ppo:PATH (a model.zip or its folder)")
        kwargs["path"] = path
    return POLICIES[name](u.observation_space, u.action_space, **kwargs)


__all__ = [
    "DWB",
    "POLICIES",
    "DepthFurrowFollower",
    "PPOPolicy",
    "Policy",
    "RegulatedPurePursuit",
    "make_policy",
]
