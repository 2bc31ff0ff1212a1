"""How much ridges steer the simulated robot, over ridge height, with the soil values swept.

1. turn ratio: yaw rate achieved under a gentle turn (0.2 rad/s at 1 m/s) in a furrow between
   sine ridges, over the level-ground rate (1 = no guidance, 0 = a rail), for each assumed soil
   value at both ends of its plausible range, on a rigid ground
   (``agrinav_gym.sim.ridge_guidance``);
2. the same on ridges that yield (``agrinav_gym.sim.terramechanics``): every measured soil of
   Wong's table under the Summit-XL's 0.15 m tread, and the yield model's own assumed values
   (patch length, bulk density) at both ends of their ranges on one of them;
3. blind completion: % of a FurrowFollow-v3 lane a constant command with no sensors drives
   before leaving it, over ridge height (``--seeds`` episodes each), with the point contact
   the registered envs use, the Summit-XL's tread, and the tread on three measured soils.

Prints the tables and writes ``docs/img/ridge_guidance.png``.
Run ``python benchmarks/ridge_guidance.py``.
"""

from __future__ import annotations

import argparse
import math
import platform
import statistics
from pathlib import Path

import gymnasium as gym
from tqdm import tqdm

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.config import SoilConfig
from agrinav_gym.robot import RobotGeometry
from agrinav_gym.sim.ridge_guidance import (
    SUMMIT_TREAD,
    measured_soils,
    soil_variants,
    turn_ratios,
    yield_variants,
)
from agrinav_gym.sim.terramechanics import (
    WONG_SOILS,
    bearing_capacity,
    bekker_sinkage,
    measured_strength,
)
from baselines.episodes import run_episode
from policies import make_policy

IMG = Path(__file__).resolve().parents[1] / "docs" / "img"
DEPTHS = [0.0, 0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.12]


#: what section 3 drives: the registered envs' point contact, the Summit-XL's tread on a rigid
#: ground, and on three measured soils whose ridges yield (firm to weak)
BLIND_SOILS = ("lean clay 22 % (WES)", "sandy loam 15 % (LLL)", "dry sand (LLL)")


def blind_contacts() -> dict[str, dict]:
    tread = {"contact_width": SUMMIT_TREAD}
    out: dict[str, dict] = {"point contact": {}, f"tread {SUMMIT_TREAD:g} m": tread}
    for name in BLIND_SOILS:
        out[f"tread {SUMMIT_TREAD:g} m, {name}"] = {**tread, **measured_strength(name)}
    return out


def blind_completion(depth: float, seed: int, soil: dict) -> float:
    over = {"furrows": {"enabled": depth > 0, "depth": max(depth, 1e-3)}}
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=over, config={"soil": soil})
    try:
        return float(
            run_episode(env, make_policy("blind", env), seed, "blind").metrics["completion"]
        )
    finally:
        env.close()


def soil_table() -> None:
    """Each measured soil's strength, what it bears under the Summit-XL's tread on level ground
    and on the steepest flank of 5 and 12 cm sine ridges (1 m rows), and its Bekker sinkage
    under a quarter of the robot's weight (the contact patch it implies)."""
    geo = RobotGeometry.from_urdf()
    load = 0.25 * geo.mass * 9.81
    flank = {d: math.degrees(math.atan(math.pi * d)) for d in (0.05, 0.12)}  # max sine slope
    soils = measured_soils()
    print(
        f"\nmeasured soils (Wong 2008, Table 2.3) under a {geo.wheel_width:g} m tread, "
        f"{SoilConfig().contact_length:g} m patch; {load:.0f} N a wheel = "
        f"{load / (geo.wheel_width * SoilConfig().contact_length) / 1000:.1f} kPa"
    )
    print(
        f"{'soil':30} {'c kPa':>6} {'φ°':>5} {'level':>7} "
        + "".join(f"{f'{d * 100:g} cm ({a:.1f}°)':>15}" for d, a in flank.items())
        + f"{'sinkage mm':>11}{'chord m':>8}"
    )
    for name, soil in soils.items():
        m = WONG_SOILS[name]
        z = bekker_sinkage(m, load, geo.wheel_radius, geo.wheel_width)
        caps = "".join(f"{bearing_capacity(soil, a):15.1f}" for a in flank.values())
        print(
            f"{name:30} {m.cohesion_kpa:6.2f} {m.friction_angle_deg:5.1f} "
            f"{bearing_capacity(soil):7.1f}{caps}{1000 * z:11.1f}"
            f"{2 * math.sqrt(2 * geo.wheel_radius * z):8.3f}"
        )


def _ratios(title: str, soils: dict) -> dict[str, list[float]]:
    ratios = {name: turn_ratios(DEPTHS, soil) for name, soil in tqdm(soils.items())}
    print(f"\n{title}")
    print(f"{'soil':30}" + "".join(f"{d:>7.3f}" for d in DEPTHS))
    for name, row in ratios.items():
        print(f"{name:30}" + "".join(f"{r:7.2f}" for r in row))
    return ratios


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, {platform.python_version()}")
    rigid = _ratios(
        "1. turn ratio on a rigid ground (achieved / level-ground yaw rate, 0.2 rad/s at 1 m/s)",
        soil_variants(),
    )
    soil_table()
    measured = _ratios("2. turn ratio on ridges that yield, 0.15 m tread", measured_soils())
    assumed = _ratios("2b. the yield model's assumed values", yield_variants())
    blind: dict[str, list[list[float]]] = {}
    for label, soil in blind_contacts().items():
        print(f"\n3. blind completion (%, {args.seeds} seeds, FurrowFollow-v3, {label})")
        blind[label] = []
        for d in tqdm(DEPTHS, desc=label):
            runs = [blind_completion(d, s, soil) for s in range(args.seeds)]
            blind[label].append(runs)
            print(
                f"ridge {d:5.3f} m: median {statistics.median(runs):5.1f} %, "
                f"min {min(runs):5.1f}, max {max(runs):5.1f}"
            )
    figure(rigid, {**measured, **{k: v for k, v in assumed.items() if k in YIELD_SWEPT}}, blind)


#: the assumed-value rows drawn beside the measured soils (dashed)
YIELD_SWEPT = ("patch 0.05 m", "patch 0.2 m")


def figure(
    rigid: dict[str, list[float]],
    measured: dict[str, list[float]],
    blind: dict[str, list[list[float]]],
) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    a, m, b = fig.subplots(1, 3)
    cm = [100 * d for d in DEPTHS]
    for name, row in rigid.items():
        style = {"lw": 2.5, "color": "k"} if name == "default" else {"lw": 1, "alpha": 0.8}
        a.plot(cm, row, marker="o", ms=3, label=name, **style)
    a.set_title("rigid ground: a gentle turn in the furrow (0.2 rad/s at 1 m/s)", fontsize=9)
    a.plot(cm, rigid["tread 0.15 m"], color="k", lw=1.5, ls=":")
    for k, (name, row) in enumerate(measured.items()):
        dashed = name in YIELD_SWEPT
        m.plot(
            cm, row, marker="" if dashed else "o", ms=3, lw=1, ls="--" if dashed else "-",
            color=f"C{k % 10}", alpha=0.85, label=name,
        )  # fmt: skip
    m.plot(cm, rigid["tread 0.15 m"], color="k", lw=2.5, label="rigid ground, tread 0.15 m")
    m.set_title("ridges that yield: Wong's measured soils, 0.15 m tread", fontsize=9)
    for ax in (a, m):
        ax.set_xlabel("ridge height (cm)")
        ax.set_ylabel("achieved / level-ground yaw rate")
        ax.axhline(1.0, color="0.6", lw=0.8)
    a.legend(fontsize=6)
    m.legend(fontsize=5, loc="lower left", ncol=2)  # the curves keep to the upper half
    for k, (label, runs) in enumerate(blind.items()):
        shift = 0.16 * (k - 0.5 * (len(blind) - 1))
        art = b.boxplot(
            runs, positions=[i + shift for i in range(len(DEPTHS))], widths=0.14,
            patch_artist=True, manage_ticks=False,
        )  # fmt: skip
        for box in art["boxes"]:
            box.set_facecolor(f"C{k}")
        b.plot([], [], color=f"C{k}", lw=6, label=label)
    b.legend(fontsize=6, loc="lower right")
    b.set_xticks(range(len(DEPTHS)), [f"{c:g}" for c in cm])
    b.set_xlabel("ridge height (cm)")
    b.set_ylabel("lane completed (%)")
    b.set_title("a constant command, no sensors (FurrowFollow-v3)", fontsize=9)
    fig.suptitle("How much the simulated ridges steer the robot")
    IMG.mkdir(parents=True, exist_ok=True)
    fig.savefig(IMG / "ridge_guidance.png", dpi=100)
    print(f"\nwrote {IMG / 'ridge_guidance.png'}")


if __name__ == "__main__":
    main()
