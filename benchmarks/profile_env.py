"""Where an env step's time goes: a per-part timer over FurrowFollow-v3 steps (on paper-p1).

Each part of ``AgriNavEnv.step`` (design.md §3) is wrapped, on the env instance, in a timer;
the table lists microseconds per env step and the share of the step. Nested rows (indented)
are inside the row above them. "raw physics" is what ``bench_env.py`` divides by: the drive
command and the physics substeps (tyre model + pybullet). The timers cost ≈ 0.2 µs each, so
the parts add up to a little more than an untimed step.

    python benchmarks/profile_env.py [--steps 400] [--repeat 5] [--localisation KIND]
        [--scenario PRESET]

``--localisation robot_localization-3d`` runs robot_localization with ``two_d_mode: false``,
``robot_localization-numpy`` its planar filter's numpy twin instead of the compiled kernel.

With ``--cprofile`` it prints cProfile's 30 most expensive functions instead (cProfile's own
overhead inflates pure-Python code several times: use it to find functions, the timer table
to weigh parts).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import statistics
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import pybullet as p

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym import rewards
from agrinav_gym.estimation.robot_localization import RobotLocalizationEkf
from agrinav_gym.render import native
from common import drive

#: (label, owner path from the unwrapped env, attribute, depth): depth 1 rows are inside the
#: depth 0 row above them
PARTS: tuple[tuple[str, str, str, int], ...] = (
    ("action check", "", "_check_action", 0),
    ("command (acceleration limits)", "", "_command", 0),
    ("drive (wheel motor targets)", "world", "drive", 1),
    ("terrain window follow", "world", "follow", 0),
    ("physics substeps", "world", "step", 0),
    ("tyre model", "world.tyres", "apply", 1),
    ("true state query", "world", "state", 0),
    ("sensors (GNSS, IMU, odometry)", "sensors", "step", 0),
    ("estimator", "estimator", "update", 0),
    ("step context", "", "_context", 0),
    ("route tracker", "tracker", "update", 1),
    ("metrics update", "metrics", "update", 1),
    ("crop contact", "contact", "touching", 1),
    ("termination checks", "task", "check", 0),
    ("reward terms", "<rewards>", "evaluate", 0),
    ("snapshot", "", "_snapshot", 0),
    ("observations", "", "_observe", 0),
    ("info", "", "_info", 0),
    ("metrics result", "", "episode_metrics", 1),
)


def _owner(env: Any, path: tuple[str, ...]) -> Any:
    obj = env
    for name in path:
        obj = getattr(obj, name)
    return obj


def instrument(env: Any, totals: dict[str, float]) -> Callable[[], None]:
    """Wrap every part in a timer adding to ``totals``; returns the undo. Methods are wrapped
    on their class and timed only for the env's current part (the tracker and the metrics are
    rebuilt at each reset; the route observation has a tracker of its own)."""
    pc = time.perf_counter
    undo = []
    for label, path, attr, _ in PARTS:
        totals[label] = 0.0
        if path == "<rewards>":
            fn = rewards.evaluate

            def timed_fn(*a: Any, _fn: Any = fn, _label: str = label, **kw: Any) -> Any:
                t0 = pc()
                try:
                    return _fn(*a, **kw)
                finally:
                    totals[_label] += pc() - t0

            rewards.evaluate = timed_fn
            undo.append((rewards, attr, fn))
            continue
        names = tuple(filter(None, path.split(".")))
        cls = type(_owner(env, names))
        fn = getattr(cls, attr)

        def timed(
            self: Any,
            *a: Any,
            _fn: Any = fn,
            _label: str = label,
            _path: tuple[str, ...] = names,
            **kw: Any,
        ) -> Any:
            if self is not _owner(env, _path):
                return _fn(self, *a, **kw)
            t0 = pc()
            try:
                return _fn(self, *a, **kw)
            finally:
                totals[_label] += pc() - t0

        setattr(cls, attr, timed)
        undo.append((cls, attr, fn))

    def restore() -> None:
        for owner, attr, fn in reversed(undo):
            setattr(owner, attr, fn)

    return restore


#: ``--localisation`` names beyond the estimator kinds
VARIANTS: dict[str, dict[str, Any]] = {
    "robot_localization-3d": {
        "kind": "robot_localization",
        "robot_localization": {"two_d_mode": False},
    },
}
#: ``--localisation`` names whose filter is swapped for another after the env is made
NUMPY_TWINS = {"robot_localization-numpy": "robot_localization"}


def make(localisation: str, scenario: str = "paper-p1") -> Any:
    if localisation in NUMPY_TWINS:
        env = make(NUMPY_TWINS[localisation], scenario)
        u = env.unwrapped
        u.estimator = RobotLocalizationEkf(u.cfg.localisation, u.world.skid_factor, u.dt, False)
        return env
    loc = VARIANTS.get(localisation, {"kind": localisation})
    return gym.make(
        "AgriNav/FurrowFollow-v3",
        scenario=scenario,
        observations=("gps", "imu", "odom", "route"),
        config={
            "task": {"max_crops_hit": 10**6, "corridor": 2.0},
            "localisation": loc,
        },
    )


def table(localisation: str, steps: int, repeat: int, scenario: str = "paper-p1") -> None:
    """Each repeat: a reset (seed r) and ``steps`` timed steps, as bench_env.py's ratio."""
    env = make(localisation, scenario)
    u = env.unwrapped
    runs: list[dict[str, float]] = []
    for r in range(repeat):
        env.reset(seed=r)
        totals: dict[str, float] = {}
        # the tracker and metrics are rebuilt at reset: instrument after it
        restore = instrument(u, totals)
        t = drive(env, steps)
        restore()
        totals["env step (total)"] = t
        runs.append({k: v / steps * 1e6 for k, v in totals.items()})
    env.close()
    med = {k: statistics.median(run[k] for run in runs) for k in runs[0]}
    total = med["env step (total)"]
    top = sum(med[label] for label, _, _, depth in PARTS if depth == 0)
    raw = med["physics substeps"] + med["drive (wheel motor targets)"]
    print(f"\nFurrowFollow-v3 on {scenario}, gps/imu/odom/route, {localisation}: µs per env step")
    print(f"(median of {repeat} runs of {steps} steps from a reset; kernels: {kernels()})\n")
    print("| part | µs / step | share |")
    print("|---|---|---|")
    for label, _, _, depth in PARTS:
        if label == "tyre model":
            sub = med[label]
            print(f"| {'  ' * depth}{label} | {sub:.1f} | {100 * sub / total:.0f} % |")
            rest = med["physics substeps"] - sub
            share = 100 * rest / total
            print(f"| {'  ' * depth}pybullet stepSimulation | {rest:.1f} | {share:.0f} % |")
            continue
        v = med[label]
        name = f"{'  ' * depth}{label}" if depth else label
        print(f"| {name} | {v:.1f} | {100 * v / total:.0f} % |")
    other = total - top
    print(f"| other (gym wrappers, step glue) | {other:.1f} | {100 * other / total:.0f} % |")
    print(f"| **env step** | **{total:.1f}** | 100 % |")
    print(f"| raw physics (drive + substeps) | {raw:.1f} | env / raw {total / raw:.2f} |")


def kernels() -> str:
    return "compiled" if native.available() else "Python/numpy twins"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--localisation",
        default="ekf",
        choices=("ekf", "robot_localization", *VARIANTS, *NUMPY_TWINS, "blend", "ideal"),
        help="robot_localization-3d: robot_localization with two_d_mode false",
    )
    ap.add_argument(
        "--scenario",
        default="paper-p1",
        help="a preset: mature-corn puts a 3 m canopy over the antenna (the GNSS sky model's "
        "heaviest case)",
    )
    ap.add_argument("--cprofile", action="store_true")
    args = ap.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, pybullet {p.getAPIVersion()}"
    )
    if args.cprofile:
        env = make(args.localisation, args.scenario)
        env.reset(seed=0)
        drive(env, 50)
        pr = cProfile.Profile()
        pr.enable()
        drive(env, args.steps)
        pr.disable()
        env.close()
        pstats.Stats(pr).sort_stats("tottime").print_stats(30)
        return
    table(args.localisation, args.steps, args.repeat, args.scenario)


if __name__ == "__main__":
    main()
