"""How much ridges steer the simulated robot, over ridge height, with the soil values swept.

1. turn ratio: yaw rate achieved under a gentle turn (0.2 rad/s at 1 m/s) in a furrow between
   sine ridges, over the level-ground rate (1 = no guidance, 0 = a rail), for each assumed soil
   value at both ends of its plausible range (``agrinav_gym.sim.ridge_guidance``);
2. blind completion: % of a FurrowFollow-v3 lane a constant command with no sensors drives
   before leaving it, over ridge height (``--seeds`` episodes each), with the point contact
   the registered envs use and with the Summit-XL's 0.15 m tread.

Prints both tables and writes ``docs/img/ridge_guidance.png``.
Run ``python benchmarks/ridge_guidance.py``.
"""

from __future__ import annotations

import argparse
import platform
import statistics
from pathlib import Path

import gymnasium as gym
from tqdm import tqdm

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.sim.ridge_guidance import soil_variants, turn_ratio
from baselines.episodes import run_episode
from policies import make_policy

IMG = Path(__file__).resolve().parents[1] / "docs" / "img"
DEPTHS = [0.0, 0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.12]


#: the tread widths section 2 drives: the registered envs' point contact, the Summit-XL's tread
TREADS = (0.0, 0.15)


def blind_completion(depth: float, seed: int, tread: float = 0.0) -> float:
    over = {"furrows": {"enabled": depth > 0, "depth": max(depth, 1e-3)}}
    config = {"soil": {"contact_width": tread}}
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=over, config=config)
    try:
        return float(
            run_episode(env, make_policy("blind", env), seed, "blind").metrics["completion"]
        )
    finally:
        env.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, {platform.python_version()}")
    soils = soil_variants()
    ratios = {name: [] for name in soils}
    for name, soil in tqdm(soils.items(), desc="soils"):
        ratios[name] = [turn_ratio(d, soil) for d in DEPTHS]
    print("\n1. turn ratio (achieved / level-ground yaw rate, 0.2 rad/s at 1 m/s)")
    print(f"{'soil':16}" + "".join(f"{d:>7.3f}" for d in DEPTHS))
    for name, row in ratios.items():
        print(f"{name:16}" + "".join(f"{r:7.2f}" for r in row))
    blind: dict[float, list[list[float]]] = {}
    for tread in TREADS:
        print(
            f"\n2. blind completion (%, {args.seeds} seeds, FurrowFollow-v3, default soil, "
            f"tread {tread:g} m)"
        )
        blind[tread] = []
        for d in tqdm(DEPTHS, desc=f"blind, tread {tread:g} m"):
            runs = [blind_completion(d, s, tread) for s in range(args.seeds)]
            blind[tread].append(runs)
            print(
                f"ridge {d:5.3f} m: median {statistics.median(runs):5.1f} %, "
                f"min {min(runs):5.1f}, max {max(runs):5.1f}"
            )
    figure(ratios, blind)


def figure(ratios: dict[str, list[float]], blind: dict[float, list[list[float]]]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    a, b = fig.subplots(1, 2)
    cm = [100 * d for d in DEPTHS]
    for name, row in ratios.items():
        style = {"lw": 2.5, "color": "k"} if name == "default" else {"lw": 1, "alpha": 0.8}
        a.plot(cm, row, marker="o", ms=3, label=name, **style)
    a.set_xlabel("ridge height (cm)")
    a.set_ylabel("achieved / level-ground yaw rate")
    a.set_title("a gentle turn in the furrow (0.2 rad/s at 1 m/s)", fontsize=9)
    a.axhline(1.0, color="0.6", lw=0.8)
    a.legend(fontsize=7)
    for k, (tread, runs) in enumerate(blind.items()):
        shift = 0.2 * (2 * k - len(blind) + 1)
        art = b.boxplot(
            runs, positions=[i + shift for i in range(len(DEPTHS))], widths=0.35,
            patch_artist=True, manage_ticks=False,
        )  # fmt: skip
        for box in art["boxes"]:
            box.set_facecolor(f"C{k}")
        b.plot(
            [],
            [],
            color=f"C{k}",
            lw=6,
            label="point contact" if not tread else f"tread {tread:g} m",
        )
    b.legend(fontsize=7, loc="lower right")
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
