"""The video of ``agrinav run --video``: frames per second of its renderer, and its encoding.

The 640 × 480 chase view (``agrinav_gym.chase_view.ChaseView``, what ``env.render()`` returns)
at poses of an RPP drive along the default FieldRoute-v3 field — inside the maize, along the
lanes and through the headland turns:

1. rendering: frames per second rasterised (the compiled kernels, the default where they are
   built) and, for reference, ray-cast with Embree (``AGRINAV_NATIVE=0``: the path without
   them); target ≥ 10 frames/s rasterised on 2 cores;
2. encoding: frames per second of ``VideoWriter`` (VP8 through PyAV) on those frames, and the
   bitrate the file comes out at (20 frames/s);
3. end to end: ``run_episode`` with a ``VideoWriter``, as ``agrinav run --video`` drives it:
   frames per second of its ``render_seconds`` and the episode's own ``seconds`` beside them.

Medians of several runs. Run: ``python benchmarks/bench_video.py`` (about two minutes).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.render import native
from agrinav_gym.scenarios import FixedFieldWarning
from baselines.episodes import VIDEO_BITRATE, VideoWriter, run_episode
from policies import make_policy

ENV = "AgriNav/FieldRoute-v3"
OBS = ["gps", "imu", "odom", "route", "depth"]


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def drive_states(env: Any, steps: int, every: int) -> list[Any]:
    """The robot's true states every ``every`` steps of an RPP drive from the first eval seed."""
    pi = make_policy("rpp", env)
    obs, _ = env.reset(seed=1_000_000_000)
    pi.reset()
    states = [env.unwrapped.state]
    for i in range(1, steps + 1):
        obs, _, term, trunc, _ = env.step(pi.act(obs))
        if i % every == 0:
            states.append(env.unwrapped.state)
        if term or trunc:
            break
    return states


def render_fps(env: Any, states: list[Any]) -> tuple[float, list[np.ndarray]]:
    """Frames per second drawing ``states`` in order (the env's own ``render``), and the frames."""
    u = env.unwrapped
    frames = []
    t0 = time.perf_counter()
    for s in states:
        u.state = s
        frames.append(env.render())
    return len(states) / (time.perf_counter() - t0), frames


def encode_fps(frames: list[np.ndarray], folder: Path) -> tuple[float, float]:
    """Frames per second of ``VideoWriter.write`` and the file's bitrate (Mbit/s at 20 fps)."""
    path = folder / "encode.webm"
    w = VideoWriter(path)
    t0 = time.perf_counter()
    for f in frames:
        w.write(f)
    w.close()
    dt = time.perf_counter() - t0
    return len(frames) / dt, path.stat().st_size * 8 / (len(frames) / w.fps) / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="runs per measurement (median)")
    ap.add_argument("--frames", type=int, default=40, help="poses rendered per run")
    ap.add_argument("--episode-steps", type=int, default=200, help="steps of the end-to-end run")
    args = ap.parse_args()

    warnings.simplefilter("ignore", FixedFieldWarning)  # one field on purpose: the same poses
    py = platform.python_version()
    print(f"machine: {platform.platform()}, {cpu_model()}, {os.cpu_count()} cores, Python {py}")
    print(f"compiled kernels: {'built' if native.available() else 'NOT BUILT (reference paths)'}")
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    env = gym.make(ENV, render_mode="rgb_array", observations=OBS)
    try:
        every = 15
        states = drive_states(env, args.frames * every, every)[: args.frames]
        w, h = env.unwrapped.cfg.render.width, env.unwrapped.cfg.render.height
        print(f"{ENV}, default field, {len(states)} poses of an RPP drive, {w} x {h} frames")
        render_fps(env, states[:3])  # the scene and the first frames' buffers, untimed

        fast, frames = [], []
        for _ in range(args.runs):
            fps, frames = render_fps(env, states)
            fast.append(fps)
        slow = []
        if native.available():
            chase = env.unwrapped._chase
            chase.rasterises = False
            for _ in range(max(2, args.runs // 2)):
                slow.append(render_fps(env, states[:: max(1, len(states) // 8)])[0])
            chase.rasterises = True
        print("\n1. rendering, frames/s (median of runs; each run's)")
        print(f"   rasterised: {statistics.median(fast):6.1f}   {[round(f, 1) for f in fast]}")
        if slow:
            print(f"   ray-cast:   {statistics.median(slow):6.1f}   {[round(f, 1) for f in slow]}")
            print(f"   ratio:      {statistics.median(fast) / statistics.median(slow):6.1f}x")

        with tempfile.TemporaryDirectory() as tmp:
            enc = [encode_fps(frames, Path(tmp)) for _ in range(args.runs)]
            print(f"\n2. encoding (VP8 through PyAV, target {VIDEO_BITRATE / 1e6:g} Mbit/s)")
            print(f"   frames/s: {statistics.median(e[0] for e in enc):6.1f}")
            print(f"   bitrate:  {statistics.median(e[1] for e in enc):6.2f} Mbit/s at 20 fps")

            ends = []
            limited = gym.make(
                ENV,
                render_mode="rgb_array",
                observations=OBS,
                max_episode_steps=args.episode_steps,
            )
            pi = make_policy("rpp", limited)
            try:
                for k in range(max(2, args.runs // 2)):
                    path = Path(tmp) / f"episode_{k}.webm"
                    writer = VideoWriter(path)
                    try:
                        ep = run_episode(limited, pi, 1_000_000_000, "rpp", writer)
                    finally:
                        writer.close()
                    ends.append((ep.frames / ep.render_seconds, ep.seconds, path.stat().st_size))
            finally:
                limited.close()
        fps_e = statistics.median(e[0] for e in ends)
        secs = statistics.median(e[1] for e in ends)
        size = statistics.median(e[2] for e in ends)
        print(f"\n3. end to end ({args.episode_steps} steps: run_episode + VideoWriter)")
        print(f"   frames/s (render + encode): {fps_e:6.1f}")
        print(f"   episode's own seconds:      {secs:6.2f}  (rendering left out)")
        print(f"   file:                       {size / 1e6:6.2f} MB")
    finally:
        env.close()


if __name__ == "__main__":
    main()
