"""Perception dataset throughput against the mesh camera's raw frame rate, side by side.

raw: the env stepping with the 848×480 mesh camera rendering RGB, depth and segmentation on
every step, minus the same env stepping without a camera — the camera's own cost per frame.
dataset: frames per second of ``generate`` writing whole shards (env construction, driving
between frames, labels, PNG/NPY encoding, tar writing included), 1 worker and 2 workers.
Medians of ``--repeat`` runs; ratios within the run.

    python benchmarks/bench_dataset.py [--repeat 3] [--frames 16]
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401
from baselines.dataset import generate, load_spec


def _steps(config: dict, observations: list[str], n: int) -> float:
    env = gym.make("AgriNav/FurrowFollow-v1", config=config, observations=observations)
    try:
        env.reset(seed=0)
        a = np.array([0.3, 0.0], np.float32)
        for _ in range(3):
            env.step(a)
        t = time.perf_counter()
        for _ in range(n):
            env.step(a)
        return (time.perf_counter() - t) / n
    finally:
        env.close()


def raw_frame_seconds(n: int) -> float:
    cam = {"model": "mesh", "width": 848, "height": 480, "rgb": True, "segmentation": True}
    with_cam = _steps({"camera": cam}, ["imu", "odom", "route", "depth"], n)
    without = _steps({}, ["imu", "odom", "route"], n)
    return with_cam - without


def dataset_fps(frames: int, shard: int, workers: int) -> float:
    spec = load_spec(None, {"frames_per_shard": shard})
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        generate(spec, Path(d) / "ds", seed=0, frames=frames, workers=workers)
        return frames / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--frames", type=int, default=16, help="frames per shard")
    a = ap.parse_args()
    raw = statistics.median(raw_frame_seconds(20) for _ in range(a.repeat))
    one = statistics.median(dataset_fps(a.frames, a.frames, 1) for _ in range(a.repeat))
    two = statistics.median(dataset_fps(2 * a.frames, a.frames, 2) for _ in range(a.repeat))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}")
    print(f"mesh camera 848x480 RGB-D + segmentation: {1 / raw:.2f} frames/s ({raw * 1e3:.0f} ms)")
    print(
        f"dataset, 1 worker, {a.frames}-frame shards: {one:.2f} frames/s = {one * raw:.0%} of raw"
    )
    print(f"dataset, 2 workers: {two:.2f} frames/s = {two / one:.2f}x one worker")
    print(f"peak RSS of this process: {rss:.0f} MB")


if __name__ == "__main__":
    main()
