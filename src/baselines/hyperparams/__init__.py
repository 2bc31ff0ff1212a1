"""PPO hyperparameters: typed and validated like every other config, in rl-baselines3-zoo's file.

``hyperparams/ppo.yml`` is keyed by env id in rl-baselines3-zoo's format (``n_envs``,
``n_timesteps``, ``normalize``, ``policy`` — a dotted name zoo imports —, ``policy_kwargs`` and
PPO's constructor arguments), so ``python -m rl_zoo3.train --algo ppo --conf-file ...`` reads it
as it is. What zoo takes from its command line instead — the env kwargs and our disjoint
train/eval scenario-seed ranges (MetaDrive-style splits) — lives in ``hyperparams/envs.yml``.
Every PPO argument is forwarded, so none vanishes silently; unknown keys are errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from typing import Any

from scenario_gen.errors import InputError
from scenario_gen.schema import from_mapping, param, parse_yaml, to_mapping

POLICIES = ("MultiInputPolicy", "policies.extractors.DepthMultiInputPolicy")
#: keys zoo consumes itself; the rest go to PPO's constructor
ZOO_KEYS = ("n_envs", "n_timesteps", "normalize")


@dataclass(frozen=True)
class PPOHyperparams:
    n_envs: int = param(4, "parallel envs (SubprocVecEnv when > 1)", 1, 256)
    n_timesteps: int = param(500_000, "environment steps to train for", 1, 10**10)
    normalize: bool | dict[str, Any] = param(
        False,
        "VecNormalize the observations (true, or zoo's {norm_obs, norm_reward}; rewards are "
        "not normalised: norm_reward false)",
    )
    policy: str = param("MultiInputPolicy", "policy class", choices=POLICIES)
    learning_rate: float | str = param(3e-4, "Adam step size, or 'lin_<x>' (linear decay)")
    n_steps: int = param(512, "rollout length per env", 1, 10**6)
    batch_size: int = param(256, "minibatch size", 1, 10**7)
    n_epochs: int = param(10, "passes over each rollout", 1, 1000)
    gamma: float = param(0.99, "discount", 0.0, 1.0)
    gae_lambda: float = param(0.95, "GAE λ", 0.0, 1.0)
    clip_range: float | str = param(0.2, "PPO clip, or 'lin_<x>'")
    clip_range_vf: float | None = param(None, "value clip (null: none)", 0.0, 100)
    normalize_advantage: bool = param(True, "normalise advantages per minibatch")
    ent_coef: float = param(0.0, "entropy bonus", 0.0, 10)
    vf_coef: float = param(0.5, "value-loss weight", 0.0, 100)
    # SB3 scales every gradient by max_grad_norm / norm: at 0 nothing is learned
    max_grad_norm: float = param(0.5, "gradient clip", 1e-6, 1e6)
    use_sde: bool = param(False, "state-dependent exploration")
    sde_sample_freq: int = param(-1, "gSDE noise resample period (-1: per rollout)", -1, 10**6)
    target_kl: float | None = param(None, "early-stop epochs above this KL (null: never)", 0, 10)
    stats_window_size: int = param(100, "episodes averaged in the rollout logs", 1, 10**6)
    policy_kwargs: dict[str, Any] = param({}, "network: net_arch, log_std_init, activation_fn ...")

    def ppo_kwargs(self) -> dict[str, Any]:
        """Every PPO constructor argument this holds (all but zoo's own keys)."""
        from stable_baselines3.common.utils import get_linear_fn

        out = {k: v for k, v in to_mapping(self).items() if k not in ZOO_KEYS}
        for key in ("learning_rate", "clip_range"):
            if isinstance(out[key], str):
                out[key] = get_linear_fn(_lin(out[key], key), 0.0, 1.0)
        from policies.checkpoint import policy_kwargs_from_json

        # checked as a checkpoint's are, an activation named ("ReLU") made the class
        out["policy_kwargs"] = policy_kwargs_from_json(out["policy_kwargs"], "hyperparams")
        if self.policy != "MultiInputPolicy":
            from policies.extractors import DepthMultiInputPolicy

            out["policy"] = DepthMultiInputPolicy
        return out

    @property
    def normalize_obs(self) -> bool:
        n = self.normalize
        return bool(n.get("norm_obs", True)) if isinstance(n, dict) else bool(n)


def _lin(text: str, key: str) -> float:
    kind, _, value = text.partition("_")
    try:
        x = float(value) if kind == "lin" else math.nan
    except ValueError:
        x = math.nan
    if not (math.isfinite(x) and x > 0):  # the schedule starts where a plain value would
        raise InputError(
            f"hyperparams.{key}", text, "allowed: a positive number or 'lin_<positive number>'"
        )
    return x


@dataclass(frozen=True)
class EnvSetup:
    """What zoo takes on its command line: env kwargs and the disjoint scenario-seed splits."""

    env_kwargs: dict[str, Any] = param({}, "gym.make kwargs for training and evaluation")
    train_seeds: tuple[int, int] = param(
        (0, 1_000_000), "[low, high) scenario seeds to train on", 0, 2**62
    )
    val_seeds: tuple[int, int] = param(
        (500_000_000, 501_000_000),
        "[low, high) validation scenario seeds: training-time evaluation and checkpoint choice",
        0,
        2**62,
    )
    eval_seeds: tuple[int, int] = param(
        (1_000_000_000, 1_001_000_000),
        "[low, high) held-out test scenario seeds: agrinav bench only, no decision taken on them",
        0,
        2**62,
    )
    warm_start: dict[str, Any] | None = param(
        None, "behaviour-cloning warm start before PPO (baselines/imitation.py; null: none)"
    )

    def warm(self, env_id: str) -> Any:
        """The checked ``WarmStart``, or None."""
        if self.warm_start is None:
            return None
        from policies import check_policy_spec

        from ..imitation import WarmStart

        ws: WarmStart = from_mapping(WarmStart, self.warm_start, f"envs.yml {env_id}.warm_start.")
        check_policy_spec(ws.policy)
        return ws


def _table(name: str) -> dict[str, Any]:
    text = resources.files("baselines.hyperparams").joinpath(name).read_text()
    data = parse_yaml(text, name)
    return data if isinstance(data, dict) else {}


def load(env_id: str, overrides: dict[str, Any] | None = None) -> tuple[PPOHyperparams, EnvSetup]:
    """The hyperparameters and env setup for ``env_id``, with ``overrides`` applied."""
    table, envs = _table("ppo.yml"), _table("envs.yml")
    if env_id not in table:
        raise InputError("--env", env_id, f"allowed (with PPO hyperparameters): {', '.join(table)}")
    data = {**table[env_id], **(overrides or {})}
    hp: PPOHyperparams = from_mapping(PPOHyperparams, data, "hyperparams.")
    for key in ("learning_rate", "clip_range"):
        value = getattr(hp, key)
        if isinstance(value, str):
            _lin(value, key)
        elif value <= 0:
            raise InputError(f"hyperparams.{key}", value, "allowed: a positive number or 'lin_<x>'")
    from policies.checkpoint import policy_kwargs_from_json

    policy_kwargs_from_json(hp.policy_kwargs, "hyperparams")  # before any folder exists
    if isinstance(hp.normalize, dict):
        n = hp.normalize
        if set(n) - {"norm_obs", "norm_reward"} or not all(isinstance(v, bool) for v in n.values()):
            raise InputError(
                "hyperparams.normalize", n, "allowed: true/false or {norm_obs: true/false}"
            )
        if n.get("norm_reward"):  # training keeps the reward parts as the env reports them
            raise InputError(
                "hyperparams.normalize.norm_reward", True, "allowed: false (not supported)"
            )
    if hp.batch_size < 2:  # SB3 normalises advantages over a minibatch: one sample is none
        raise InputError("hyperparams.batch_size", hp.batch_size, "allowed: at least 2")
    if hp.batch_size > hp.n_steps * hp.n_envs:
        raise InputError(
            "hyperparams.batch_size",
            hp.batch_size,
            f"allowed: at most n_steps × n_envs = {hp.n_steps * hp.n_envs}",
        )
    if hp.use_sde:  # its noise matrix has no place in the checkpoint: the run would not load
        raise InputError(
            "hyperparams.use_sde",
            True,
            "the checkpoint format holds a Gaussian policy's log_std vector, not gSDE's "
            "matrix; allowed: false",
        )
    setup: EnvSetup = from_mapping(EnvSetup, envs.get(env_id, {}), f"envs.yml {env_id}.")
    check_splits(setup, f"envs.yml {env_id}.")
    setup.warm(env_id)
    return hp, setup


def check_splits(setup: EnvSetup, where: str) -> None:
    """Train, validation and test seed ranges: each non-empty, no two overlapping."""
    ranges = {"train_seeds": setup.train_seeds, "val_seeds": setup.val_seeds}
    ranges["eval_seeds"] = setup.eval_seeds
    seen: dict[str, tuple[int, int]] = {}
    for name, (lo, hi) in ranges.items():
        if not lo < hi:
            raise InputError(f"{where}{name}", [lo, hi], "allowed: a [low, high) range, low < high")
        for other, (olo, ohi) in seen.items():
            if lo < ohi and olo < hi:
                raise InputError(
                    f"{where}{name}",
                    [lo, hi],
                    f"allowed: a range disjoint from {other} {[olo, ohi]}",
                )
        seen[name] = (lo, hi)


def to_zoo(hp: PPOHyperparams) -> dict[str, Any]:
    """The hyperparameters as an rl-baselines3-zoo ``ppo.yml`` entry."""
    return {k: v for k, v in to_mapping(hp).items() if v is not None}


__all__ = ["EnvSetup", "PPOHyperparams", "load", "refuse_split_keys", "to_zoo"]


def refuse_split_keys(extra: dict[str, Any]) -> None:
    """An ``--env-kwargs`` file may not set the seeds: the splits are envs.yml's (training seeds
    for the episodes, validation for any choice); a file that set them would train or choose on
    other fields than the run records."""
    split = sorted(k for k in extra if k in ("scenario_seeds", "scenario_seed"))
    if split:
        raise InputError(
            f"--env-kwargs {split[0]}",
            extra[split[0]],
            "is set by envs.yml's train/validation/test splits; allowed: any other env keyword",
        )


def merge_env_kwargs(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    """``base`` (an envs.yml ``env_kwargs``) with ``extra`` over it: nested mappings key by key
    (a ``randomize`` mapping adds ranges and replaces those it names), anything else replaced.
    Dotted keys stay keys — randomize's are names, not paths — so ``schema.merge`` (which
    splits them) is not the merge here."""
    out = dict(base)
    for k, v in extra.items():
        both = isinstance(v, dict) and isinstance(out.get(k), dict)
        out[k] = merge_env_kwargs(out[k], v) if both else v
    return out
