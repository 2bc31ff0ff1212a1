"""Resident memory per env reset, and where it goes.

Each line resets an env (or one part of it) ``--resets`` times after a warm-up and reports the
growth of the process's resident set per reset, measured twice: as the OS sees it, and after
glibc's ``malloc_trim(0)`` has returned the free heap it keeps (what a long run would get back
under memory pressure). Lines:

* ``env, new field each reset``: FurrowFollowDepth with ``randomize`` (a new field every reset);
* ``env, one field``: the same field every reset, proxy and mesh camera;
* ``pybullet: URDF reload`` / ``pybullet: resetSimulation + URDF``: what the world does per
  reset (a fresh robot body, so no contact cache carries over from the previous episode) and
  per new field, in a bare pybullet client.

Run: ``python benchmarks/bench_reset_memory.py --resets 300``.
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import platform
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parent.parent / "tests"))  # after the packages

import gymnasium as gym
import pybullet as p

import agrinav_gym  # noqa: F401
from agrinav_gym.robot import urdf_path
from fields import TINY

LIBC = ctypes.CDLL("libc.so.6")


def rss_kb(trim: bool) -> int:
    if trim:
        LIBC.malloc_trim(0)
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS")


def growth(op: Callable[[int], None], n: int, warm: int = 50) -> tuple[float, float]:
    for i in range(warm):
        op(i)
    gc.collect()
    raw0, trim0 = rss_kb(False), rss_kb(True)
    for i in range(warm, warm + n):
        op(i)
    gc.collect()
    raw1 = rss_kb(False)
    trim1 = rss_kb(True)
    return (raw1 - raw0) / n, (trim1 - trim0) / n


def env_op(model: str, randomize: bool) -> Callable[[int], None]:
    kw = {"randomize": {"crop.stage": [1, 5]}} if randomize else {}
    env = gym.make(
        "AgriNav/FurrowFollowDepth-v3",
        scenario_overrides=TINY,
        config={"camera": {"model": model, "width": 64, "height": 48}},
        **kw,
    )

    def op(i: int) -> None:
        env.reset(seed=i)
        env.step(env.action_space.sample())

    return op


def pybullet_op(reset_simulation: bool) -> Callable[[int], None]:
    cid = p.connect(p.DIRECT)
    state = {"robot": -1}

    def op(i: int) -> None:
        if reset_simulation:
            p.resetSimulation(physicsClientId=cid)
        elif state["robot"] >= 0:
            p.removeBody(state["robot"], physicsClientId=cid)
        state["robot"] = p.loadURDF(
            urdf_path(),
            [0, 0, 1],
            [0, 0, 0, 1],
            flags=p.URDF_MERGE_FIXED_LINKS,
            physicsClientId=cid,
        )

    return op


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--resets", type=int, default=300)
    ap.add_argument("--only", default="", help="run the lines whose name contains this")
    n = ap.parse_args().resets
    print(f"# {platform.machine()}, {platform.python_version()}, {n} resets per line")
    print("| what | raw kB/reset | after malloc_trim kB/reset |")
    print("|---|---|---|")
    lines = [
        ("env, new field each reset (proxy camera)", env_op("proxy", True)),
        ("env, one field (proxy camera)", env_op("proxy", False)),
        ("env, one field (mesh camera)", env_op("mesh", False)),
        ("pybullet: URDF reload (removeBody + loadURDF)", pybullet_op(False)),
        ("pybullet: resetSimulation + loadURDF", pybullet_op(True)),
    ]
    only = ap.parse_args().only
    for name, op in lines:
        if only and only not in name:
            continue
        raw, trimmed = growth(op, n)
        print(f"| {name} | {raw:.1f} | {trimmed:.1f} |", flush=True)


if __name__ == "__main__":
    main()
