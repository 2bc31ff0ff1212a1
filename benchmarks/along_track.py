"""Where the estimate's along-track error comes from on slopes, climbing and descending.

On a pitched robot the GNSS mast leans along the track as it leans sideways on a rolled one:
robot_localization in ``two_d_mode`` removes the antenna's offset through yaw alone, so the
estimate sits ``(R − R_yaw) · lever`` (the lean) from the truth, ≈ 0.71 m · sin(pitch). What is
left after the lean is the filter's own along-track error. Climbing, the wheels slip: the
odometry's speed (wheel speed × radius) reads more than the body moves, the filter integrates
it between fixes, and its estimate leads the truth.

For each estimator this drives the cases' fields and seeds with one controller and logs every
control step: the estimate's along-track error (estimate − truth along the true heading), the
lean as the true attitude gives it (part of the estimate where the filter keeps it; "—" where
the filter removes the antenna's offset through its whole attitude, and "rest" is then the
whole error), and the odometry's speed against the body's true forward speed. Steps are split
by pitch (REP 103: pitch > 0 puts the nose down), climbing below ``−--pitch`` degrees and
descending above it. The table gives the episodes' means with 95 % bootstrap intervals (mm;
the speed ratio as a ratio).

Run ``python benchmarks/along_track.py`` (≈ 4 min on 2 cores with the defaults).
"""

from __future__ import annotations

import argparse
import math
import platform
import time
from typing import Any

import numpy as np

from common import add_drive_args, checked_drive_args, ci_cell, drive_cases

#: each estimator's config over the suite's, and whether it removes the antenna's offset
#: through yaw alone (``two_d_mode``) and so keeps the lean in its estimate
ESTIMATORS = {
    "robot_localization": ("{}", True),
    "robot_localization-3d": ('{"localisation.robot_localization.two_d_mode": false}', False),
    "ekf-oracle": ('{"localisation.kind": "ekf"}', False),
}
TRAVEL = ("climbing", "descending")


def episode(
    env: Any, policy: Any, seed: int, pitch_deg: float, planar: bool
) -> dict[str, dict[str, float]]:
    """One episode's means over its climbing and its descending steps; ``planar``: the
    estimator keeps the mast's lean (``rest`` is what is left without it), else the lean is
    not in its estimate and ``rest`` is the whole error."""
    u = env.unwrapped
    obs, _ = env.reset(seed=seed)
    policy.reset()
    lever = np.asarray(u.sensors.lever, dtype=np.float64)
    rows = []
    while True:
        obs, _, term, trunc, _ = env.step(policy.act(obs))
        s = u.state
        ex, ey, _ = u.estimator.pose
        yaw = float(s.rpy[2])
        c, sn = math.cos(yaw), math.sin(yaw)
        r_yaw = np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])
        lean = (s.rot @ lever - r_yaw @ lever)[:2]
        ahead = np.array([c, sn])
        error = np.array([ex - s.pos[0], ey - s.pos[1]])
        body_v = float(np.dot(s.vel, s.rot[:, 0]))
        odom_v = float(u.readings.odom[0])
        rows.append((error @ ahead, lean @ ahead, float(s.rpy[1]), odom_v, body_v))
        if term or trunc:
            break
    along, lean, pitch, odom_v, body_v = np.array(rows).T
    limit = math.radians(pitch_deg)
    out = {}
    for travel, mask in zip(TRAVEL, (pitch < -limit, pitch > limit), strict=True):
        if mask.sum() < 20 or body_v[mask].mean() <= 0.05:
            continue
        out[travel] = {
            "along": float(along[mask].mean()),
            "lean": float(lean[mask].mean()),
            "rest": float((along - lean if planar else along)[mask].mean()),
            "speed": float(odom_v[mask].mean() / body_v[mask].mean()),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_drive_args(
        ap, "ood", "slope 9-12 deg", "robot_localization,robot_localization-3d", ESTIMATORS
    )
    ap.add_argument("--pitch", type=float, default=3.0, help="pitch above which a step counts, deg")
    args = ap.parse_args()
    if not 0.0 <= args.pitch < 45.0:
        ap.error(f"--pitch: {args.pitch}; allowed: 0 to 45 degrees")
    chosen, rows = checked_drive_args(ap, args, ESTIMATORS)

    t0 = time.perf_counter()
    results = drive_cases(
        args.suite,
        rows,
        {name: ESTIMATORS[name][0] for name in chosen},
        args.policy,
        args.seeds,
        lambda env, pi, seed, name: episode(env, pi, seed, args.pitch, ESTIMATORS[name][1]),
    )

    print(
        f"\n{args.policy}, {args.seeds} `{args.suite}` seeds a case, steps pitched more than "
        f"{args.pitch:g}°; {platform.machine()}, {time.perf_counter() - t0:.0f} s. Means over "
        "episodes [95 % bootstrap], along-track mm (+ the estimate ahead of the truth):\n"
    )
    print(
        "| estimator | case | travel | episodes | estimate − truth | mast lean | rest "
        "| odometry / true speed |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for (est_name, row), eps in results.items():
        for travel in TRAVEL:
            got = [e[travel] for e in eps if travel in e]
            lean = ci_cell([g["lean"] for g in got]) if ESTIMATORS[est_name][1] else "—"
            print(
                f"| {est_name} | {row} | {travel} | {len(got)} | "
                f"{ci_cell([g['along'] for g in got])} | {lean} | "
                f"{ci_cell([g['rest'] for g in got])} | "
                f"{ci_cell([g['speed'] for g in got], 1.0, '.3f')} |"
            )


if __name__ == "__main__":
    main()
