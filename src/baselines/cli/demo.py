"""``agrinav demo``: the main job on the embedded default."""

from __future__ import annotations

import argparse
from typing import Any

from .args import episodes_type


def add(sub: Any) -> None:
    de = sub.add_parser(
        "demo",
        help="DWB, shipped PPO and the blind reference on the paper suite's fields (saved "
        "and printed first)",
    )
    de.add_argument(
        "--out",
        default="runs/demo",
        help="the folder to write: the fields, benchmark.md, figures (default: %(default)s)",
    )
    de.add_argument(
        "--seeds",
        type=episodes_type,
        default=2,
        help="held-out seeds per field and policy (default: %(default)s)",
    )
    de.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from baselines.demo import demo

    demo(args.out, args.seeds)
    return 0
