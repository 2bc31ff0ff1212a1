"""``agrinav tune``: a classical controller's parameters searched on the training split."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .args import episodes_type, int_at_least


def add(sub: Any) -> None:
    from baselines.tune import SEARCH

    tu = sub.add_parser(
        "tune",
        help="search a classical controller's parameters on training fields (Optuna)",
        description="An Optuna TPE search of the controller's parameters on FieldRoute training "
        "fields (the same fields and reset seeds for every trial and controller); writes "
        "best.yaml (run it with --policies NAME:best.yaml), trials.csv, search.png. A killed "
        "run resumes: the same command runs only the episodes it had not finished.",
    )
    tu.add_argument("--policy", required=True, choices=sorted(SEARCH))
    tu.add_argument("--trials", type=int_at_least(1, 10_000), default=40)
    tu.add_argument("--episodes", type=episodes_type, default=8, help="training fields a trial")
    tu.add_argument(
        "--seed",
        type=int_at_least(0, 2**32 - 1),  # Optuna's TPE sampler (numpy's legacy seeding)
        default=0,
        help="the search's seed and the first reset seed (0 to 2^32 - 1)",
    )
    tu.add_argument("--out", required=True)
    tu.add_argument("--force", action="store_true", help="replace an earlier tune's --out")
    tu.add_argument(
        "--workers",
        type=int_at_least(1),
        default=1,
        help="run each trial's episodes in this many processes (the same search as 1)",
    )
    tu.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run each trial's episodes as Ray tasks (the ray extra): local, auto or host:port",
    )
    tu.add_argument(
        "--env-kwargs",
        metavar="FILE",
        help="a YAML mapping merged over the env's envs.yml env_kwargs, as agrinav train "
        "--env-kwargs takes it (e.g. curved rows and other turns in the training ranges)",
    )
    tu.add_argument(
        "--route-clock",
        action="store_true",
        help="end each episode on the test suites' clock (20 s per metre of route, Nav2's "
        "progress-checker rate) instead of the registered 4,000 steps",
    )
    tu.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from baselines.report import command_line
    from baselines.tune import tune

    best = tune(
        args.policy,
        args.trials,
        args.episodes,
        args.seed,
        args.out,
        command_line(["agrinav", *sys.argv[1:]]),
        args.force,
        workers=args.workers,
        ray=args.ray,
        env_kwargs=Path(args.env_kwargs) if args.env_kwargs else None,
        route_clock=args.route_clock,
    )
    print(f"best trial {best['trial']}: score {best['score']} -> {args.out}/best.yaml")
    return 0
