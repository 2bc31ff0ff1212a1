"""Held-out evaluation of an action function on an env id: mean return and the paper's metrics."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numpy as np


def evaluate(
    act: Callable[[dict[str, Any]], Any],
    env_id: str,
    kwargs: dict[str, Any],
    episodes: int,
    seed: int,
) -> dict[str, float]:
    """``episodes`` deterministic episodes with reset seeds ``seed``, ``seed + 1``, ...: the
    mean return, episode length (steps), paper metrics and success rate."""
    import gymnasium as gym

    import agrinav_gym

    env = gym.make(agrinav_gym.check_env_id(env_id), **kwargs)
    rets, rmse, furrow, comp, succ, crops = [], [], [], [], [], []
    lengths: list[int] = []
    try:
        for ep in range(episodes):
            obs, _ = env.reset(seed=seed + ep)
            total, done, steps = 0.0, False, 0
            info: dict[str, Any] = {}
            while not done:
                obs, r, term, trunc, info = env.step(act(obs))
                total += float(r)
                steps += 1
                done = term or trunc
            lengths.append(steps)
            m = info["metrics"]
            rets.append(total)
            rmse.append(m["rmse"] if m["rmse"] is not None else np.nan)
            furrow.append(m["in_furrow_rmse"] if m["in_furrow_rmse"] is not None else np.nan)
            crops.append(m["crops_hit"])
            comp.append(m["completion"])
            succ.append(float(info.get("is_success", False)))
    finally:
        env.close()
    with warnings.catch_warnings():  # all NaN (no episode measured it): NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        rmse_mean, furrow_mean = float(np.nanmean(rmse)), float(np.nanmean(furrow))
    return {
        "return": float(np.mean(rets)),
        "length": float(np.mean(lengths)),
        "rmse": rmse_mean,
        "in_furrow_rmse": furrow_mean,
        "completion": float(np.mean(comp)),
        "success": float(np.mean(succ)),
        "crops_hit": float(np.mean(crops)),
    }
