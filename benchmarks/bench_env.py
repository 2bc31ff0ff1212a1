"""Environment benchmarks (the env suite's performance targets), on the paper-p1 field.

1. env steps/s with gps/imu/odom/route observations (target ≥ 1,500);
2. env steps/s with 64 x 48 depth added (target ≥ 300);
3. one interleaved run (every setup once per repeat, medians over repeats): the env step over
   raw physics of the same robot in the same world making the same moves — the wheel command,
   the terrain window following the robot and the 12 substeps (tyre model + pybullet) —
   with the default estimator (EKF; target ≤ 1.3), the blend and the navigation suites'
   robot_localization (its filter in numpy and compiled); and simulated seconds per
   wall-clock second of the state-only env against pybullet's own ``RacecarGymEnv`` (target
   ≥ 3×) and of the 64 x 48 depth env against ``RacecarZEDGymEnv`` (its 100 x 10 camera),
   both run through ``pybullet_gym_shim`` (they were written for the old ``gym``);
4. marginal memory per plant (target ≤ 2 KB): RSS of an env on the same field planted at two
   densities, each in a fresh process;
5. load time of a 100,000-plant field (target ≤ 10 s): generate + build + reset;
6. reset with a new randomized scenario (target ≤ 1 s);
7. vector-env scaling: the state-only env in 1 and 2 subprocess workers, env steps/s and the
   efficiency of 2 (target: 2 workers ≥ 1.7× one), interleaved, three ways: Gymnasium's
   ``AsyncVectorEnv`` (``gymnasium.make_vec(..., vectorization_mode="async")``, one env per
   process) and ``agrinav_gym.make_vec`` (4 envs per worker process, ``--per-worker N``),
   with and without ``pin_workers``.

Medians of several runs; run with ``make bench`` or ``python benchmarks/bench_env.py``
(``--sections 3,7`` for some). Timings of steps only: resets are not timed (a racecar episode
is 1,000 of its physics steps, 10 s).
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
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

import agrinav_gym  # registers the envs
from agrinav_gym.estimation.robot_localization import RobotLocalizationEkf
from agrinav_gym.sim.quiet import quiet  # pybullet's racecar envs print from C and Python
from baselines.suites import RTK_NAV2
from common import drive, s_curve
from pybullet_gym_shim import racecar_envs, sim_seconds

STEPS = 1000
ENV_ID = "AgriNav/FurrowFollow-v3"
STATE_OBS = ("gps", "imu", "odom", "route")
#: the benchmark drive's task: long enough that no step of it ends the episode
TASK = {"task": {"max_crops_hit": 10**6, "corridor": 2.0}}


def steps_per_second(observations: tuple[str, ...], repeat: int) -> tuple[float, float]:
    env = _env(observations)
    env.reset(seed=0)
    drive(env, 100)
    rates = [STEPS / drive(env, STEPS) for _ in range(repeat)]
    env.close()
    return statistics.median(rates), min(rates)


def _env(
    observations: tuple[str, ...] = STATE_OBS, localisation: str | dict[str, Any] = "ekf"
) -> gym.Env:
    loc = {"kind": localisation} if isinstance(localisation, str) else localisation
    return gym.make(
        ENV_ID, scenario="paper-p1", observations=observations, config={**TASK, "localisation": loc}
    )


def _rl_env(compiled: bool) -> gym.Env:
    """The env with the navigation suites' estimator (robot_localization as a Nav2 user sets
    it up, ``baselines.suites.RTK_NAV2``), its filter compiled (where the kernels are built)
    or the numpy twin."""
    env = _env(localisation=RTK_NAV2["localisation"])
    u = env.unwrapped
    if not compiled:
        u.estimator = RobotLocalizationEkf(u.cfg.localisation, u.world.skid_factor, u.dt, False)
    return env


def raw_physics(env: gym.Env, seed: int, n: int, window: bool = True) -> float:
    """Seconds per step of the same moves as ``drive`` from a reset with ``seed``, physics
    only: the wheel command, the terrain window following the robot (``window``) and the
    substeps."""
    u = env.unwrapped
    env.reset(seed=seed)
    w, scale = u.world, (u.cfg.robot.v_max, u.cfg.robot.w_max)
    t = 0.0
    for i in range(n):
        v, om = (s_curve(i) * scale).tolist()
        if window:  # where the robot is, as the env's last state query says (untimed)
            pos, q = p.getBasePositionAndOrientation(w.robot, physicsClientId=w.client)
            yaw = p.getEulerFromQuaternion(q)[2]
        t0 = time.perf_counter()
        w.drive(v, om)
        if window:
            w.follow(pos[0], pos[1], yaw)
        w.step(u.substeps)
        t += time.perf_counter() - t0
    return t / n


def racecar_seconds(env: object, n: int, start: int = 0) -> float:
    """Seconds spent in ``step`` over ``n`` steps of an old-gym racecar env (S-curve throttle
    and steering; an episode's end resets, untimed)."""
    total = 0.0
    for i in range(start, start + n):
        a = s_curve(i).astype(np.float64)
        t0 = time.perf_counter()
        _, _, done, _ = env.step(a)  # type: ignore[attr-defined]
        total += time.perf_counter() - t0
        if done:
            env.reset()  # type: ignore[attr-defined]
    return total


def interleaved(repeat: int, steps: int = 400) -> dict[str, float]:
    """Section 3: every setup once per repeat, in turn (the machine's load drifts alike for
    all); medians. Seconds per env step, and simulated seconds per wall second."""
    ekf, blend, depth = _env(), _env(localisation="blend"), _env((*STATE_OBS, "depth"))
    rl_np, rl_c = _rl_env(False), _rl_env(True)
    racecar_cls, zed_cls = racecar_envs()
    with quiet():
        racecar = racecar_cls()
        racecar.reset()
        zed = zed_cls(renders=False)  # its constructor resets
    dt = ekf.unwrapped.dt
    runs: dict[str, list[float]] = {
        k: [] for k in ("ekf", "raw", "raw_nowin", "blend", "rl", "rl_c", "depth", "rc", "zed")
    }
    race_steps, zed_steps, depth_steps = 40, 4, 100
    for r in range(repeat):
        ekf.reset(seed=r)
        runs["ekf"].append(drive(ekf, steps) / steps)
        runs["raw"].append(raw_physics(ekf, r, steps))
        runs["raw_nowin"].append(raw_physics(ekf, r, steps, window=False))
        blend.reset(seed=r)  # the same physics as the EKF env's: the same raw
        runs["blend"].append(drive(blend, steps) / steps)
        for key, env in (("rl", rl_np), ("rl_c", rl_c)):
            env.reset(seed=r)
            runs[key].append(drive(env, steps) / steps)
        depth.reset(seed=r)
        runs["depth"].append(drive(depth, depth_steps) / depth_steps)
        with quiet():
            runs["rc"].append(racecar_seconds(racecar, race_steps, r * race_steps) / race_steps)
            runs["zed"].append(racecar_seconds(zed, zed_steps, r * zed_steps) / zed_steps)
    for env in (ekf, blend, rl_np, rl_c, depth):
        env.close()
    med = {k: statistics.median(v) for k, v in runs.items()}
    med["rc_sim"] = sim_seconds(racecar) / med["rc"]
    med["zed_sim"] = sim_seconds(zed) / med["zed"]
    med["ekf_sim"] = dt / med["ekf"]
    med["depth_sim"] = dt / med["depth"]
    # per-repeat ratios (the same repeat's setups ran back to back), then their median
    med["ratio"] = statistics.median(e / w for e, w in zip(runs["ekf"], runs["raw"], strict=True))
    med["ratio_nowin"] = statistics.median(
        e / w for e, w in zip(runs["ekf"], runs["raw_nowin"], strict=True)
    )
    for key in ("blend", "rl", "rl_c"):
        med[f"{key}_ratio"] = statistics.median(
            e / w for e, w in zip(runs[key], runs["raw"], strict=True)
        )
    med["rl_sim"], med["rl_c_sim"] = dt / med["rl"], dt / med["rl_c"]
    return med


def report_interleaved(m: dict[str, float], repeat: int) -> None:
    print(f"3. interleaved, median of {repeat} (FurrowFollow-v3 on paper-p1, 400 steps a run):")
    print(
        f"   env step {m['ekf'] * 1e3:.3f} ms (EKF) vs raw physics {m['raw'] * 1e3:.3f} ms: "
        f"env / raw {m['ratio']:.2f} (target ≤ 1.3; raw without the terrain window's moves "
        f"{m['raw_nowin'] * 1e3:.3f} ms: {m['ratio_nowin']:.2f})"
    )
    print(
        f"   blend estimator: env step {m['blend'] * 1e3:.3f} ms, env / raw {m['blend_ratio']:.2f}"
    )
    for key, name in (("rl", "numpy filter"), ("rl_c", "compiled filter")):
        print(
            f"   robot_localization (the suites' setup), {name}: env step "
            f"{m[key] * 1e3:.3f} ms, env / raw {m[f'{key}_ratio']:.2f} (target ≤ 1.3); "
            f"sim s per wall s {m[f'{key}_sim']:.1f}: {m[f'{key}_sim'] / m['rc_sim']:.2f}x "
            "RacecarGymEnv"
        )
    print(
        f"   sim s per wall s: state-only env {m['ekf_sim']:.1f} vs RacecarGymEnv "
        f"{m['rc_sim']:.1f} ({m['rc'] * 1e3:.1f} ms per 0.5 s step): "
        f"{m['ekf_sim'] / m['rc_sim']:.2f}x (target ≥ 3x)"
    )
    print(
        f"   sim s per wall s: 64x48 depth env {m['depth_sim']:.1f} vs RacecarZEDGymEnv "
        f"{m['zed_sim']:.2f} ({m['zed'] * 1e3:.0f} ms per 0.1 s step): "
        f"{m['depth_sim'] / m['zed_sim']:.0f}x"
    )


PER_WORKER = (
    4  # envs per worker process in the batched setup (--per-worker; agrinav train's n_envs)
)


def _vector_env(kind: str, workers: int, per_worker: int = PER_WORKER) -> gym.vector.VectorEnv:
    """``async``: Gymnasium's AsyncVectorEnv, one env per process; ``batched`` (``pinned``):
    ``agrinav_gym.make_vec``, ``per_worker`` envs per process (each worker on one core)."""
    kw: dict[str, Any] = {"scenario": "paper-p1", "observations": STATE_OBS, "config": TASK}
    if kind in ("batched", "pinned"):
        return agrinav_gym.make_vec(
            ENV_ID, per_worker * workers, workers=workers, pin_workers=kind == "pinned", **kw
        )
    return gym.make_vec(
        ENV_ID,
        num_envs=workers,
        vectorization_mode="async",
        vector_kwargs={"context": "spawn"},
        **kw,
    )


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far (Linux /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


Scaling = dict[tuple[str, int], tuple[float, list[float], float]]


def vector_scaling(repeat: int, steps: int = 300, per_worker: int = PER_WORKER) -> Scaling:
    """Section 7: per setup (async / batched / pinned) and worker count (1, 2), the median env
    steps/s of interleaved runs, each worker's median busy share of the wall time, and the main
    process's."""
    kinds = ("async", "batched", "pinned")
    envs = {(kind, n): _vector_env(kind, n, per_worker) for kind in kinds for n in (1, 2)}
    runs: dict[tuple[str, int], list[tuple[float, list[float], float]]] = {k: [] for k in envs}
    try:
        for venv in envs.values():
            venv.reset(seed=list(range(venv.num_envs)))
            _vector_drive(venv, 20)
        for _ in range(repeat):
            for key, venv in envs.items():
                pids = [proc.pid for proc in venv.unwrapped.processes]
                before = [_cpu_seconds(pid) for pid in pids]
                main0 = time.process_time()
                # the same number of env steps in every setup
                wall = _vector_drive(venv, steps * key[1] // venv.num_envs)
                busy = [(_cpu_seconds(pid) - b) / wall for pid, b in zip(pids, before, strict=True)]
                rate = venv.num_envs * (steps * key[1] // venv.num_envs) / wall
                runs[key].append((rate, busy, (time.process_time() - main0) / wall))
    finally:
        for venv in envs.values():
            venv.close()
    out = {}
    for key, rs in runs.items():
        rate = statistics.median(r[0] for r in rs)
        busy = [statistics.median(r[1][i] for r in rs) for i in range(key[1])]
        out[key] = (rate, busy, statistics.median(r[2] for r in rs))
    return out


def _vector_drive(venv: gym.vector.VectorEnv, n: int) -> float:
    """Seconds for ``n`` batched steps of the S-curve (ended episodes reset themselves)."""
    k = venv.num_envs
    t0 = time.perf_counter()
    for i in range(n):
        venv.step(np.repeat(s_curve(i)[None], k, axis=0))
    return time.perf_counter() - t0


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
env = gym.make("AgriNav/FurrowFollow-v3", scenario=scn)
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
        env = gym.make("AgriNav/FurrowFollow-v3", scenario=scn)
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
        "AgriNav/FurrowFollow-v3",
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
    ap.add_argument(
        "--per-worker", type=int, default=PER_WORKER, help="section 7: envs per make_vec worker"
    )
    ap.add_argument("--sections", default="1,2,3,4,5,6,7", help="comma list of the sections to run")
    args = ap.parse_args()
    run = {int(x) for x in args.sections.split(",") if x.strip()}
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, pybullet {p.getAPIVersion()}; median of {args.repeat}\n"
    )
    if 1 in run:
        med, low = steps_per_second(STATE_OBS, args.repeat)
        print(
            f"1. gps/imu/odom/route      : {med:7.0f} steps/s (min {low:.0f}; target ≥ 1500; "
            f"{med / 20:.0f}x real time)"
        )
    if 2 in run:
        med, low = steps_per_second((*STATE_OBS, "depth"), args.repeat)
        print(f"2. + depth 64x48           : {med:7.0f} steps/s (min {low:.0f}; target ≥ 300)")
    if 3 in run:
        report_interleaved(interleaved(args.repeat), args.repeat)
    if 4 in run:
        a, b, per, rss = memory_per_plant()
        print(
            f"4. marginal memory         : {per:7.0f} B/plant traced, {rss:.0f} B/plant RSS "
            f"({a} -> {b} plants; target ≤ 2048)"
        )
    if 5 in run:
        n, g, bld, tot = load_100k(max(1, args.repeat // 2))
        print(
            f"5. {n:,}-plant field      : generate {g:.2f} s + env build/reset {bld:.2f} s = "
            f"{tot:.2f} s (target ≤ 10 s)"
        )
    if 6 in run:
        print(f"6. randomized reset        : {randomized_reset(args.repeat):7.3f} s (target ≤ 1 s)")
    if 7 in run:
        v = vector_scaling(args.repeat, per_worker=args.per_worker)
        names = {
            "async": "AsyncVectorEnv (spawn), 1 env per worker",
            "batched": f"agrinav_gym.make_vec, {args.per_worker} envs per worker",
            "pinned": f"agrinav_gym.make_vec, {args.per_worker} envs per worker, pin_workers",
        }
        print("7. vector envs (target: 2 workers ≥ 1.7x one)")
        for kind, name in names.items():
            (one, busy1, main1), (two, busy2, main2) = v[kind, 1], v[kind, 2]
            print(
                f"   {name}: 1 worker {one:.0f} env steps/s, 2 workers {two:.0f}: "
                f"{two / one:.2f}x, efficiency {two / (2 * one):.0%}"
            )
            print(
                f"     busy share of the wall time: 1 worker {busy1[0]:.0%} (main {main1:.0%}); "
                f"2 workers {' + '.join(f'{b:.0%}' for b in busy2)} (main {main2:.0%})"
            )
        print(f"   {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
