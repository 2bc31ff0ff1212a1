"""Controllers behind one interface: DWB, regulated pure pursuit, a depth furrow follower, PPO.

``make_policy(spec, env)`` builds one from an env's spaces and its public configuration (speed
limits, camera calibration); ``spec`` is ``dwb`` (= ``dwb:furrow``), ``dwb:nav2``,
``dwb:tuned``, ``dwb:PATH.yaml``, ``rpp``, ``stanley`` (Stanley with integral action) — each
also ``:tuned`` (the shipped result of the tuning budget) or ``:PATH.yaml`` —, ``depth``,
``ppo:PATH`` or ``blind`` (a constant command: the reference that shows what the field steers
by itself).
Policies see observations only.
"""

from __future__ import annotations

import warnings
from importlib import resources
from pathlib import Path
from typing import Any

from scenario_gen.errors import InputError, Notice

from .base import Policy
from .blind import Blind
from .depth_follower import DepthFurrowFollower
from .dwb import DWB
from .dwb.params import SHIPPED as DWB_SHIPPED
from .ppo import PPOPolicy
from .rpp import RegulatedPurePursuit
from .spec import SEPARATOR, SHIPPED_ARG, PolicySpec
from .stanley import Stanley

POLICIES: dict[str, type[Policy]] = {
    "dwb": DWB,
    "rpp": RegulatedPurePursuit,
    "depth": DepthFurrowFollower,
    "ppo": PPOPolicy,
    "blind": Blind,
    "stanley": Stanley,
}


#: Checkpoints shipped in the package, by the env id they were trained on.
SHIPPED = {
    "AgriNav/FurrowFollow-v3": "furrow_follow_ppo",
    "AgriNav/FieldRoute-v3": "field_route_ppo",
    "AgriNav/FurrowFollowDepth-v3": "furrow_follow_depth_ppo",
}


def shipped_model(env_id: str) -> Path:
    """Folder of the shipped PPO checkpoint for ``env_id`` (model, command, curve)."""
    if env_id not in SHIPPED:
        raise InputError(
            "policy", f"ppo:shipped for {env_id}", f"shipped checkpoints: {', '.join(SHIPPED)}"
        )
    folder = Path(str(resources.files("policies.models").joinpath(SHIPPED[env_id])))
    if not (folder / "checkpoint.json").is_file():
        raise InputError("policy", f"ppo:shipped for {env_id}", f"is missing from {folder}")
    return folder


#: Controllers that take a parameter file (``rpp:best.yaml``, as ``agrinav tune`` writes).
TUNABLE = ("rpp", "stanley")
#: ``NAME:tuned``: the parameters the tuning budget chose, shipped (``policies/config/
#: NAME_tuned.yaml``; DWB's is ``dwb_tuned.yaml``, a whole ``dwb:`` config)
TUNED_ARG = "tuned"


def tuned_file(name: str) -> Path:
    """The shipped parameter file of ``NAME:tuned``."""
    return Path(str(resources.files("policies.config").joinpath(f"{name}_{TUNED_ARG}.yaml")))


def param_file(path: str | Path, name: str) -> dict[str, Any]:
    """A parameter file: a YAML mapping of numbers, true/false (switches such as RPP's
    ``allow_reversing``) or null; the policy rejects unknown names itself."""
    import math

    from scenario_gen.schema import load_yaml

    data = load_yaml(path, f"policy {name}")
    if not data:
        raise InputError(
            f"policy {name}",
            str(path),
            f"holds no parameters; allowed: at least one (the defaults are plain {name!r})",
        )
    cls = POLICIES.get(name)
    if cls is not None and getattr(cls, "PARAMS", None):  # names first, then each one's range
        cls.check_file_params(data)
    for k, v in data.items():
        ok = v is None or isinstance(v, (int, float))
        if not ok or (isinstance(v, float) and not math.isfinite(v)):
            raise InputError(
                f"policy {name}: {k}", v, "allowed: a finite number, true/false or null"
            )
    return data


def check_policy_spec(spec: Any) -> tuple[str, str]:
    """(name, argument) of a policy spec, checked without an env: the CLI calls this before it
    builds anything, so a typo costs no simulator start-up and leaves nothing behind."""
    if not isinstance(spec, str):
        raise InputError("policy", spec, f"allowed: {', '.join(POLICIES)} or ppo:PATH")
    name, path = PolicySpec.parse(spec)
    if name not in POLICIES:
        raise InputError("policy", spec, f"allowed: {', '.join(POLICIES)} (ppo:PATH, ppo:shipped)")
    if spec.endswith(SEPARATOR) and not path:
        raise InputError("policy", spec, f"an empty ':' argument; allowed: {name} or {name}:ARG")
    if name == "ppo":
        if not path:
            raise InputError("policy", spec, "ppo needs a checkpoint: ppo:PATH or ppo:shipped")
        if path != SHIPPED_ARG and not Path(path).exists():
            raise InputError(
                "policy",
                spec,
                "allowed: a checkpoint folder holding checkpoint.json, or ppo:shipped",
            )
    elif name == "dwb":
        if path and path not in DWB_SHIPPED and not path.lower().endswith((".yaml", ".yml")):
            shipped = ", ".join(f"dwb:{n}" for n in DWB_SHIPPED)
            raise InputError("policy", spec, f"allowed: dwb, {shipped}, dwb:PATH.yaml")
    elif name in TUNABLE:
        ok = path == TUNED_ARG or (
            path.lower().endswith((".yaml", ".yml")) and Path(path).is_file()
        )
        if path and not ok:
            missing = path.lower().endswith((".yaml", ".yml")) and not Path(path).is_file()
            raise InputError(
                "policy",
                spec,
                ("no such file; " if missing else "")
                + f"allowed: {name}, {name}:{TUNED_ARG} or {name}:PATH.yaml (a parameter file)",
            )
        if path:  # its values, before any simulator starts
            file = tuned_file(name) if path == TUNED_ARG else path
            POLICIES[name].check_file_params(param_file(file, name))
    elif path:
        raise InputError("policy", spec, f"{name} takes no ':' argument")
    return name, path


def make_policy(spec: str, env: Any, **params: Any) -> Policy:
    """A controller for ``env``: ``spec`` is a policy name, ``ppo:PATH`` for a trained
    checkpoint, or ``ppo:shipped`` for the checkpoint shipped for the env's id; ``dwb:nav2``,
    ``dwb:furrow`` (= ``dwb``) or ``dwb:PATH.yaml`` pick the DWB configuration. The policy gets
    the env's spaces and its public ``RobotInterface``, nothing else."""
    name, path = check_policy_spec(spec)
    u = env.unwrapped
    kwargs: dict[str, Any] = dict(params)
    if name == "ppo":
        if path == SHIPPED_ARG:
            if u.spec is None:
                raise InputError("policy", spec, "ppo:shipped needs an env made with gym.make")
            path = str(shipped_model(u.spec.id))
        kwargs["path"] = path
    elif name == "dwb":
        # dwb = dwb:furrow (the furrow-tuned changes); dwb:nav2 = Nav2 Humble's defaults
        kwargs.setdefault("params", path or "furrow")
    elif name in TUNABLE and path:
        file = tuned_file(name) if path == TUNED_ARG else path
        kwargs = {**param_file(file, name), **kwargs}
    policy = POLICIES[name](u.observation_space, u.action_space, u.interface, **kwargs)
    trained_on = getattr(policy, "meta", {}).get("env_id")
    if trained_on and u.spec is not None and trained_on != u.spec.id:
        # the spaces matched (checked on loading), so it runs: a transfer, not a mistake
        # the user should be left to find in the results
        warnings.warn(
            f"{spec} was trained on {trained_on}; it drives {u.spec.id} here",
            Notice,
            stacklevel=2,
        )
    return policy
