"""A picture of one DWB cycle: the local costmap, the plan, the chosen trajectory, and a few
of the rejected ones with the critic that rejected them."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from agrinav_gym.interface import OBSERVATION_KEYS

if TYPE_CHECKING:
    from .policy import DWB


def cycle_figure(pi: DWB, path: str | Path, title: str = "", rejected: int = 6) -> None:
    """Write a PNG of ``pi``'s last cycle (call after ``pi.act``), full scores for every twist."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    assert pi.last is not None, "run act() first"
    cycle = pi.cycle_inputs
    ev = pi.planner.evaluate(cycle, full=True)  # every critic on every twist, for the picture
    g = pi.grid
    ext = (
        g.origin_x,
        g.origin_x + g.size_x * g.resolution,
        g.origin_y,
        g.origin_y + g.size_y * g.resolution,
    )
    fig = Figure(figsize=(7.5, 7.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    rgba = np.ones((256, 4))
    rgba[1:253, :3] = np.linspace(0.95, 0.35, 252)[:, None]  # inflated costs, darker = higher
    rgba[253] = (0.95, 0.55, 0.1, 1.0)  # inscribed
    rgba[254] = (0.75, 0.0, 0.0, 1.0)  # lethal
    rgba[255] = (0.4, 0.4, 0.4, 1.0)  # unknown
    cmap = ListedColormap(rgba)
    ax.imshow(
        pi.master.T,
        origin="lower",
        extent=ext,
        cmap=cmap,
        vmin=0,
        vmax=255,
        interpolation="nearest",
    )
    ro = ev.rollouts
    finite = np.isfinite(ev.total)
    bad = np.flatnonzero(~ev.legal)
    if len(bad):
        pick = bad[np.linspace(0, len(bad) - 1, min(rejected, len(bad))).astype(int)]
        seen: set[str] = set()
        for i in pick:
            why = ev.rejected_by[i].split(":")[0]
            label = f"rejected ({why})" if why not in seen else None
            seen.add(why)
            p = ro.poses[i, : ro.length[i]]
            ax.plot(p[:, 0], p[:, 1], "--", lw=1.0, color="tab:red", alpha=0.7, label=label)
    ok = np.flatnonzero(finite)
    if len(ok):
        worst = ok[np.argsort(ev.total[ok])[-3:]]
        for j, i in enumerate(worst):
            p = ro.poses[i, : ro.length[i]]
            ax.plot(
                p[:, 0],
                p[:, 1],
                "-",
                lw=1.0,
                color="tab:blue",
                alpha=0.6,
                label="legal, worse" if j == 0 else None,
            )
    ax.plot(
        cycle.plan[:, 0], cycle.plan[:, 1], ".", ms=2, color="tab:green", label="transformed plan"
    )
    if ev.best >= 0:
        b = ev.best
        p = ro.poses[b, : ro.length[b]]
        v, w = ro.twists[b]
        ax.plot(
            p[:, 0],
            p[:, 1],
            "-",
            lw=2.5,
            color="black",
            label=f"chosen: v {v:.2f} m/s, ω {w:.2f} rad/s",
        )
        fx, fy = pi.footprint[:, 0], pi.footprint[:, 1]
        x, y, th = p[-1]
        c, s = np.cos(th), np.sin(th)
        poly = np.column_stack([x + fx * c - fy * s, y + fx * s + fy * c])
        ax.fill(poly[:, 0], poly[:, 1], fill=False, ec="black", lw=1.0, ls=":")
    x, y, th = pi.pose
    c, s = np.cos(th), np.sin(th)
    fx, fy = pi.footprint[:, 0], pi.footprint[:, 1]
    poly = np.column_stack([x + fx * c - fy * s, y + fx * s + fy * c])
    ax.fill(
        poly[:, 0],
        poly[:, 1],
        fc=(0.2, 0.4, 1.0, 0.25),
        ec="tab:blue",
        lw=1.5,
        label="robot footprint",
    )
    n_legal = int(finite.sum())
    ax.set_title(
        (title + "\n" if title else "")
        + f"{len(ro.twists)} twists, {n_legal} legal; cells: white free … grey 252, "
        "orange inscribed, red lethal",
        fontsize=8,
    )
    ax.set_xlabel("x (odometry frame, m)")
    ax.set_ylabel("y (m)")
    ax.set_xlim(ext[0], ext[1])
    ax.set_ylim(ext[2], ext[3])
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    """``python -m policies.dwb.figure OUT.png [SPEC] [STEP]``: drive FieldRoute (seed 10⁹,
    the benchmark's first) with SPEC (default dwb:furrow) for STEP steps and draw that cycle."""
    import sys

    import gymnasium as gym

    import agrinav_gym  # noqa: F401
    from policies import make_policy

    args = sys.argv[1:] if argv is None else argv
    out = args[0] if args else "dwb_cycle.png"
    spec = args[1] if len(args) > 1 else "dwb:furrow"
    steps = int(args[2]) if len(args) > 2 else 1600
    env = gym.make("AgriNav/FieldRoute-v3", observations=list(OBSERVATION_KEYS))
    try:
        pi = make_policy(spec, env)
        obs, _ = env.reset(seed=1_000_000_000)
        pi.reset()
        for _ in range(steps):
            obs, _, term, trunc, _ = env.step(pi.act(obs))
            if term or trunc:
                break
        pi.act(obs)
        cycle_figure(pi, out, f"{spec} · FieldRoute seed 10⁹ · step {steps}")  # type: ignore[arg-type]
    finally:
        env.close()
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
