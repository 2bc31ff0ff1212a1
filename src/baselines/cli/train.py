"""``agrinav train``: PPO on an AgriNav env, hyperparameters from hyperparams/ppo.yml."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..scenario_spec import parse_set
from .args import int_at_least


def add(sub: Any) -> None:
    tr = sub.add_parser(
        "train",
        help="train a learned policy (PPO) on an AgriNav env",
        description="Train PPO with the env's entry of hyperparams/ppo.yml (rl-baselines3-zoo "
        "format) and envs.yml. Writes safe checkpoints, TensorBoard/CSV logs, config and curve.",
    )
    tr.add_argument("--env", required=True, help="env id, e.g. AgriNav/FurrowFollow-v3")
    tr.add_argument("--algo", default="ppo", choices=["ppo"])
    tr.add_argument("--timesteps", type=int_at_least(1), help="total steps (default: the file's)")
    tr.add_argument(
        "--seed",
        type=int_at_least(0, 2**32 - 1),  # numpy's legacy seeding, which SB3 uses
        default=0,
        help="the run's seed (0 to 2^32 - 1)",
    )
    tr.add_argument("--out", required=True, help="run folder (new or empty)")
    tr.add_argument("--n-envs", type=int_at_least(1, 256), help="parallel envs (default: file's)")
    tr.add_argument(
        "--device",
        default="cpu",
        help="torch device: cpu (default), cuda, cuda:N, mps, or auto (CUDA if present, else "
        "cpu); refused when not available here, recorded in checkpoint.json and config.yml",
    )
    tr.add_argument(
        "--hyperparams",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="override hyperparameters, e.g. learning_rate=1e-4 n_steps=256",
    )
    tr.add_argument(
        "--scenario", help="train on a preset, a saved scenario folder or a bank folder instead"
    )
    tr.add_argument(
        "--eval-every", type=int_at_least(1), default=20000, help="timesteps between evaluations"
    )
    tr.add_argument("--eval-episodes", type=int_at_least(1), default=4)
    tr.add_argument(
        "--checkpoint-every", type=int_at_least(1), help="save checkpoints/step_N every N steps"
    )
    tr.add_argument("--resume", help="continue from a checkpoint folder of an earlier run")
    tr.add_argument(
        "--init-from",
        metavar="CHECKPOINT",
        help="fine-tune: a new run that starts from this checkpoint folder's weights and "
        "observation normalisation (same observations and actions; fresh optimizer, its own step "
        "count, no warm start)",
    )
    tr.add_argument(
        "--env-kwargs",
        metavar="FILE",
        help="a YAML mapping merged over the env's envs.yml env_kwargs (nested mappings key by "
        "key), e.g. more randomize ranges; recorded in the run's config.yml",
    )
    tr.add_argument(
        "--no-warm-start",
        action="store_true",
        help="skip the env's behaviour-cloning warm start (envs.yml warm_start)",
    )
    tr.add_argument(
        "--torch-threads",
        type=int_at_least(1, 256),
        default=1,
        help="CPU threads for PyTorch (default 1: the env workers need the other cores)",
    )
    tr.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import torch

    from baselines.train import TrainRun, train

    torch.set_num_threads(args.torch_threads)  # a process setting: the application's to choose
    out = train(
        TrainRun(
            env_id=args.env,
            out=Path(args.out),
            seed=args.seed,
            timesteps=args.timesteps,
            eval_every=args.eval_every,
            eval_episodes=args.eval_episodes,
            n_envs=args.n_envs,
            device=args.device,
            overrides=parse_set(args.hyperparams, "--hyperparams", "learning_rate=1e-4"),
            scenario=args.scenario,
            checkpoint_every=args.checkpoint_every,
            resume=Path(args.resume) if args.resume else None,
            init_from=Path(args.init_from) if args.init_from else None,
            warm_start=not args.no_warm_start,
            env_kwargs=Path(args.env_kwargs) if args.env_kwargs else None,
        ),
        argv=args.argv,
    )
    print(f"checkpoint, config, command, logs and learning curve in {out}")
    return 0
