"""``agrinav dataset perception``: labelled RGB-D frames from randomized fields."""

from __future__ import annotations

import argparse
from typing import Any

from ..scenario_spec import parse_set
from .args import episodes_type, int_at_least, seed_type


def add(sub: Any) -> None:
    ds = sub.add_parser("dataset", help="generate a domain-randomized dataset")
    kinds = ds.add_subparsers(dest="kind", required=True, metavar="{perception,trajectories}")
    pe = kinds.add_parser("perception", help="RGB-D frames with segmentation and labels")
    pe.add_argument("--spec", help="YAML file of spec fields (docs/datasets.md); default: defaults")
    pe.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="spec field")
    pe.add_argument("--out", required=True)
    # a bound, as --episodes has: a typo such as 10^20 must be an error, not an endless run
    pe.add_argument("--frames", type=int_at_least(1, 10_000_000), default=256)
    pe.add_argument("--workers", type=int_at_least(1), default=1)
    pe.add_argument("--seed", type=seed_type, default=0)
    pe.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="make the shards as Ray tasks (the ray extra): local, auto or host:port",
    )
    pe.set_defaults(func=perception)
    tr = kinds.add_parser("trajectories", help="policy rollouts as a Minari dataset")
    tr.add_argument("--env", default="AgriNav/FurrowFollow-v3")
    tr.add_argument("--policy", required=True, help="dwb, rpp, depth or ppo:PATH")
    tr.add_argument("--episodes", type=episodes_type, default=10)
    tr.add_argument("--seed", type=seed_type, default=0)
    tr.add_argument("--dataset-id", default="agrinav/furrow_follow-v0")
    tr.add_argument("--out", required=True)
    tr.add_argument("--force", action="store_true", help="replace an existing --out folder")
    tr.set_defaults(func=trajectories)


def perception(args: argparse.Namespace) -> int:
    from pathlib import Path

    from baselines.dataset import generate, load_spec, write_card

    spec = load_spec(args.spec, parse_set(args.set))
    n = generate(
        spec, Path(args.out), args.seed, args.frames, args.workers, card=write_card, ray=args.ray
    )
    print(f"{n} frames written to {args.out} (README.md, mosaic.png)")
    return 0


def trajectories(args: argparse.Namespace) -> int:
    from baselines.dataset.trajectories import record

    path = record(
        args.env, args.policy, args.episodes, args.out, args.seed, args.dataset_id, args.force
    )
    print(f"Minari dataset {args.dataset_id} written to {path}")
    print(
        f"load it: baselines.dataset.trajectories.load({str(args.out)!r}), or "
        f"minari.load_dataset({args.dataset_id!r}) with MINARI_DATASETS_PATH={args.out}"
    )
    return 0
