"""Drive physics and localisation benchmarks, side by side in one run.

"legacy" is the drive before the tyre model — pybullet's own sphere-wheel contact with friction
1.0 and the old fixed track multiplier 3 — rebuilt here from the same URDF and world.

1. yaw-rate tracking, commanded vs achieved (steady mean and std), flat and furrowed ground;
2. wheel-odometry yaw rate / true yaw rate (the skid-steer's χ);
3. climbing: distance gained up a slope in 6 s at 0.5 m/s, μ 0.6 and 1.0, vs the derived limit;
4. accelerometer std on flat ground driving straight, over the MTi-300 noise;
5. env step cost (FurrowFollow on paper-p1) legacy vs tyre model, blend vs EKF, over raw
   physics of the same moves;
6. estimate position error RMS (EKF and blend) in RTK fixed / float / standalone and under
   mature maize with the canopy fix model, regulated pure pursuit driving one lane;
7. the fix mode the canopy supports by crop stage and foliage loss (the model's sensitivity).

Figures (docs/img): yaw-rate step response legacy vs tyre model; estimate error by fix mode.
Medians of ``--repeat`` runs where timing is involved. Run ``python benchmarks/bench_physics.py``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p
from tqdm import tqdm

import agrinav_gym  # noqa: F401  (registers the envs)
import scenario_gen as sg
from agrinav_gym.config import GnssFixConfig, RobotConfig, SoilConfig
from agrinav_gym.sensors.fixmode import LEVELS, Canopy, FixModeChain, SkyModel
from agrinav_gym.sim.world import World
from common import drive, s_curve
from scenario_gen import Terrain

IMG = Path(__file__).resolve().parents[1] / "docs" / "img"
COMMANDS = ((0.0, 0.5), (0.5, 0.5), (1.0, 0.2), (0.0, 1.5))


class LegacyWorld(World):
    """The drive before the tyre model: pybullet wheel contact, friction 1, track × 3."""

    def __init__(self, robot: RobotConfig, soil: SoilConfig | None = None, gui: bool = False):
        super().__init__(robot, soil, gui)
        self.skid_factor = 3.0

    def _spawn_robot(self, pos: list[float], quat: Any) -> None:
        super()._spawn_robot(pos, quat)
        for j in self.wheels:
            p.setCollisionFilterGroupMask(self.robot, j, 1, -1, physicsClientId=self.client)
            p.changeDynamics(self.robot, j, lateralFriction=1.0, physicsClientId=self.client)
        if hasattr(self, "patch"):
            p.changeDynamics(self.patch.body, -1, lateralFriction=1.0, physicsClientId=self.client)

    def step(self, substeps: int) -> None:
        for _ in range(substeps):
            p.stepSimulation(physicsClientId=self.client)


def legacy_env(env: gym.Env) -> None:
    """Swap an env's world to the legacy drive (before its first reset)."""
    w = env.unwrapped.world
    w.__class__ = LegacyWorld
    w.skid_factor = 3.0


def plane(slope_deg: float = 0.0) -> Terrain:
    n, sp = 301, 0.1
    x = -15.0 + sp * np.arange(n)
    return Terrain(np.tile(x * math.tan(math.radians(slope_deg)), (n, 1)), -15.0, -15.0, sp)


def furrowed() -> tuple[Terrain, tuple[float, float, float]]:
    """The ridged preset's terrain (DEM window, 0.12 m ridges, roughness) and a pose in the
    middle of its first lane, along the rows."""
    scn = sg.generate(sg.preset("ridged"), 0)
    lane = np.flatnonzero(np.asarray(scn.route.segment) == "furrow")
    x, y = scn.route.xy[lane[len(lane) // 4]]
    return scn.terrain, (float(x), float(y), float(scn.rows.angle))


def run_world(
    cls: type[World],
    terrain: Terrain,
    v: float,
    w: float,
    seconds: float,
    soil: SoilConfig | None = None,
    at: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> dict[str, np.ndarray]:
    world = cls(RobotConfig(), soil)
    try:
        world.load(terrain)
        world.place_robot(*at, terrain)
        world.drive(0.0, 0.0)
        world.step(world.cfg.physics_hz)
        sub = world.cfg.physics_hz // world.cfg.control_hz
        rate, odom, pos = [], [], [world.state().pos.copy()]
        for _ in range(round(seconds * world.cfg.control_hz)):
            world.drive(v, w)
            world.step(sub)
            s = world.state()
            rate.append(float(s.ang[2]))
            wl, wr = 0.5 * (s.wheels[0] + s.wheels[2]), 0.5 * (s.wheels[1] + s.wheels[3])
            odom.append((wr - wl) * world.geometry.wheel_radius / world.geometry.track)
            pos.append(s.pos.copy())
    finally:
        world.close()
    return {"rate": np.asarray(rate), "odom": np.asarray(odom), "pos": np.asarray(pos)}


def yaw_tracking() -> dict[str, Any]:
    print("\n1-2. yaw-rate tracking and odometry ω ratio (steady state after 2 s of 6 s)")
    grounds = {"flat": (plane(), (0.0, 0.0, 0.0)), "furrowed": furrowed()}
    out: dict[str, Any] = {}
    print(
        f"{'':9}{'ground':9}{'v, ω cmd':>11} {'ω true':>8} {'ratio':>6} {'std/mean':>9}"
        f" {'odom/true':>10}"
    )
    for name, cls in (("legacy", LegacyWorld), ("tyres", World)):
        for gname, (terrain, at) in grounds.items():
            for v, w in COMMANDS:
                r = run_world(cls, terrain, v, w, 6.0, at=at)
                ss, od = r["rate"][40:], r["odom"][40:]
                out[(name, gname, v, w)] = (ss.mean(), ss.std(), od.mean() / ss.mean())
                print(
                    f"{name:9}{gname:9}{v:5.1f},{w:5.2f} {ss.mean():8.3f} {ss.mean() / w:6.2f}"
                    f" {ss.std() / max(abs(ss.mean()), 1e-9):9.1%}"
                    f" {od.mean() / max(abs(ss.mean()), 1e-9):10.2f}"
                )
    return out


def step_response_figure() -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.4), dpi=110)
    for k, (v, w) in enumerate(((0.0, 0.5), (0.5, 0.5))):
        ax = fig.add_subplot(1, 2, k + 1)
        flat = (plane(), (0.0, 0.0, 0.0))
        for name, cls, (ground, at), style in (
            ("legacy, flat", LegacyWorld, flat, "C3-"),
            ("legacy, furrowed", LegacyWorld, furrowed(), "C3:"),
            ("tyre model, flat", World, flat, "C0-"),
            ("tyre model, furrowed", World, furrowed(), "C0:"),
        ):
            r = run_world(cls, ground, v, w, 6.0, at=at)
            t = np.arange(1, len(r["rate"]) + 1) / 20.0
            ax.plot(t, r["rate"], style, lw=1.2, label=name)
        ax.axhline(w, color="k", lw=0.8, ls="--", label="command")
        ax.set(title=f"step to v={v} m/s, ω={w} rad/s", xlabel="time, s", ylabel="yaw rate, rad/s")
        ax.set_ylim(0, 1.6)
        ax.legend(fontsize=7, loc="upper right", ncol=2)
    fig.tight_layout()
    IMG.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig).print_png(str(IMG / "yaw_step_response.png"))
    print(f"   figure: {IMG / 'yaw_step_response.png'}")


def climbing() -> None:
    print("\n3. metres gained up the slope in 6 s at 0.5 m/s (3 m commanded)")
    slopes = (0, 10, 15, 20, 25, 30, 35, 40)
    print(f"{'':18}" + "".join(f"{s:>7}°" for s in slopes) + "   derived limit atan(μ − c_rr)")
    for name, cls, mu in (
        ("legacy (μ 1)", LegacyWorld, 1.0),
        ("tyres μ 0.6", World, 0.6),
        ("tyres μ 1.0", World, 1.0),
    ):
        soil = SoilConfig(friction=mu)
        gained = []
        for s in slopes:
            r = run_world(cls, plane(s), 0.5, 0.0, 6.0, soil)
            gained.append((r["pos"][-1, 0] - r["pos"][0, 0]) / math.cos(math.radians(s)))
        limit = math.degrees(math.atan(mu - soil.rolling_resistance))
        tail = f"   {limit:.1f}°" if cls is World else "   none (no traction model)"
        cells = "".join(f"{g:8.2f}" if g > -0.5 else "  slides" for g in gained)
        print(f"{name:18}" + cells + tail)


def accelerometer() -> None:
    print("\n4. accelerometer std on flat ground, 0.5 m/s straight, / MTi-300 noise at 20 Hz")
    sigma = 60e-6 * 9.81 * math.sqrt(20)
    flat = {
        "field": {"width": 6.0, "length": 30.0},
        "layout": {"headland": 2.0},
        "terrain": {"source": "plane", "margin": 4.0},
        "furrows": {"enabled": False, "roughness": 0.0},
    }
    for name in ("legacy", "tyres"):
        env = gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario_overrides=flat,
            config={"task": {"corridor": 5.0, "max_crops_hit": 10**6}},
        )
        if name == "legacy":
            legacy_env(env)
        env.reset(seed=0, options={"lane": 2})
        f = []
        for k in range(200):
            env.step(np.array([0.5, 0.0], np.float32))
            if k >= 40:
                f.append(env.unwrapped.readings.accel.copy())
        env.close()
        std = np.std(f, axis=0)
        print(
            f"   {name:7}: std (x, y, z) {np.round(std, 4)} m/s² = {np.round(std / sigma, 1)} × MTi"
        )


def step_cost(repeat: int) -> None:
    print(f"\n5. env step cost, FurrowFollow on paper-p1 (median of {repeat}, interleaved)")
    setups = (
        ("legacy+blend", "blend", None),
        ("tyres+blend", "blend", None),
        ("tyres+ekf", "ekf", None),
        ("tyres+ekf R1", "ekf", 5),  # 2.5 m maize over the antenna: the sky model at work
    )
    envs = []
    for name, loc, stage in setups:
        env = gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario="paper-p1",
            scenario_overrides={"crop": {"stage": stage}} if stage else None,
            observations=("gps", "imu", "odom", "route"),
            config={
                "task": {"max_crops_hit": 10**6, "corridor": 2.0},
                "localisation": {"kind": loc},
            },
        )
        if name.startswith("legacy"):
            legacy_env(env)
        envs.append(env)
    env_t: list[list[float]] = [[] for _ in setups]
    raw_t: list[list[float]] = [[] for _ in setups]
    for r in range(repeat):  # interleaved: the machine's load drifts alike for every setup
        for i, env in enumerate(envs):
            u = env.unwrapped
            env.reset(seed=r)
            env_t[i].append(drive(env, 300) / 300)
            env.reset(seed=r)
            t = 0.0
            for k in range(300):
                t0 = time.perf_counter()
                u.world.drive(*(s_curve(k) * (u.cfg.robot.v_max, u.cfg.robot.w_max)).tolist())
                u.world.step(u.substeps)
                t += time.perf_counter() - t0
            raw_t[i].append(t / 300)
    for env in envs:
        env.close()
    base = statistics.median(env_t[0])
    for (name, *_), e_t, r_t in zip(setups, env_t, raw_t, strict=True):
        e, r = statistics.median(e_t), statistics.median(r_t)
        print(
            f"   {name:13}: env step {e * 1e3:.3f} ms, raw physics {r * 1e3:.3f} ms, "
            f"env/raw {e / r:.2f}, env / legacy env {e / base:.2f}"
        )


CASES = (
    ("RTK fixed", {"mode": "rtk_fixed", "fix": {"model": "constant"}}, 1),
    ("RTK float", {"mode": "rtk_float", "fix": {"model": "constant"}}, 1),
    ("standalone", {"mode": "standalone", "fix": {"model": "constant"}}, 1),
    ("maize R1 canopy", {"mode": "rtk_fixed"}, 5),
)


def estimate_errors(seeds: int) -> dict[tuple[str, str], list[float]]:
    """Both estimators on the same drive: the robot is steered by pure pursuit on the true pose
    (the ``ideal`` estimator), and the EKF and the blend read the same sensor readings, so
    neither estimate changes where the robot goes."""
    from agrinav_gym.estimation import make_estimator
    from policies import make_policy

    print(f"\n6. estimate position error RMS over one lane, median of {seeds} seeds")
    out: dict[tuple[str, str], list[float]] = {}
    modes: dict[str, dict[str, int]] = {}
    with tqdm(total=len(CASES) * seeds, desc="episodes", unit="ep", leave=False) as bar:
        for case, gnss, stage in CASES:
            env = gym.make(
                "AgriNav/FurrowFollow-v3",
                scenario_overrides={"crop": {"stage": stage}},
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
                ests = {
                    k: make_estimator(k, u.cfg.localisation, u.world.skid_factor, u.dt)
                    for k in ("ekf", "blend")
                }
                rng = np.random.default_rng(seed)
                err: dict[str, list[float]] = {k: [] for k in ests}
                for e in ests.values():
                    e.reset(*u.start, rng)
                    e.update(u.readings, u.dt)
                while True:
                    obs, _, term, trunc, _ = env.step(pi.act(obs))
                    for k, e in ests.items():
                        e.update(u.readings, u.dt)
                        ex, ey, _ = e.pose
                        err[k].append(math.hypot(ex - u.state.pos[0], ey - u.state.pos[1]))
                    m = modes.setdefault(case, {})
                    m[u.readings.gnss_mode] = m.get(u.readings.gnss_mode, 0) + 1
                    if term or trunc:
                        break
                for k in ests:
                    out.setdefault((case, k), []).append(float(np.sqrt(np.mean(np.square(err[k])))))
                bar.update()
            env.close()
    for case, *_ in CASES:
        e, b = (statistics.median(out[(case, k)]) for k in ("ekf", "blend"))
        total = sum(modes[case].values())
        share = ", ".join(f"{k} {v / total:.0%}" for k, v in sorted(modes[case].items()))
        print(f"   {case:16}: EKF {e:.3f} m, blend {b:.3f} m   (fix modes: {share})")
    return out


def error_figure(errors: dict[tuple[str, str], list[float]]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 3.4), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    x = np.arange(len(CASES))
    for k, (kind, colour) in enumerate((("ekf", "C0"), ("blend", "C1"))):
        med = [statistics.median(errors[(c, kind)]) for c, *_ in CASES]
        ax.bar(x + (k - 0.5) * 0.38, med, 0.38, color=colour, label=kind)
        for xi, c in zip(x, CASES, strict=True):
            ax.plot(
                np.full(len(errors[(c[0], kind)]), xi + (k - 0.5) * 0.38),
                errors[(c[0], kind)],
                "k.",
                ms=3,
            )
    ax.set_yscale("log")
    ax.set_xticks(x, [c for c, *_ in CASES])
    ax.set(ylabel="position error RMS, m", title="estimate error by GNSS fix mode (same drives)")
    ax.legend()
    fig.tight_layout()
    FigureCanvasAgg(fig).print_png(str(IMG / "estimate_error_by_fix_mode.png"))
    print(f"   figure: {IMG / 'estimate_error_by_fix_mode.png'}")


def fix_sensitivity() -> None:
    print("\n7. fix mode the sky supports at a lane centre (antenna 0.71 m), by foliage loss")
    losses = (1.0, 2.0, 4.0)
    names = {0: "none", 1: "standalone", 2: "float", 3: "FIXED"}
    print(f"   {'rows, stage (height)':26}" + "".join(f"{g:>6.0f} dB/m   " for g in losses))
    for rows in (1.0, 0.76):
        for stage in (1, 3, 4, 5):
            spec = sg.preset(
                "default",
                layout={"row_spacing": rows},
                crop={"stage": stage},
                field={"width": 12.0, "length": 20.0},
            )
            scn = sg.generate(spec, 0)
            pl = scn.plants
            ids = np.unique(pl.row[pl.row >= 0])[3:5]
            c = np.mean([[pl.x[pl.row == r].mean(), pl.y[pl.row == r].mean()] for r in ids], axis=0)
            ant = np.array([c[0], c[1], float(scn.terrain.height_at(*c)) + 0.71])
            cells = []
            for g in losses:
                cfg = GnssFixConfig(foliage_db_per_m=g)
                qc, qd = SkyModel(cfg, Canopy(scn)).usable(ant)
                level = FixModeChain(cfg, "rtk_fixed", 0.1).supported(qc, qd)
                cells.append(f"{names[level]:>10} {qc:.2f}")
            h = float(np.mean(pl.height[pl.row >= 0]))
            print(f"   {rows:.2f} m, {stage} ({h:.1f} m)" + " " * 8 + "  ".join(cells))
    print(f"   (mode, carrier-usable sky fraction; levels {', '.join(LEVELS)})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timing repeats")
    ap.add_argument("--seeds", type=int, default=5, help="episodes per localisation case")
    args = ap.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, pybullet {p.getAPIVersion()}"
    )
    yaw_tracking()
    step_response_figure()
    climbing()
    accelerometer()
    step_cost(args.repeat)
    error_figure(estimate_errors(args.seeds))
    fix_sensitivity()


if __name__ == "__main__":
    main()
