"""Environment benchmarks (the env suite's performance targets), on the paper-p1 field.

1. env steps/s with gps/imu/odom/route observations (target ≥ 1,500);
2. env steps/s with 64 x 48 depth added (target ≥ 300);
3. env step cost / raw physics cost of the same robot making the same moves, in one run
   (target ≤ 1.5), and, for reference, / the robot alone on a plane;
4. marginal memory per plant (target ≤ 2 KB): RSS of an env on the same field planted at two
   densities, each in a fresh process;
5. load time of a 100,000-plant field (target ≤ 10 s): generate + build + reset;
6. reset with a new randomized scenario (target ≤ 1 s).

Medians of several runs; run with ``make bench`` or ``python benchmarks/bench_env.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np
import pybullet as p

import agrinav_gym  # noqa: F401  (registers the envs)
from common import drive, s_curve

STEPS = 1000


def steps_per_second(observations: tuple[str, ...], repeat: int) -> tuple[float, float]:
    env = gym.make(
        "AgriNav/FurrowFollow-v2",
        scenario="paper-p1",
        observations=observations,
        config={"task": {"max_crops_hit": 10**6, "corridor": 2.0}},
    )
    env.reset(seed=0)
    drive(env, 100)
    rates = [STEPS / drive(env, STEPS) for _ in range(repeat)]
    env.close()
    return statistics.median(rates), min(rates)


def step_cost_ratio(repeat: int) -> tuple[float, float, float]:
    """(env step, raw substeps in the same world, robot alone on a plane), seconds per step."""
    env = gym.make(
        "AgriNav/FurrowFollow-v2",
        scenario="paper-p1",
        observations=("gps", "imu", "odom", "route"),
        config={"task": {"max_crops_hit": 10**6, "corridor": 2.0}},
    )
    u = env.unwrapped
    env_t, raw_t = [], []
    for r in range(repeat):
        env.reset(seed=r)
        env_t.append(drive(env, 400) / 400)
        env.reset(seed=r)  # the same moves again, physics only: drive + substeps
        t = 0.0
        for i in range(400):
            v, w = (s_curve(i) * (u.cfg.robot.v_max, u.cfg.robot.w_max)).tolist()
            t0 = time.perf_counter()
            u.world.drive(v, w)
            u.world.step(u.substeps)
            t += time.perf_counter() - t0
        raw_t.append(t / 400)
    env.close()
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    p.setPhysicsEngineParameter(
        fixedTimeStep=1 / 240, numSolverIterations=10, enableConeFriction=0, physicsClientId=cid
    )
    p.createMultiBody(
        0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid
    )
    from agrinav_gym.robot import urdf_path

    rob = p.loadURDF(
        urdf_path(), [0, 0, 0.115], flags=p.URDF_MERGE_FIXED_LINKS, physicsClientId=cid
    )
    p.setJointMotorControlArray(
        rob,
        [0, 1, 2, 3],
        p.VELOCITY_CONTROL,
        targetVelocities=[5.0] * 4,
        forces=[80.0] * 4,
        physicsClientId=cid,
    )
    t0 = time.perf_counter()
    for _ in range(400 * 12):
        p.stepSimulation(physicsClientId=cid)
    plane = (time.perf_counter() - t0) / 400
    p.disconnect(cid)
    return statistics.median(env_t), statistics.median(raw_t), plane


MEMORY_CHILD = r"""
import json, sys, tracemalloc, gymnasium as gym, agrinav_gym, scenario_gen as sg
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096
spacing = float(sys.argv[1])
# jitter within a sixth of the spacing: plants keep their positions (generate.check_spec)
lay = {"plant_spacing": spacing, "jitter_longitudinal": min(0.02, spacing / 6)}
scn = sg.generate(sg.preset("paper-p1", layout=lay), 0)
_ = scn.terrain.tree
before = rss()
tracemalloc.start()
env = gym.make("AgriNav/FurrowFollow-v2", scenario=scn)
env.reset(seed=0)
for _ in range(50):
    env.step(env.action_space.sample() * 0)
traced, _ = tracemalloc.get_traced_memory()
print(json.dumps({"plants": len(scn.plants), "env_bytes": rss() - before, "traced": traced}))
"""


def memory_per_plant() -> tuple[int, int, float, float]:
    """(plants a, plants b, traced bytes per plant, RSS bytes per plant) between two densities.

    The traced figure counts every Python/numpy allocation the env holds (plant proxies,
    KD-trees); RSS adds pybullet's, but the allocator's reuse of freed pages makes it noisy.
    """
    out = []
    for spacing in (1.0, 0.05):
        res = subprocess.run(
            [sys.executable, "-c", MEMORY_CHILD, str(spacing)],
            capture_output=True,
            text=True,
            check=True,
        )
        out.append(json.loads(res.stdout.strip().splitlines()[-1]))
    a, b = out
    n = b["plants"] - a["plants"]
    return (
        a["plants"],
        b["plants"],
        (b["traced"] - a["traced"]) / n,
        (b["env_bytes"] - a["env_bytes"]) / n,
    )


def load_100k(repeat: int) -> tuple[int, float, float, float]:
    import scenario_gen as sg

    # a 1.4 ha maize field at 0.75 x 0.18 m: ≈100,000 plants
    spec = sg.preset("default", field={"width": 110.0, "length": 131.0})
    gen, build = [], []
    n = 0
    for r in range(repeat):
        t0 = time.perf_counter()
        scn = sg.generate(spec, r)
        t1 = time.perf_counter()
        env = gym.make("AgriNav/FurrowFollow-v2", scenario=scn)
        env.reset(seed=0)
        env.step(np.zeros(2, np.float32))
        t2 = time.perf_counter()
        env.close()
        n = len(scn.plants)
        gen.append(t1 - t0)
        build.append(t2 - t1)
    g, b = statistics.median(gen), statistics.median(build)
    return n, g, b, g + b


def randomized_reset(repeat: int) -> float:
    env = gym.make(
        "AgriNav/FurrowFollow-v2",
        scenario="paper-p1",
        randomize={
            "crop.stage": [1, 5],
            "layout.plant_spacing": [0.8, 1.2],
            "layout.jitter_lateral": [0.0, 0.03],
            "layout.row_angle_deg": [-20.0, 20.0],
            "terrain.site": {"choices": ["flattest", "steepest"]},
            "gnss.mode": {"choices": ["rtk_fixed", "rtk_float"]},
            "lighting.soil_rgb": [[0.3, 0.2, 0.1], [0.6, 0.45, 0.3]],
        },
    )
    env.reset(seed=0)
    times = []
    for r in range(repeat):
        t0 = time.perf_counter()
        env.reset(seed=100 + r)
        times.append(time.perf_counter() - t0)
    env.close()
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, pybullet {p.getAPIVersion()}; median of {args.repeat}\n"
    )
    med, low = steps_per_second(("gps", "imu", "odom", "route"), args.repeat)
    print(
        f"1. gps/imu/odom/route      : {med:7.0f} steps/s (min {low:.0f}; target ≥ 1500; "
        f"{med / 20:.0f}x real time)"
    )
    med, low = steps_per_second(("gps", "imu", "odom", "route", "depth"), args.repeat)
    print(f"2. + depth 64x48           : {med:7.0f} steps/s (min {low:.0f}; target ≥ 300)")
    env_s, raw_s, plane_s = step_cost_ratio(args.repeat)
    print(
        f"3. env step {env_s * 1e3:.3f} ms vs raw 12 substeps {raw_s * 1e3:.3f} ms in the same "
        f"world: ratio {env_s / raw_s:.2f} (target ≤ 1.5); robot alone on a plane "
        f"{plane_s * 1e3:.3f} ms: ratio {env_s / plane_s:.2f}"
    )
    a, b, per, rss = memory_per_plant()
    print(
        f"4. marginal memory         : {per:7.0f} B/plant traced, {rss:.0f} B/plant RSS "
        f"({a} -> {b} plants; target ≤ 2048)"
    )
    n, g, bld, tot = load_100k(max(1, args.repeat // 2))
    print(
        f"5. {n:,}-plant field      : generate {g:.2f} s + env build/reset {bld:.2f} s = "
        f"{tot:.2f} s (target ≤ 10 s)"
    )
    print(f"6. randomized reset        : {randomized_reset(args.repeat):7.3f} s (target ≤ 1 s)")


if __name__ == "__main__":
    main()
