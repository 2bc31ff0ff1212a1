"""``agrinav export-policy``: a PPO checkpoint as ONNX, or as Stable-Baselines3 files in
rl-baselines3-zoo's layout."""

from __future__ import annotations

import argparse
from typing import Any


def add(sub: Any) -> None:
    from baselines.policy_export import TARGETS

    ep = sub.add_parser(
        "export-policy",
        help="export a PPO checkpoint as ONNX or as Stable-Baselines3 / rl-baselines3-zoo files",
        description="Export a PPO checkpoint: --to onnx (policy.onnx: raw observations in, one "
        "input per observation key, normalisation folded in, the deterministic action out) or "
        "--to sb3 (PPO.save's model zip and vecnormalize.pkl in rl-baselines3-zoo's folder "
        "layout). Each export is checked against the torch policy before it is written.",
    )
    ep.add_argument(
        "checkpoint",
        metavar="CHECKPOINT",
        help="a checkpoint folder (checkpoint.json), ppo:PATH or shipped:ENV_ID",
    )
    ep.add_argument("--to", required=True, choices=TARGETS, help="what to export as")
    ep.add_argument(
        "--out", required=True, metavar="DIR", help="output folder (must not exist, or --force)"
    )
    ep.add_argument("--force", action="store_true", help="replace an earlier export's folder")
    ep.add_argument(
        "--trust-checkpoint",
        action="store_true",
        help="--to onnx: also read a Stable-Baselines3 model.zip or rl-baselines3-zoo run "
        "folder, which unpickles (runs code) when loaded: only for files you trust",
    )
    ep.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from baselines.policy_export import export_policy

    info = export_policy(
        args.checkpoint, args.to, args.out, args.force, args.trust_checkpoint, args.argv
    )
    width = max(map(len, info))
    for k, v in info.items():
        print(f"{k:<{width}}  {v}")
    return 0
