"""Running a policy on an env: episodes, trajectories, videos and the trajectory figure."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class Episode:
    policy: str
    env_id: str
    seed: int
    metrics: dict[str, Any]
    steps: int
    termination: str
    seconds: float
    poses: np.ndarray = field(repr=False)  # true base positions (N, 2), for evaluation only
    route: np.ndarray = field(repr=False)
    furrow: np.ndarray = field(repr=False)
    plants: np.ndarray = field(repr=False)


def run_episode(
    env: Any, policy: Any, seed: int, policy_name: str, video: Any | None = None
) -> Episode:
    import gymnasium as gym  # noqa: F401

    obs, _ = env.reset(seed=seed)
    policy.reset()
    info: dict[str, Any] = {}
    steps, t0 = 0, time.perf_counter()
    while True:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        steps += 1
        if video is not None:
            video(env)
        if term or trunc:
            break
    u = env.unwrapped
    scn = u.scenario
    return Episode(
        policy_name,
        u.spec.id if u.spec else type(u).__name__,
        seed,
        dict(info["metrics"]),
        steps,
        info.get("termination", "time_limit"),
        time.perf_counter() - t0,
        u.trajectory,
        u.route.xy.copy(),
        u.route.furrow.copy(),
        np.column_stack([scn.plants.x, scn.plants.y])[~scn.plants.is_weed],
    )


def trajectory_figure(ep: Episode, path: Path, title: str) -> None:
    """The source paper's Fig. 12, better: path, trajectory coloured by CTE, crops, numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from agrinav_gym.metrics import project_to_polyline

    dist, _, _, _ = project_to_polyline(ep.poses, ep.route)
    pad = 1.5
    lo = np.minimum(ep.route.min(axis=0), ep.poses.min(axis=0)) - pad
    hi = np.maximum(ep.route.max(axis=0), ep.poses.max(axis=0)) + pad
    span = hi - lo
    fig, ax = plt.subplots(figsize=(10, max(3.0, min(8.0, 10 * span[1] / span[0] + 1.2))))
    near = np.all((ep.plants >= lo) & (ep.plants <= hi), axis=1)
    px, py = ep.plants[near].T
    ax.scatter(px, py, s=6, color="forestgreen", alpha=0.6, label="crops", linewidths=0)
    ax.plot(*ep.route.T, "--", color="0.3", lw=1.0, label="reference path")
    seg = np.stack([ep.poses[:-1], ep.poses[1:]], axis=1)
    vmax = max(0.05, float(np.percentile(dist, 99)))
    lc = LineCollection(list(seg), cmap="plasma", norm=plt.Normalize(0, vmax), linewidths=2.5)
    lc.set_array(0.5 * (dist[:-1] + dist[1:]))
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label="cross-track error (m)", shrink=0.85)
    m = ep.metrics

    def f(v: Any) -> str:
        return "—" if v is None else f"{v:.3f}"

    text = (
        f"RMSE {f(m['rmse'])} m · MAE {f(m['mae'])} · max {f(m['max'])}\n"
        f"in-furrow {f(m['in_furrow_rmse'])} · headland {f(m['headland_rmse'])} · "
        f"completion {m['completion']:.0f} % · crops hit {m['crops_hit']}"
    )
    ax.set_title(f"{title}\n{text}", fontsize=9)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


class VideoWriter:
    """MP4 of the env's ``rgb_array`` chase view (OpenCV's FFmpeg backend)."""

    def __init__(self, path: Path, fps: int = 20) -> None:
        self.path, self.fps = path, fps
        self.writer: Any = None

    def __call__(self, env: Any) -> None:
        import cv2

        frame = env.render()
        if frame is None:
            return
        if self.writer is None:
            h, w = frame.shape[:2]
            self.writer = cv2.VideoWriter(
                str(self.path), cv2.VideoWriter.fourcc(*"mp4v"), self.fps, (w, h)
            )
        self.writer.write(frame[:, :, ::-1])

    def close(self) -> None:
        if self.writer is not None:
            self.writer.release()
