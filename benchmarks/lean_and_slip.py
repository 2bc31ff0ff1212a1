"""Where the soil's effect on precision comes from, under each estimator, on tilted ground.

The `sensitivity` suite's soil rows drive the `unseen` fields, several on side slopes. There the
robot slips downhill, and the controller tracks its estimate with a lag on the downhill side;
robot_localization in ``two_d_mode`` also puts its estimate downhill of the truth, by the GNSS
mast's lean (0.71 m · sin roll: it removes the antenna's offset through yaw alone). The two
errors point opposite ways, so a slipperier soil, with a larger lag, cancels more of the lean.

For each soil row and estimator this drives the suite's fields and seeds with one controller
and logs every control step: the true cross-track error, the estimate's cross-track error (what
the controller steers on) and the roll. On the steps rolled more than ``--tilt`` degrees each
is signed uphill-positive (REP 103: roll > 0 raises the left side; cross-track > 0 is left of
the route). The table gives the episodes' means with 95 % bootstrap intervals: the estimate's
offset (true − estimated cross-track: where the truth lies from the estimate), the estimate's
cross-track (the tracking lag) and the true cross-track (their sum), and the RMS of the true
cross-track over every step (time-weighted, headland included: not the suite's path RMSE).

Run ``python benchmarks/lean_and_slip.py`` (≈ 12 min on 2 cores with the defaults;
``--estimators robot_localization-3d`` for robot_localization with ``two_d_mode: false``;
``--suite ood --cases 'slope 9-12 deg' --policy ppo:shipped`` for another suite's cases).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from typing import Any

import numpy as np

from agrinav_gym.routes import Tracker
from baselines.suites import SENSITIVITY
from common import add_drive_args, ci_cell, drive_chosen

#: the sensitivity suite's soil rows: its default and the friction and shear-modulus ends
SOIL_ROWS = tuple(
    group
    for group, kind, values in SENSITIVITY
    if kind == "soil" and set(values) <= {"friction", "shear_modulus"}
)
#: each estimator's config over the suite's (robot_localization in two_d_mode is the suite's)
ESTIMATORS = {
    "robot_localization": "{}",
    "ekf-oracle": '{"localisation.kind": "ekf"}',
    "robot_localization-3d": '{"localisation.robot_localization.two_d_mode": false}',
}


def episode(env: Any, policy: Any, seed: int, tilt: float) -> dict[str, float]:
    """One episode's uphill-signed means over its tilted steps and its RMS true cross-track."""
    u = env.unwrapped
    obs, _ = env.reset(seed=seed)
    policy.reset()
    est = Tracker(u.route)
    est.reset(*u.estimator.pose[:2])
    true_cte, est_cte, roll = [], [], []
    while True:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        ex, ey, _ = u.estimator.pose
        true_cte.append(info["cte"])
        est_cte.append(est.update(ex, ey)[0])
        roll.append(float(u.state.rpy[0]))
        if term or trunc:
            break
    t, e, r = np.array(true_cte), np.array(est_cte), np.array(roll)
    tilted = np.abs(r) > math.radians(tilt)
    up = np.sign(r[tilted])
    out = {"tilted": float(tilted.mean()), "rms": float(np.sqrt(np.mean(t**2)))}
    if tilted.any():
        out |= {
            "offset": float(np.mean((t - e)[tilted] * up)),
            "lag": float(np.mean(e[tilted] * up)),
            "true": float(np.mean(t[tilted] * up)),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_drive_args(
        ap,
        "sensitivity",
        ";".join(SOIL_ROWS),
        "robot_localization,ekf-oracle",
        ESTIMATORS,
        " (default: the sensitivity suite's soil rows)",
    )
    ap.add_argument("--tilt", type=float, default=2.0, help="roll above which a step counts, deg")
    ap.add_argument("--json", help="also write every episode's numbers here")
    args = ap.parse_args()
    if not 0.0 <= args.tilt < 45.0:
        ap.error(f"--tilt: {args.tilt}; allowed: 0 to 45 degrees")
    t0 = time.perf_counter()
    results = drive_chosen(
        ap, args, ESTIMATORS, lambda env, pi, seed, _: episode(env, pi, seed, args.tilt)
    )

    print(
        f"\n{args.policy}, {args.seeds} `{args.suite}` seeds a row, steps rolled > {args.tilt:g}°; "
        f"{platform.machine()}, {time.perf_counter() - t0:.0f} s. Uphill-signed means, mm "
        "[95 % bootstrap over episodes]:\n"
    )
    print(
        "| estimator | case | estimate's offset | estimate's cross-track | true cross-track "
        "| RMS true, all steps |"
    )
    print("|---|---|---|---|---|---|")
    for (est_name, row), eps in results.items():
        tilted = [e for e in eps if "offset" in e]
        print(
            f"| {est_name} | {row} | {ci_cell([e['offset'] for e in tilted])} | "
            f"{ci_cell([e['lag'] for e in tilted])} | {ci_cell([e['true'] for e in tilted])} | "
            f"{ci_cell([e['rms'] for e in eps], fmt='.0f')} |"
        )
    if args.json:
        by_estimator: dict[str, dict[str, list[dict[str, float]]]] = {}
        for (est_name, row), eps in results.items():
            by_estimator.setdefault(est_name, {})[row] = eps
        with open(args.json, "w") as f:
            json.dump(by_estimator, f, indent=1)


if __name__ == "__main__":
    main()
