"""``agrinav train``: PPO on an AgriNav env with hyperparameters from hyperparams/ppo.yml.

Every run writes, next to its model: ``config.yml`` (the exact hyperparameters and env
kwargs), ``command.txt`` (how to reproduce it), ``evaluations.json`` and ``learning_curve.png``
(periodic evaluation on held-out scenario seeds).
"""

from __future__ import annotations

import json
import shlex
import sys
import time
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from scenario_gen import ScenarioError

HYPERPARAMS = "ppo.yml"


def hyperparams(env_id: str) -> dict[str, Any]:
    text = resources.files("baselines.hyperparams").joinpath(HYPERPARAMS).read_text()
    table = yaml.safe_load(text)
    if env_id not in table:
        raise ScenarioError(
            "--env", env_id, f"allowed (with PPO hyperparameters): {', '.join(table)}"
        )
    return dict(table[env_id])


def _make_env(env_id: str, kwargs: dict[str, Any]) -> Any:
    import gymnasium as gym

    import agrinav_gym  # noqa: F401

    return gym.make(env_id, **kwargs)


def evaluate(
    model: Any, env_id: str, kwargs: dict[str, Any], norm: Any, episodes: int, seed: int
) -> dict[str, float]:
    """Deterministic episodes on held-out seeds; mean return and the paper's metrics."""
    env = _make_env(env_id, kwargs)
    rets, rmse, furrow, comp, succ, crops = [], [], [], [], [], []
    try:
        for ep in range(episodes):
            obs, _ = env.reset(seed=seed + ep)
            total, done, info = 0.0, False, {}
            while not done:
                o = obs
                if norm is not None:
                    o = norm.normalize_obs({k: v[None] for k, v in obs.items()})
                    o = {k: v[0] for k, v in o.items()}
                action, _ = model.predict(o, deterministic=True)
                obs, r, term, trunc, info = env.step(action)
                total += float(r)
                done = term or trunc
            m = info["metrics"]
            rets.append(total)
            rmse.append(m["rmse"] if m["rmse"] is not None else np.nan)
            furrow.append(m["in_furrow_rmse"] if m["in_furrow_rmse"] is not None else np.nan)
            crops.append(m["crops_hit"])
            comp.append(m["completion"])
            succ.append(float(info.get("is_success", False)))
    finally:
        env.close()
    return {
        "return": float(np.mean(rets)),
        "rmse": float(np.nanmean(rmse)),
        "in_furrow_rmse": float(np.nanmean(furrow)),
        "completion": float(np.mean(comp)),
        "success": float(np.mean(succ)),
        "crops_hit": float(np.mean(crops)),
    }


def train(
    env_id: str,
    timesteps: int,
    seed: int,
    out: str | Path,
    eval_every: int = 20000,
    eval_episodes: int = 4,
    argv: list[str] | None = None,
) -> Path:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize
    from tqdm import tqdm

    from policies.extractors import DepthAndVector

    if timesteps < 1:
        raise ScenarioError("--timesteps", timesteps, "allowed: an integer >= 1")
    out_dir = Path(out)
    if out_dir.exists() and any(out_dir.iterdir()):
        raise ScenarioError("--out", str(out_dir), "already holds files; choose a new directory")
    hp = hyperparams(env_id)
    env_kwargs = dict(hp.get("env_kwargs", {}))
    train_kwargs = {**env_kwargs, "scenario_seeds": list(hp["train_seeds"])}
    eval_kwargs = {**env_kwargs, "scenario_seeds": list(hp["eval_seeds"])}
    n_envs = int(hp.get("n_envs", 1))
    torch.set_num_threads(1)  # the env processes need the other core
    venv = make_vec_env(
        f"agrinav_gym:{env_id}",
        n_envs=n_envs,
        seed=seed,
        vec_env_cls=SubprocVecEnv if n_envs > 1 else DummyVecEnv,
        env_kwargs=train_kwargs,
    )
    norm = None
    if hp.get("normalize"):
        venv = norm = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
    policy_kwargs = dict(hp.get("policy_kwargs", {}))
    if hp.get("features_extractor") == "DepthAndVector":
        policy_kwargs["features_extractor_class"] = DepthAndVector
    model = PPO(
        hp["policy"],
        venv,
        seed=seed,
        verbose=0,
        device="cpu",
        n_steps=hp["n_steps"],
        batch_size=hp["batch_size"],
        n_epochs=hp["n_epochs"],
        learning_rate=hp["learning_rate"],
        gamma=hp["gamma"],
        gae_lambda=hp["gae_lambda"],
        clip_range=hp["clip_range"],
        ent_coef=hp["ent_coef"],
        policy_kwargs=policy_kwargs,
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    history: list[dict[str, float]] = []
    eval_seed = int(hp["eval_seeds"][0])
    t_start = time.perf_counter()

    class Progress(BaseCallback):
        def _on_training_start(self) -> None:
            self.bar = tqdm(total=timesteps, desc=f"train {env_id}", unit="step")
            self.next_eval = eval_every

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            if self.num_timesteps >= self.next_eval:
                self.next_eval += eval_every
                res = evaluate(self.model, env_id, eval_kwargs, norm, eval_episodes, eval_seed)
                res.update(
                    timesteps=self.num_timesteps, minutes=(time.perf_counter() - t_start) / 60
                )
                history.append(res)
                self.bar.set_postfix(rmse=f"{res['rmse']:.3f}", done=f"{res['completion']:.0f}%")
                (out_dir / "evaluations.json").write_text(json.dumps(history, indent=1))
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    model.learn(total_timesteps=timesteps, callback=Progress())
    final = evaluate(model, env_id, eval_kwargs, norm, eval_episodes, eval_seed)
    final.update(timesteps=int(model.num_timesteps), minutes=(time.perf_counter() - t_start) / 60)
    history.append(final)
    slim_optimizer(model)
    model.save(out_dir / "model.zip")
    if norm is not None:
        norm.save(str(out_dir / "vecnormalize.pkl"))
    venv.close()
    config = {
        "env_id": env_id,
        "algo": "ppo",
        "seed": seed,
        "timesteps": timesteps,
        "hyperparams": hp,
        "minutes": final["minutes"],
    }
    (out_dir / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    cmd = argv if argv is not None else sys.argv
    (out_dir / "command.txt").write_text(" ".join(shlex.quote(a) for a in cmd) + "\n")
    (out_dir / "evaluations.json").write_text(json.dumps(history, indent=1))
    learning_curve(history, out_dir / "learning_curve.png", env_id)
    return out_dir


def slim_optimizer(model: Any) -> None:
    """Drop Adam's moment estimates (twice the weights' size) before saving: a shipped
    checkpoint is for inference, and fine-tuning from it restarts the moments."""
    pol = model.policy
    pol.optimizer = pol.optimizer_class(
        pol.parameters(), lr=model.lr_schedule(1), **pol.optimizer_kwargs
    )


def learning_curve(history: list[dict[str, float]], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [h["minutes"] for h in history]
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    ax[0].plot(t, [h["return"] for h in history], "o-")
    ax[0].set_xlabel("training time (min, 2-core CPU)")
    ax[0].set_ylabel("eval return (held-out seeds)")
    ax[1].plot(t, [h["rmse"] for h in history], "o-", color="tab:red", label="RMSE")
    if all("in_furrow_rmse" in h for h in history):
        ax[1].plot(
            t, [h["in_furrow_rmse"] for h in history], "^-", color="tab:purple", label="in-furrow"
        )
    ax[1].legend(loc="upper left", fontsize=8)
    ax[1].set_xlabel("training time (min)")
    ax[1].set_ylabel("cross-track RMSE (m)")
    ax2 = ax[1].twinx()
    ax2.plot(t, [h["completion"] for h in history], "s--", color="tab:green")
    ax2.set_ylabel("completion (%)", color="tab:green")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
