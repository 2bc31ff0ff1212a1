"""Does a controller drive each headland turn type? RPP on FieldRoute over seeded episodes.

For every turn type asked for, ``AgriNav/FieldRoute-v3`` on a preset (default ``hillside``:
two lanes, one turn) with ``route.turn`` set, Nav2's progress checker on (0.5 m within 10 s,
else the episode fails as a stall) and the default localisation; one episode per reset seed.
Counted per episode: the turn *completed* (the robot got past the turn's last waypoint along
the route, arc length, before the episode ended or it succeeded), the *headland cleared*
(it got 1 m into the next lane's crop without touching a crop plant on the way from the end
of the first lane), a *stall* (the progress check fired), and how the episode ended.

Run: ``python benchmarks/headland_turns.py [--turns omega keyhole] [--episodes 20]
[--set route.turn_offset=2.0 ...] [--config gnss.fix.model=constant ...] [--per-episode]``
(``--per-episode``: a line per reset seed, with how it ended, how far it got and which plants
it touched; ``--config``: env config values, dotted).
"""

from __future__ import annotations

import argparse
import collections
import time
from typing import Any

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401  (registers the envs)
from baselines.episodes import run_episode
from baselines.scenario_spec import parse_set
from baselines.suites import NAV2_PROGRESS
from policies import make_policy
from scenario_gen.errors import InputError
from scenario_gen.schema import merge


def turn_arcs(env: Any) -> tuple[float, float, float]:
    """Route arc lengths of the first lane's last furrow waypoint, the turn's last waypoint and
    1 m past the next lane's first furrow waypoint (inf: no turn)."""
    u = env.unwrapped
    r = u.scenario.route
    on = np.flatnonzero(r.turn != "")
    if not len(on):
        return (float("inf"),) * 3
    furrow = r.segment == "furrow"
    before = np.flatnonzero(furrow[: on[0]])[-1]
    after = on[-1] + np.flatnonzero(furrow[on[-1] :])[0]
    arc = u.route.arc
    return float(arc[before]), float(arc[on[-1]]), float(arc[after]) + 1.0


class Watch:
    """Called after every step (``run_episode``'s video hook): crops touched between the
    first lane's end and 1 m into the next lane, and whether the robot got that far."""

    def __init__(self) -> None:
        self.arcs: tuple[float, float, float] | None = None
        self.hits_at_exit: int | None = None
        self.hits_in: int | None = None
        self.frames = 0  # run_episode's hook protocol: a video's frame count, none here

    def __call__(self, env: Any) -> float:
        u = env.unwrapped
        if self.arcs is None:  # the first call comes right after reset
            self.arcs = turn_arcs(env)
        hits = len(u.crops_hit_ids)
        if self.hits_at_exit is None and u.arc >= self.arcs[0]:
            self.hits_at_exit = hits
        if self.hits_in is None and u.arc >= self.arcs[2]:
            self.hits_in = hits
        return 0.0  # seconds spent drawing (run_episode keeps them out of the episode's time)


def run(
    turn: str,
    episodes: int,
    preset: str,
    policy: str,
    first_seed: int,
    over: dict[str, Any],
    per_episode: bool = False,
    config: dict[str, Any] | None = None,
) -> dict[str, Any]:
    env = gym.make(
        "AgriNav/FieldRoute-v3",
        scenario=preset,
        scenario_overrides={**over, "route.turn": turn},
        config=merge({"task": NAV2_PROGRESS}, config or {}),
    )
    pol = make_policy(policy, env)
    ends: collections.Counter[str] = collections.Counter()
    completed = cleared = stalls = 0
    hits, headland = [], []
    t0 = time.perf_counter()
    for seed in range(first_seed, first_seed + episodes):
        watch = Watch()
        ep = run_episode(env, pol, seed, policy, video=watch)
        ends[ep.termination] += 1
        stalls += ep.termination == "progress"
        assert watch.arcs is not None
        done = ep.termination == "success" or env.unwrapped.arc > watch.arcs[1]
        completed += bool(done)
        cleared += (
            watch.hits_in is not None
            and watch.hits_at_exit is not None
            and watch.hits_in == watch.hits_at_exit
        )
        hits.append(ep.metrics.get("crops_hit", 0))
        headland.append(ep.metrics.get("headland_rmse", np.nan))
        if per_episode:
            touched = sorted(env.unwrapped.crops_hit_ids)
            print(
                f"  seed {seed}: {ep.termination} at {ep.metrics.get('completion', 0.0):.1f} % "
                f"of the route, turn {'completed' if done else 'not completed'}, plants "
                f"touched {touched} ({watch.hits_at_exit} before the turn, "
                f"{watch.hits_in} by 1 m into the next lane)",
                flush=True,
            )
    env.close()
    return {
        "turn": turn,
        "episodes": episodes,
        "completed": completed,
        "cleared": cleared,
        "stalls": stalls,
        "terminations": dict(ends),
        "crops_hit_mean": float(np.mean(hits)),
        "headland_rmse_mean": float(np.nanmean(headland)),
        "seconds": time.perf_counter() - t0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turns", nargs="+", default=["semicircle", "omega", "keyhole"])
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--preset", default="hillside")
    ap.add_argument("--policy", default="rpp")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario override, e.g. route.turn_offset=2.0 (repeatable)",
    )
    ap.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an env config value, e.g. gnss.fix.model=constant (repeatable)",
    )
    ap.add_argument("--per-episode", action="store_true", help="a line per reset seed")
    args = ap.parse_args()
    try:
        over = parse_set(args.set)
        config = parse_set(args.config, "--config", "gnss.fix.model=constant")
    except InputError as exc:
        ap.error(str(exc))
    for turn in args.turns:
        r = run(
            turn,
            args.episodes,
            args.preset,
            args.policy,
            args.first_seed,
            over,
            args.per_episode,
            config,
        )
        print(
            f"{args.policy} on {args.preset} {over or ''} {config or ''}, turn {r['turn']}: "
            "completed the "
            f"turn in {r['completed']}/{r['episodes']}, cleared the headland in "
            f"{r['cleared']}/{r['episodes']}, stalls {r['stalls']}, terminations "
            f"{r['terminations']}, crops hit {r['crops_hit_mean']:.2f}/episode, headland RMSE "
            f"{r['headland_rmse_mean']:.3f} m ({r['seconds']:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
