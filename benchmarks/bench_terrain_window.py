"""What the physics ground's window costs per metre driven, against another revision's window.

The robot's path is the env's own route (FieldRoute-v3: both lanes and the headland turn),
walked in control steps of 0.05 m (1 m/s at 20 Hz) with the travel direction as heading; each
step calls the window's ``follow`` as ``AgriNavEnv.step`` does. Per field: refills per 100 m,
milliseconds per refill and microseconds per control step, for this checkout's
``TerrainPatch`` and the one at ``--baseline`` (``sim/world.py`` read from git), interleaved,
medians of ``--repeat`` runs. Fields: the paper's P1 (rows along an axis: the long window)
and ``unseen`` fields (rows at any angle: the square one).

    python benchmarks/bench_terrain_window.py [--baseline REV] [--repeat 5] [--fields 4]
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.sim import world as current

STEP_M = 0.05  # a control step at 1 m/s


def _baseline_module(rev: str) -> Any:
    """``agrinav_gym.sim.world`` as it was at git revision ``rev``."""
    root = Path(__file__).resolve().parents[1]
    src = subprocess.run(
        ["git", "show", f"{rev}:src/agrinav_gym/sim/world.py"],
        cwd=root,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "world_baseline.py"
        path.write_text(src)
        # a module of the same package, so its relative imports resolve
        spec = importlib.util.spec_from_file_location("agrinav_gym.sim._world_baseline", path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    return mod


def _walk(route: Any) -> tuple[np.ndarray, np.ndarray]:
    """Points every STEP_M along the route, with the travel direction at each."""
    s = np.arange(0.0, float(route.arc[-1]), STEP_M)
    x = np.interp(s, route.arc, route.xy[:, 0])
    y = np.interp(s, route.arc, route.xy[:, 1])
    h = np.arctan2(np.gradient(y), np.gradient(x))
    return np.stack([x, y], axis=1), h


def _run(cls: Any, reach: float, terrain: Any, angle: float, pts: np.ndarray, hdg: np.ndarray):
    """(refills, seconds of all follows, seconds per refill) of one walk with window ``cls``."""
    cid = p.connect(p.DIRECT)
    try:
        args: list[Any] = [cid, terrain, 0.8, angle]
        if "reach" in inspect.signature(cls.__init__).parameters:
            args.append(reach)
        w = cls(*args)
        w.follow(float(pts[0, 0]), float(pts[0, 1]), force=True)
        moves, total, each = 0, 0.0, []
        for (x, y), h in zip(pts.tolist(), hdg.tolist(), strict=True):
            t0 = time.perf_counter()
            moved = w.follow(x, y, heading=h)
            dt = time.perf_counter() - t0
            total += dt
            if moved:
                moves += 1
                each.append(dt)
        return moves, total, statistics.median(each) if each else 0.0
    finally:
        p.disconnect(cid)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", default="5eca2e3", help="git revision of the other window")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fields", type=int, default=4, help="unseen fields (rows at any angle)")
    a = ap.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {sys.version.split()[0]}")
    old = _baseline_module(a.baseline)
    cases = [("paper-p1", None)] + [("unseen", k) for k in range(a.fields)]
    rows = []
    for name, k in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if k is None:
                env = gym.make("AgriNav/FieldRoute-v3", scenario=name)
                env.reset(seed=0)
            else:
                from baselines.suites import suite

                case = suite("unseen")[0]
                env = gym.make(case.env_id, **case.env_kwargs())
                env.reset(seed=1000 + k)
        u = env.unwrapped
        terrain, angle, reach = u.scenario.terrain, u.scenario.rows.angle, u.world._reach
        pts, hdg = _walk(u.route)
        env.close()
        metres = len(pts) * STEP_M
        res: dict[str, list[tuple[int, float, float]]] = {"old": [], "new": []}
        for _ in range(a.repeat):
            res["old"].append(_run(old.TerrainPatch, reach, terrain, angle, pts, hdg))
            res["new"].append(_run(current.TerrainPatch, reach, terrain, angle, pts, hdg))
        label = name if k is None else f"unseen #{k} ({math.degrees(angle) % 180:.0f}°)"
        for which in ("old", "new"):
            r = res[which]
            moves = r[0][0]
            per_step = statistics.median(t for _, t, _ in r) / len(pts) * 1e6
            per_refill = statistics.median(e for *_, e in r) * 1e3
            rows.append((label, which, metres, 100.0 * moves / metres, per_refill, per_step))
    print(f"\nterrain window: baseline {a.baseline} vs this checkout, medians of {a.repeat}\n")
    print("| field | window | route m | refills / 100 m | ms / refill | µs / control step |")
    print("|---|---|---|---|---|---|")
    for label, which, metres, rate, ms, us in rows:
        print(f"| {label} | {which} | {metres:.0f} | {rate:.1f} | {ms:.1f} | {us:.1f} |")


if __name__ == "__main__":
    main()
