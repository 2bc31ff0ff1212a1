"""Controllers behind one interface: DWB, regulated pure pursuit, a depth furrow follower, PPO.

``make_policy("dwb" | "rpp" | "depth" | "ppo:PATH", env)`` builds one from an env's spaces and
its public configuration (speed limits, camera calibration); policies see observations only.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
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


#: Checkpoints shipped in the package, by the env id they were trained on.
SHIPPED = {
    "AgriNav/FurrowFollow-v0": "furrow_follow_ppo",
    "AgriNav/FieldRoute-v0": "field_route_ppo",
    "AgriNav/FurrowFollowDepth-v0": "furrow_follow_depth_ppo",
}


def shipped_model(env_id: str) -> Path:
    """Folder of the shipped PPO checkpoint for ``env_id`` (model.zip, command, curve)."""
    if env_id not in SHIPPED:
        raise ValueError(f"no shipped PPO checkpoint for {env_id}; shipped: {', '.join(SHIPPED)}")
    folder = Path(str(resources.files("policies.models").joinpath(SHIPPED[env_id])))
    if not (folder / "model.zip").is_file():
        raise ValueError(f"the shipped checkpoint for {env_id} is missing from {folder}")
    return folder


def make_policy(spec: str, env: Any, **params: Any) -> Policy:
    """``spec`` is a policy name, ``ppo:PATH`` for a trained checkpoint, or ``ppo:shipped`` for
    the checkpoint shipped for the env's id."""
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
        kwargs["path"] = str(shipped_model(u.spec.id)) if path == "shipped" and u.spec else path
    return POLICIES[name](u.observation_space, u.action_space, **kwargs)


__all__ = [
    "DWB",
    "POLICIES",
    "SHIPPED",
    "DepthFurrowFollower",
    "PPOPolicy",
    "Policy",
    "RegulatedPurePursuit",
    "make_policy",
    "shipped_model",
]
