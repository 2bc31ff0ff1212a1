"""Running a policy on an env: episodes, trajectories, videos and the trajectory figure."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agrinav_gym.recoveries import CLEARING


@dataclass
class Episode:
    policy: str
    env_id: str
    seed: int
    metrics: dict[str, Any]
    steps: int
    termination: str
    seconds: float  # the episode's own time (reset, policy, steps), rendering left out
    poses: np.ndarray = field(repr=False)  # true base positions (N, 2), for evaluation only
    errors: np.ndarray = field(repr=False)  # cross-track error of each pose (EpisodeMetrics)
    route: np.ndarray = field(repr=False)
    furrow: np.ndarray = field(repr=False)
    plants: np.ndarray = field(repr=False)  # crop positions (M, 2)
    hit: np.ndarray = field(repr=False)  # positions of the crops touched (K, 2)
    conditions: dict[str, str] = field(
        default_factory=dict
    )  # localisation, camera, speed, controller
    # with interventions (run_with_interventions): what ended each stretch, and where
    interventions: list[dict[str, Any]] | None = None
    autonomous_m: float | None = None  # route metres the robot drove by itself
    render_seconds: float = 0.0  # drawing and encoding the video's frames, apart from seconds
    frames: int = 0  # video frames written


#: Terminations an operator answers by putting the robot back on the route.
INTERVENTIONS = ("corridor", "crops_hit", "progress", "tip_over", "off_terrain")
MAX_INTERVENTIONS = 200
RESUME_AHEAD = 0.5  # m past the point reached: past the obstacle, not over a lane


def run_with_interventions(env: Any, policy: Any, seed: int, policy_name: str) -> Episode:
    """One long run in which every stall, corridor exit or stalk contact is an intervention
    (``INTERVENTIONS``) after which the run resumes from the route, as field trials count
    them; ends at the route's end or the step limit. Mean distance between interventions is
    ``autonomous_m / len(interventions)``."""
    u = env.unwrapped
    u_cfg = u.cfg.task
    if u_cfg.max_crops_hit != 0:
        raise ValueError("an intervention run needs task.max_crops_hit = 0 (every contact)")
    obs, _ = env.reset(seed=seed)
    policy.reset()
    info: dict[str, Any] = {}
    steps, t0 = 0, time.perf_counter()
    stops: list[dict[str, Any]] = []
    autonomous, since = 0.0, u.arc
    while True:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        steps += 1
        if info.get("recovery") in CLEARING:
            policy.clear_costmaps()
        kind = info.get("termination")
        if term and kind in INTERVENTIONS and len(stops) < MAX_INTERVENTIONS:
            autonomous += max(u.arc - since, 0.0)
            stops.append({"kind": kind, "at_m": round(u.arc, 2), "step": steps})
            obs, info = u.resume_on_route(RESUME_AHEAD)
            policy.reset()
            since = u.arc
            continue
        if term or trunc:
            break
    autonomous += max(u.arc - since, 0.0)
    ep = _episode(env, policy, seed, policy_name, info, steps, t0)
    ep.interventions, ep.autonomous_m = stops, autonomous
    return ep


def run_episode(
    env: Any, policy: Any, seed: int, policy_name: str, video: VideoWriter | None = None
) -> Episode:
    """One episode; with ``video`` every state (the reset's and each step's) is a frame,
    and the time spent on frames is ``render_seconds``, kept out of ``seconds``."""
    obs, _ = env.reset(seed=seed)
    policy.reset()
    info: dict[str, Any] = {}
    steps, t0 = 0, time.perf_counter()
    rendered = 0.0 if video is None else video(env)
    while True:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        steps += 1
        if info.get("recovery") in CLEARING:
            policy.clear_costmaps()
        if video is not None:
            rendered += video(env)
        if term or trunc:
            break
    ep = _episode(env, policy, seed, policy_name, info, steps, t0)
    ep.seconds -= rendered
    ep.render_seconds = rendered
    ep.frames = 0 if video is None else video.frames
    return ep


def _episode(
    env: Any, policy: Any, seed: int, policy_name: str, info: dict[str, Any], steps: int, t0: float
) -> Episode:
    u = env.unwrapped
    p = u.scenario.plants
    crops = np.column_stack([p.x, p.y])
    hit = np.asarray(sorted(u.crops_hit_ids), np.int64)
    return Episode(
        policy_name,
        u.spec.id if u.spec else type(u).__name__,
        seed,
        dict(info["metrics"]),
        steps,
        info.get("termination", "time_limit"),
        time.perf_counter() - t0,
        u.trajectory,
        np.asarray(u.metrics.errors),
        u.route.xy.copy(),
        u.route.furrow.copy(),
        crops[~p.is_weed],
        crops[hit] if len(hit) else np.empty((0, 2)),
        _conditions(u.conditions(), policy.describe()),
    )


def _conditions(env: dict[str, str], controller: str) -> dict[str, str]:
    """The env's conditions with the controller, after it the navigator that feeds it."""
    out = dict(env)
    nav = out.pop("navigator", None)
    out["controller"] = f"{controller}; {nav}" if nav else controller
    return out


def trajectory_figure(ep: Episode, path: Path, title: str) -> None:
    """The source paper's Fig. 12, better: path, trajectory coloured by cross-track error,
    crops (those hit marked), how the episode ended, and the numbers."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    pad = 1.5
    lo = np.minimum(ep.route.min(axis=0), ep.poses.min(axis=0)) - pad
    hi = np.maximum(ep.route.max(axis=0), ep.poses.max(axis=0)) + pad
    span = hi - lo
    fig = Figure(figsize=(10, max(3.5, min(8.0, 10 * span[1] / span[0] + 1.6))))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    near = np.all((ep.plants >= lo) & (ep.plants <= hi), axis=1)
    px, py = ep.plants[near].T
    ax.scatter(px, py, s=6, color="forestgreen", alpha=0.6, label="crops", linewidths=0)
    if len(ep.hit):
        hx, hy = ep.hit.T
        ax.scatter(
            hx,
            hy,
            s=40,
            marker="x",
            color="red",
            linewidths=1.5,
            zorder=5,
            label=f"crops hit ({len(ep.hit)})",
        )
    ax.plot(*ep.route.T, "--", color="0.3", lw=1.0, label="reference path")
    seg = np.stack([ep.poses[:-1], ep.poses[1:]], axis=1)
    dist = ep.errors
    vmax = max(0.05, float(np.percentile(dist, 99)))
    lc = LineCollection(list(seg), cmap="plasma", norm=Normalize(0, vmax), linewidths=2.5)
    lc.set_array(0.5 * (dist[:-1] + dist[1:]))
    ax.add_collection(lc)
    # the scale ends at the 99th percentile so one spike does not wash the rest out; the
    # arrow says there is more above it
    above = "max" if float(dist.max()) > vmax else "neither"
    fig.colorbar(lc, ax=ax, label="cross-track error (m)", shrink=0.85, extend=above)
    ax.plot(*ep.poses[0], "o", color="black", ms=5, zorder=6, label="start")
    ax.plot(*ep.poses[-1], "s", color="black", ms=5, zorder=6, label=f"end: {ep.termination}")
    m = ep.metrics

    def f(v: Any) -> str:
        return "—" if v is None else f"{v:.3f}"

    # completion rounded down: 99.6 % of a route that was not finished never reads 100 %
    done = math.floor(10.0 * m["completion"]) / 10.0
    text = (
        f"path RMSE {f(m.get('path_rmse'))} m (per step {f(m['rmse'])}) · MAE {f(m['mae'])} · "
        f"max {f(m['max'])}\n"
        f"in-furrow {f(m.get('path_in_furrow_rmse'))} · headland "
        f"{f(m.get('path_headland_rmse'))} · completion {done:.1f} % · "
        f"crops hit {m['crops_hit']} · ended: {ep.termination} after {ep.steps} steps"
    )
    ax.set_title(f"{title}\n{text}", fontsize=9)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    # along the figure's foot: inside the axes it covered the headland turn, where the
    # largest errors are
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=6, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0.0, 0.3 / fig.get_figheight(), 1.0, 1.0))
    fig.savefig(path, dpi=110)


#: VP8's target bitrate, bit/s: ≈ 9 MB a minute of the 640 × 480 chase view (OpenCV's
#: writer, which takes no bitrate, made ≈ 12 Mbit/s of it: 90 MB a minute). On a FieldRoute
#: drive doubling it gains < 1 dB PSNR.
VIDEO_BITRATE = 1_200_000
#: libvpx's speed settings: ≈ 5-7 ms a 640 × 480 frame where its defaults take ≈ 40 ms, for
#: the same PSNR at this bitrate
VIDEO_OPTIONS = {"deadline": "good", "cpu-used": "5"}


class VideoWriter:
    """A VP8 WebM (libvpx through PyAV) of the env's ``rgb_array`` view: plays in browsers and
    README previews. ``bitrate`` in bit/s. Each call renders and encodes one frame, moves
    ``progress`` (a tqdm bar) on by one and returns the seconds it took (``seconds`` sums
    them). Odd frame sizes lose their last column or row (4:2:0 chroma)."""

    def __init__(
        self, path: Path, fps: int = 20, bitrate: int = VIDEO_BITRATE, progress: Any = None
    ) -> None:
        self.path, self.fps, self.bitrate = Path(path), fps, bitrate
        self.progress = progress
        self.frames = 0
        self.seconds = 0.0
        self._out: Any = None
        self._stream: Any = None

    def __call__(self, env: Any) -> float:
        t0 = time.perf_counter()
        frame = env.render()
        if frame is not None:
            self.write(frame)
        dt = time.perf_counter() - t0
        self.seconds += dt
        if self.progress is not None:
            self.progress.update(1)
        return dt

    def write(self, frame: np.ndarray) -> None:
        """Encode one (h, w, 3) uint8 RGB frame."""
        import av

        h, w = (frame.shape[0] // 2) * 2, (frame.shape[1] // 2) * 2
        if self._stream is None:
            if h == 0 or w == 0:
                raise ValueError(f"a video frame needs at least 2 x 2 pixels, got {frame.shape}")
            self._out = av.open(str(self.path), "w", format="webm")
            opts = dict(VIDEO_OPTIONS)
            self._stream = self._out.add_stream("libvpx", rate=self.fps, options=opts)
            self._stream.width, self._stream.height = w, h
            self._stream.pix_fmt = "yuv420p"
            self._stream.bit_rate = self.bitrate
            # one thread: libvpx's own threads cost ≈ 7× the CPU at 640 × 480 (≈ 50 ms a frame
            # against 7 ms measured on 2 busy cores), and the renderer has the cores
            self._stream.codec_context.thread_count = 1
        elif (h, w) != (self._stream.height, self._stream.width):
            size = f"{self._stream.height} x {self._stream.width}"
            raise ValueError(f"frame {frame.shape} differs from the video's {size}")
        vf = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame[:h, :w, :3]), format="rgb24")
        vf.pts = self.frames
        self._mux(self._stream.encode(vf))
        self.frames += 1

    def _mux(self, packets: Any) -> None:
        for pk in packets:
            self._out.mux(pk)

    def close(self) -> None:
        if self._out is not None:
            try:
                self._mux(self._stream.encode())  # flush the encoder
            finally:
                self._out.close()
                self._out = None
