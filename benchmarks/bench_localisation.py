"""Localisation benchmark: the oracle EKF against robot_localization as a Nav2 user runs it.

On the same drives — one lane of the default field made 100 m long, regulated pure pursuit
steering on the true pose, so that no estimate changes where the robot goes — every estimator
reads the same sensor readings. For each GNSS condition and estimator: the position error RMS,
its component across the true heading (what row following feels), and the normalised
estimation error squared of (x, y, yaw), NEES = eᵀP⁻¹e, against its expectation 3 for a
consistent filter: its mean over the drive and the share of steps inside the two-sided 95 %
χ²(3) bounds (95 % when consistent).

Conditions: a receiver held in RTK fixed, float or standalone (constant fix model); R1 maize
(2.5 m) over the antenna with the canopy fix model; V14 (1.8 m, the sky just supports fixed)
and R1 with the receiver's faults under canopy switched on (``FAULTS``: multipath jumps,
wrong fixes, slips every 20 s × q_carrier and a re-fix that slows with the sky).
Estimators: ``ekf-oracle`` (the default ``ekf``: the simulator's own error models),
``robot_localization`` with its defaults (no lever arm, late fixes as current, no
rejection), and robot_localization tuned as a careful user would (base_link -> gps transform,
``smooth_lagged_data`` with 1 s of history, GPS rejection at 5σ).
Run ``python benchmarks/bench_localisation.py [--seeds N]``.
"""

from __future__ import annotations

import argparse
import math
import statistics
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from scipy.stats import chi2
from tqdm import tqdm

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.config import LocalisationConfig, RobotLocalizationConfig
from agrinav_gym.estimation import make_estimator
from agrinav_gym.interface import GNSS_RTK_FIXED, GNSS_RTK_FLOAT, GNSS_STANDALONE
from agrinav_gym.scenarios import FixedFieldWarning

CONST = {"model": "constant"}
#: the faults under canopy, with slips and re-fixes frequent enough to show in a lane's drive
FAULTS = {
    "jump_rate_hz": 0.2,
    "false_fix_prob": 0.3,
    "multipath_mtbf_s": 20.0,
    "refix_sky_exponent": 2.0,
}
CASES: tuple[tuple[str, dict[str, Any], int], ...] = (
    ("RTK fixed", {"mode": GNSS_RTK_FIXED, "fix": CONST}, 1),
    ("RTK float", {"mode": GNSS_RTK_FLOAT, "fix": CONST}, 1),
    ("standalone", {"mode": GNSS_STANDALONE, "fix": CONST}, 1),
    ("R1 canopy", {"mode": GNSS_RTK_FIXED}, 5),
    ("V14 canopy, faults", {"mode": GNSS_RTK_FIXED, "fix": FAULTS}, 4),
    ("R1 canopy, faults", {"mode": GNSS_RTK_FIXED, "fix": FAULTS}, 5),
)
ESTIMATORS: tuple[tuple[str, str, RobotLocalizationConfig | None], ...] = (
    ("ekf-oracle", "ekf-oracle", None),
    ("r_l defaults", "robot_localization", RobotLocalizationConfig()),
    (
        "r_l tuned",
        "robot_localization",
        RobotLocalizationConfig(
            gps_lever_arm=True,
            smooth_lagged_data=True,
            history_length_s=1.0,
            gps_rejection_threshold=5.0,
        ),
    ),
)
SETTLE = 40  # steps (2 s) before scoring: the start
LENGTH = 100.0  # m: the default field, longer, so that a lane takes about two minutes


def run(seeds: int) -> tuple[dict[tuple[str, str], list[dict[str, float]]], dict[str, str]]:
    from policies import make_policy

    out: dict[tuple[str, str], list[dict[str, float]]] = {}
    seen: dict[str, dict[str, float]] = {}
    lo, hi = chi2.ppf([0.025, 0.975], 3)
    with tqdm(total=len(CASES) * seeds, desc="episodes", unit="ep", leave=False) as bar:
        for case, gnss, stage in CASES:
            env = gym.make(
                "AgriNav/FurrowFollow-v3",
                scenario_overrides={"crop": {"stage": stage}, "field": {"length": LENGTH}},
                observations=["gps", "imu", "odom", "route"],
                config={
                    "gnss": gnss,
                    "localisation": {"kind": "ideal"},
                    "task": {"corridor": 3.0, "max_crops_hit": 10**6},
                },
            )
            u = env.unwrapped
            pi = make_policy("rpp", env)
            for seed in range(seeds):
                obs, _ = env.reset(seed=seed)
                pi.reset()
                ests = {}
                for name, kind, rl in ESTIMATORS:
                    loc = u.cfg.localisation
                    if rl is not None:
                        loc = LocalisationConfig(kind=kind, robot_localization=rl)
                    ests[name] = make_estimator(kind, loc, u.world.skid_factor, u.dt)
                rng = np.random.default_rng(seed)
                rows: dict[str, list[tuple[float, float, float]]] = {k: [] for k in ests}
                for e in ests.values():
                    e.reset(*u.start, rng)
                    e.update(u.readings, u.dt)
                k = 0
                while True:
                    obs, _, term, trunc, _ = env.step(pi.act(obs))
                    k += 1
                    x, y, yaw = float(u.state.pos[0]), float(u.state.pos[1]), float(u.state.rpy[2])
                    for name, e in ests.items():
                        e.update(u.readings, u.dt)
                        if k < SETTLE:
                            continue
                        ex, ey, eyaw = e.pose
                        err = np.array([ex - x, ey - y, math.remainder(eyaw - yaw, math.tau)])
                        nees = float(err @ np.linalg.solve(e.covariance, err))
                        across = -math.sin(yaw) * err[0] + math.cos(yaw) * err[1]
                        rows[name].append((math.hypot(err[0], err[1]), across, nees))
                    m = seen.setdefault(case, {})
                    m[u.readings.gnss_mode] = m.get(u.readings.gnss_mode, 0) + 1
                    if term or trunc:
                        break
                faults = u.sensors.gnss.faults
                if faults is not None:
                    for kind, n in faults.started.items():
                        m[kind] = m.get(kind, 0) + n
                for name, r in rows.items():
                    a = np.asarray(r)
                    out.setdefault((case, name), []).append(
                        {
                            "rms": float(np.sqrt(np.mean(a[:, 0] ** 2))),
                            "across": float(np.sqrt(np.mean(a[:, 1] ** 2))),
                            "nees": float(np.mean(a[:, 2])),
                            "inside": float(np.mean((a[:, 2] > lo) & (a[:, 2] < hi))),
                        }
                    )
                bar.update()
            env.close()
    modes = {}
    for case, m in seen.items():
        steps = sum(v for k, v in m.items() if k not in ("jump", "false_fix"))
        share = ", ".join(
            f"{k} {v / steps:.0%}" for k, v in sorted(m.items()) if k not in ("jump", "false_fix")
        )
        names = {"jump": "multipath jumps", "false_fix": "false fixes"}
        extra = [f"{m[k]} {label}" for k, label in names.items() if k in m]
        modes[case] = share + (f"; {', '.join(extra)} in all" if extra else "")
    return out, modes


def report(
    out: dict[tuple[str, str], list[dict[str, float]]], modes: dict[str, str], seeds: int
) -> None:
    print(f"\nfix modes seen ({seeds} episodes per condition)")
    for case, text in modes.items():
        print(f"   {case:20}: {text}")
    print(f"\nposition error and NEES of (x, y, yaw), median of {seeds} seeds per cell")
    print(
        "| GNSS | estimator | position RMS | across-track RMS | mean NEES (3 = consistent) "
        "| steps in 95 % χ² bounds |"
    )
    print("|---|---|---|---|---|---|")
    for case, *_ in CASES:
        for name, *_ in ESTIMATORS:
            cell = out[(case, name)]

            def med(key: str, cell: list[dict[str, float]] = cell) -> float:
                return statistics.median(c[key] for c in cell)

            print(
                f"| {case} | {name} | {med('rms'):.3f} m | {med('across'):.3f} m "
                f"| {med('nees'):.3g} | {med('inside'):.0%} |"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="episodes per condition")
    args = ap.parse_args()
    warnings.simplefilter("ignore", FixedFieldWarning)  # one field on purpose: same drives
    out, modes = run(args.seeds)
    report(out, modes, args.seeds)


if __name__ == "__main__":
    main()
