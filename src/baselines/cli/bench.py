"""``agrinav run`` and ``agrinav bench``: policies on envs, metrics, tables and figures."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from policies.spec import FORMS

from .args import episodes_type, int_at_least, seed_type, separated


def add(sub: Any) -> None:
    ru = sub.add_parser(
        "run", help="run a policy for some episodes: metrics.json + trajectory plots"
    )
    ru.add_argument(
        "--env", default="AgriNav/FieldRoute-v3", help="a registered env id (default: %(default)s)"
    )
    ru.add_argument("--policy", required=True, help=f"one of: {FORMS}")
    ru.add_argument(
        "--seed",
        type=seed_type,
        default=1_000_000_000,
        help="the first episode's reset seed; the next episodes take the following ones "
        "(default: %(default)s, the benchmarks' first evaluation seed)",
    )
    ru.add_argument(
        "--episodes", type=episodes_type, default=1, help="how many (default: %(default)s)"
    )
    ru.add_argument("--scenario", help="a scenario directory or preset (default: the env's)")
    ru.add_argument(
        "--out", required=True, help="the folder to write: metrics.json, plots, the video"
    )
    ru.add_argument("--video", action="store_true", help="write a WebM video of the first episode")
    ru.add_argument(
        "--max-steps",
        type=int_at_least(1),
        help="end each episode (truncated) after this many control steps (default: the env's)",
    )
    _common(ru)
    ru.set_defaults(func=run)

    from baselines.suites import SUITES

    be = sub.add_parser("bench", help="benchmark policies on a suite: results.json, benchmark.md")
    be.add_argument(
        "--suite",
        required=True,
        help=f"one of {', '.join(SUITES)} (growth: mesh camera)",
    )
    be.add_argument(
        "--cases",
        type=separated(";", "case names"),
        help="only these cases of the suite, separated by ';' (their names as benchmark.md "
        "shows them, e.g. 'curved rows R 15-30 m;contour rows, slope 4-8 deg'); each keeps "
        "its seeds",
    )
    be.add_argument(
        "--policies",
        required=True,
        type=separated(",", "policies"),
        help=f"a comma list (e.g. dwb:nav2,dwb,rpp:tuned,ppo:shipped) of: {FORMS}",
    )
    be.add_argument("--seeds", type=episodes_type, default=3)
    be.add_argument("--out", required=True)
    be.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an env config value set on every case over the suite's own, dotted and "
        "repeatable (e.g. soil.contact_width=0.15): the suite's fields and seeds with one "
        "assumed value moved; the tables and records say so",
    )
    _spread(be, "episodes")
    _common(be)
    be.set_defaults(func=bench)


def _spread(parser: Any, what: str) -> None:
    """``--workers`` and ``--ray``: where the command's independent tasks run."""
    parser.add_argument(
        "--workers",
        type=int_at_least(1),
        default=1,
        help=f"run the {what} in this many processes (the same results as 1)",
    )
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help=f"run the {what} as Ray tasks (the ray extra): local, auto or host:port",
    )


def _common(parser: Any) -> None:
    parser.add_argument("--force", action="store_true", help="replace an existing --out folder")
    parser.add_argument(
        "--trust-checkpoint",
        action="store_true",
        help="also load Stable-Baselines3 model.zip / vecnormalize.pkl files, which unpickle "
        "(run code) when loaded: only for files you trust",
    )


def run(args: argparse.Namespace) -> int:
    from baselines.bench import run as run_policy
    from baselines.report import run_table

    records = run_policy(
        args.env,
        args.policy,
        args.seed,
        args.episodes,
        args.out,
        args.scenario,
        args.video,
        max_steps=args.max_steps,
        force=args.force,
        trust_checkpoint=args.trust_checkpoint,
    )
    print(run_table(records))
    print(f"wrote {Path(args.out).resolve()} (metrics.json: every field of every episode)")
    return 0


def bench(args: argparse.Namespace) -> int:
    from baselines.bench import bench as run_bench
    from baselines.bench import command_line
    from baselines.scenario_spec import parse_set

    run_bench(
        args.suite,
        args.policies,
        args.seeds,
        args.out,
        command_line(args.argv),
        force=args.force,
        trust_checkpoint=args.trust_checkpoint,
        workers=args.workers,
        ray=args.ray,
        groups=args.cases,
        config=parse_set(args.config, "--config", "soil.contact_width=0.15"),
    )
    print((Path(args.out) / "benchmark.md").read_text())
    return 0
