"""DWB per-step cost, before and after the Nav2-faithful rewrite, side by side in one run.

Records the observations of one FieldRoute episode (lanes and a headland U-turn, depth on),
then times ``act()`` of each controller over the same observation sequence: the legacy DWB
(loaded from git, ``--legacy-rev``), ``dwb:nav2`` and ``dwb:furrow``, plus the env step that
produced the observations, for scale. Medians of ``--repeat`` passes; ratios are taken within
the run (machines here vary ≈ 2× from day to day).

    python benchmarks/bench_dwb.py [--steps 600] [--repeat 3] [--legacy-rev 8e8bbcc]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401  (registers the envs)
from policies import make_policy

ROOT = Path(__file__).resolve().parents[1]
OBS = ["gps", "imu", "odom", "route", "depth"]


def legacy_dwb(rev: str, env: Any, tmp: Path) -> Any | None:
    """The DWB module of git revision ``rev`` (policies/dwb.py), built for ``env``."""
    try:
        code = subprocess.check_output(
            ["git", "show", f"{rev}:src/policies/dwb.py"], cwd=ROOT, stderr=subprocess.DEVNULL
        ).decode()
        yaml = subprocess.check_output(
            ["git", "show", f"{rev}:src/policies/config/dwb_furrow.yaml"], cwd=ROOT
        ).decode()
    except (subprocess.CalledProcessError, FileNotFoundError):
        return None
    mod = types.ModuleType("policies._legacy_dwb")
    mod.__package__ = "policies"
    sys.modules[mod.__name__] = mod
    exec(compile(code, f"{rev}:src/policies/dwb.py", "exec"), mod.__dict__)
    cfg = tmp / "legacy_dwb.yaml"
    cfg.write_text(yaml)
    u = env.unwrapped
    return mod.DWB(u.observation_space, u.action_space, u.interface, params=cfg)


def record(steps: int) -> tuple[list[dict[str, np.ndarray]], float]:
    """Observations of one episode driven by dwb:furrow, and the median env step (ms)."""
    env = gym.make("AgriNav/FieldRoute-v3", observations=OBS)
    pi = make_policy("dwb:furrow", env)
    obs, _ = env.reset(seed=1_000_000_000)
    pi.reset()
    seq, dts = [], []
    for _ in range(steps):
        seq.append(obs)
        a = pi.act(obs)
        t0 = time.perf_counter()
        obs, _, term, trunc, _ = env.step(a)
        dts.append(time.perf_counter() - t0)
        if term or trunc:
            break
    env.close()
    return seq, 1e3 * statistics.median(dts)


def per_step(pi: Any, seq: list[dict[str, np.ndarray]], repeat: int) -> float:
    runs = []
    for _ in range(repeat):
        pi.reset()
        t = []
        for obs in seq:
            t0 = time.perf_counter()
            pi.act(obs)
            t.append(time.perf_counter() - t0)
        runs.append(statistics.median(t))
    return 1e3 * statistics.median(runs)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--legacy-rev", default="8e8bbcc")
    args = ap.parse_args()
    seq, env_ms = record(args.steps)
    env = gym.make("AgriNav/FieldRoute-v3", observations=OBS)
    rows: list[tuple[str, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        legacy = legacy_dwb(args.legacy_rev, env, Path(tmp))
        if legacy is not None:
            rows.append((f"legacy dwb ({args.legacy_rev})", per_step(legacy, seq, args.repeat)))
        for spec in ("dwb:nav2", "dwb:furrow"):
            rows.append((spec, per_step(make_policy(spec, env), seq, args.repeat)))
    env.close()
    print(f"machine: {platform.processor() or platform.machine()}, {platform.python_version()}")
    print(f"{len(seq)} FieldRoute steps (seed 1e9), median of {args.repeat} passes")
    print(f"{'controller':28s} ms/step   × env step ({env_ms:.2f} ms)")
    for name, ms in rows:
        print(f"{name:28s} {ms:7.2f}   {ms / env_ms:5.2f}")
    if legacy is not None:
        for name, ms in rows[1:]:
            print(f"{name} / legacy: {ms / rows[0][1]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
