"""``agrinav train``: PPO on an AgriNav env, hyperparameters from hyperparams/ppo.yml."""

from __future__ import annotations

import argparse
from typing import Any

from .args import int_at_least, seed_type


def add(sub: Any) -> None:
    tr = sub.add_parser("train", help="train a learned policy (PPO) on an AgriNav env")
    tr.add_argument("--env", required=True, help="env id, e.g. AgriNav/FurrowFollow-v0")
    tr.add_argument("--algo", default="ppo", choices=["ppo"])
    tr.add_argument("--timesteps", type=int_at_least(1), required=True)
    tr.add_argument("--seed", type=seed_type, default=0)
    tr.add_argument("--out", required=True)
    tr.add_argument(
        "--eval-every", type=int_at_least(1), default=20000, help="timesteps between evaluations"
    )
    tr.add_argument("--eval-episodes", type=int_at_least(1), default=4)
    tr.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from baselines.train import train

    out = train(
        args.env,
        args.timesteps,
        args.seed,
        args.out,
        args.eval_every,
        args.eval_episodes,
        argv=args.argv,
    )
    print(f"model, config, command and learning curve in {out}")
    return 0
