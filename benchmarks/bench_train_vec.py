"""PPO training throughput: SB3's ``SubprocVecEnv`` (one process per env) against
``BatchedSB3VecEnv`` (``agrinav_gym.make_vec``: the envs several to a worker process), the way
``agrinav train`` runs them, interleaved.

Each setup trains FieldRoute-v3's PPO (its ppo.yml entry, its envs.yml training kwargs) for
``--rollouts`` rollouts of ``n_envs × n_steps`` steps from the same seed, after one untimed
rollout; timed are ``model.learn``'s steps per wall second (rollout collection and the
updates) and, separately, the rollout collection alone. Both see the same episodes (the
adapter's test compares them step for step), so only the time differs.

    python benchmarks/bench_train_vec.py [--repeat 3] [--rollouts 2] [--n-envs 4] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from typing import Any

import torch


def _setup(kind: str, n_envs: int, workers: int) -> tuple[Any, Any]:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv, VecNormalize

    from baselines import hyperparams as hpmod
    from baselines.sb3_vec import BatchedSB3VecEnv

    env_id = "AgriNav/FieldRoute-v3"
    hp, setup = hpmod.load(env_id, {"n_envs": n_envs})
    kw = {**setup.env_kwargs, "scenario_seeds": list(setup.train_seeds)}
    if kind == "subproc":
        venv: Any = make_vec_env(
            f"agrinav_gym:{env_id}", n_envs=n_envs, seed=0, vec_env_cls=SubprocVecEnv, env_kwargs=kw
        )
    else:
        venv = BatchedSB3VecEnv(env_id, n_envs, workers, kw)
        venv.seed(0)
    venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)
    model = PPO(env=venv, seed=0, verbose=0, device="cpu", **hp.ppo_kwargs())
    return model, venv


def _timed_learn(model: Any, steps: int) -> tuple[float, float]:
    """(steps per second of learn, steps per second of the rollouts alone)."""
    collect = 0.0
    original = model.collect_rollouts

    def timed(*a: Any, **k: Any) -> Any:
        nonlocal collect
        t0 = time.perf_counter()
        out = original(*a, **k)
        collect += time.perf_counter() - t0
        return out

    model.collect_rollouts = timed
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    wall = time.perf_counter() - t0
    model.collect_rollouts = original
    return steps / wall, steps / collect


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rollouts", type=int, default=2)
    ap.add_argument("--n-envs", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(1)  # as agrinav train: the env workers need the other cores
    kinds = ("subproc", "batched")
    setups = {k: _setup(k, args.n_envs, args.workers) for k in kinds}
    rate: dict[str, list[float]] = {k: [] for k in kinds}
    roll: dict[str, list[float]] = {k: [] for k in kinds}
    for model, _ in setups.values():  # warm-up: the first rollout, untimed
        model.learn(total_timesteps=model.n_steps * args.n_envs)
    for _ in range(args.repeat):
        for k, (model, _) in setups.items():
            r, c = _timed_learn(model, args.rollouts * model.n_steps * args.n_envs)
            rate[k].append(r)
            roll[k].append(c)
    for _, venv in setups.values():
        venv.close()
    print(
        f"PPO on FieldRoute-v3, {args.n_envs} envs, {args.rollouts} rollouts a run, median of "
        f"{args.repeat} interleaved runs ({platform.machine()}, {os.cpu_count()} cores):"
    )
    for k, label in zip(
        kinds, ("SubprocVecEnv (1 env/process)", f"make_vec ({args.workers} workers)"), strict=True
    ):
        print(
            f"  {label:32s} learn {statistics.median(rate[k]):7.0f} steps/s "
            f"(runs {', '.join(f'{x:.0f}' for x in rate[k])}); "
            f"rollouts {statistics.median(roll[k]):7.0f} steps/s"
        )

    def ratio(x: dict[str, list[float]]) -> float:
        return statistics.median(b / s for b, s in zip(x["batched"], x["subproc"], strict=True))

    print(f"  batched / subproc: learn {ratio(rate):.2f}x, rollouts {ratio(roll):.2f}x")


if __name__ == "__main__":
    main()
