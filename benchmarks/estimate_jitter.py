"""What of an estimator's pose error reaches a controller: its level, its jitter, the slip.

A controller that steers on the heading error (Stanley: ``k_heading · heading error`` plus
``atan(k · e / v)``) feels the estimate's yaw error directly, and every step-to-step jump of
the estimate as a jump of its command. For each estimator this drives a suite's cases with one
controller and logs every control step: the estimate's error across the route (estimated −
true cross-track) and in yaw, the true crab angle (the body velocity's direction: the tread's
sideways slip), and the commanded yaw rate. Per episode it reports the RMS of each error (its
level) and of its change from one step to the next (its jitter), the RMS crab angle and the
yaw error's least-squares share of it, the RMS change of the command, and how the episode
ended (finished, or the termination and the route fraction where it came).

Run ``python benchmarks/estimate_jitter.py --suite ood --cases 'contour rows, slope 4-8 deg'
--policy stanley:tuned`` (≈ 3 min on 2 cores for 8 seeds and two estimators);
``--estimators ekf-oracle-no-heading-bias`` drives the oracle without its state for the IMU's
heading error (docs/benchmark.md, "Why tuned Stanley finishes more runs under
robot_localization").
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from collections import Counter
from typing import Any

import numpy as np

from agrinav_gym.routes import Tracker
from common import add_drive_args, ci_cell, drive_chosen

ESTIMATORS = {
    "robot_localization": "{}",
    "ekf-oracle": '{"localisation.kind": "ekf"}',
    "robot_localization-3d": '{"localisation.robot_localization.two_d_mode": false}',
    # the oracle without its IMU heading-error state: the IMU's yaw fused as robot_localization
    # fuses it (the IMU itself keeps its 1° heading error)
    "ekf-oracle-no-heading-bias": (
        '{"localisation.kind": "ekf", "localisation.heading_bias_deg": 0}'
    ),
}


#: m/s: below it the body's velocity direction (the crab angle) is noise
CRAB_MIN_SPEED = 0.2


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def episode(env: Any, policy: Any, seed: int) -> dict[str, Any]:
    """One episode's error levels, jitters, command jitter and ending."""
    u = env.unwrapped
    obs, _ = env.reset(seed=seed)
    policy.reset()
    est = Tracker(u.route)
    est.reset(*u.estimator.pose[:2])
    lateral, yaw, omega, crab = [], [], [], []
    info: dict[str, Any] = {}
    while True:
        action = policy.act(obs)
        obs, _, term, trunc, info = env.step(action)
        ex, ey, eyaw = u.estimator.pose
        lateral.append(est.update(ex, ey)[0] - info["cte"])
        yaw.append(float(eyaw) - float(u.state.rpy[2]))
        omega.append(float(action[1]))
        vb = u.state.rot.T @ u.state.vel
        crab.append(math.atan2(vb[1], vb[0]) if math.hypot(vb[0], vb[1]) > CRAB_MIN_SPEED else 0.0)
        if term or trunc:
            break
    lat, yw, om, cb = np.array(lateral), _wrap(np.array(yaw)), np.array(omega), np.array(crab)
    return {
        "lateral": _rms(lat),
        "lateral_jitter": _rms(np.diff(lat)),
        "yaw": _rms(yw),
        "yaw_jitter": _rms(_wrap(np.diff(yw))),
        "command_jitter": _rms(np.diff(om)),
        "crab": _rms(cb),
        # least squares through the origin: how much of the true crab angle the yaw error carries
        "yaw_per_crab": float(yw @ cb / (cb @ cb)) if cb @ cb > 0 else float("nan"),
        "finished": bool(info.get("is_success")),
        "ending": str(info.get("termination", "truncated" if trunc else "finished")),
        "progress": float(info["progress"]),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_drive_args(
        ap, "ood", "contour rows, slope 4-8 deg", "robot_localization,ekf-oracle", ESTIMATORS
    )
    ap.add_argument("--json", help="also write every episode's numbers here")
    args = ap.parse_args()
    t0 = time.perf_counter()
    results = drive_chosen(ap, args, ESTIMATORS, lambda env, pi, seed, _: episode(env, pi, seed))
    print(
        f"\n{args.policy}, {args.seeds} `{args.suite}` seeds a case; {platform.machine()}, "
        f"{time.perf_counter() - t0:.0f} s. Means over episodes [95 % bootstrap]: RMS over each "
        "episode's control steps; jitter = RMS of the change from one step to the next; the "
        "command is the normalised yaw rate (×1000):\n"
    )
    print(
        "| estimator | case | finished | lateral error, mm | its jitter, mm | yaw error, mrad "
        "| its jitter, mrad | true crab angle, mrad | yaw error per crab angle "
        "| command jitter (×1000) | endings (route fraction) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for (name, row), eps in results.items():
        done = sum(e["finished"] for e in eps)
        ends = Counter(e["ending"] for e in eps if not e["finished"])
        where = ", ".join(
            f"{k} ×{n} ({np.median([e['progress'] for e in eps if e['ending'] == k]):.2f})"
            for k, n in ends.most_common()
        )
        print(
            f"| {name} | {row} | {done}/{len(eps)} | "
            + " | ".join(
                ci_cell([e[k] for e in eps], fmt=".1f")
                for k in ("lateral", "lateral_jitter", "yaw", "yaw_jitter", "crab")
            )
            + f" | {ci_cell([e['yaw_per_crab'] for e in eps], scale=1.0, fmt='+.2f')} | "
            + ci_cell([e["command_jitter"] for e in eps], fmt=".1f")
            + f" | {where or '—'} |"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({f"{n} | {r}": eps for (n, r), eps in results.items()}, f, indent=1)


if __name__ == "__main__":
    main()
