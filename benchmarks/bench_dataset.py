"""Perception dataset throughput against the mesh camera's raw frame rate, side by side.

raw: the dataset's env (its randomized fields) with the 848×480 mesh camera rendering RGB,
depth and segmentation on every step, minus the same env and fields without a camera — the
camera's own cost per frame.
dataset: frames per second of ``generate`` writing whole shards (env construction, driving
between frames, labels, PNG/NPY encoding, tar writing, worker start-up included), the same
``--shards`` shards with 1 worker and with 2 workers. Medians of ``--repeat`` runs; ratios
within the run.

    python benchmarks/bench_dataset.py [--repeat 3] [--frames 16] [--shards 4]
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
from baselines.dataset.perception import DATASET_SCENARIO_SEEDS, make_env


def raw_frame_seconds(fields: int, n: int) -> float:
    """The mesh camera's own cost per frame on the dataset's fields: the spec's env rendering
    on every step minus the same env without a camera, on the same ``fields`` fields (reset
    seeds) and actions, interleaved."""
    spec = load_spec(None, {"frame_every": 1})
    cam = make_env(spec, 0.55, 25.0)
    bare = gym.make(
        spec.env,
        scenario=spec.preset,
        scenario_overrides={"field": {"length": spec.field_length}},
        randomize=spec.randomize,
        scenario_seeds=list(DATASET_SCENARIO_SEEDS),
        observations=["gps", "imu", "odom", "route"],
    )
    a = np.array([0.3, 0.0], np.float32)
    spent = {"cam": 0.0, "bare": 0.0}
    try:
        for k in range(fields):
            for name, env in (("cam", cam), ("bare", bare)):
                env.reset(seed=k)
                env.step(a)  # the first frame loads the tiles
                t = time.perf_counter()
                for _ in range(n):
                    env.step(a)
                spent[name] += time.perf_counter() - t
    finally:
        cam.close()
        bare.close()
    return (spent["cam"] - spent["bare"]) / (fields * n)


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
    ap.add_argument("--shards", type=int, default=4, help="shards per dataset run")
    a = ap.parse_args()
    n = a.frames * a.shards
    raw = statistics.median(raw_frame_seconds(4, 8) for _ in range(a.repeat))
    one = statistics.median(dataset_fps(n, a.frames, 1) for _ in range(a.repeat))
    two = statistics.median(dataset_fps(n, a.frames, 2) for _ in range(a.repeat))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}")
    print(
        f"mesh camera 848x480 RGB-D + segmentation on the dataset's fields: "
        f"{1 / raw:.2f} frames/s ({raw * 1e3:.0f} ms)"
    )
    print(
        f"dataset, 1 worker, {a.shards} shards of {a.frames} frames: {one:.2f} frames/s "
        f"= {one * raw:.0%} of raw"
    )
    print(f"dataset, 2 workers: {two:.2f} frames/s = {two / one:.2f}x one worker")
    print(f"peak RSS of this process: {rss:.0f} MB")


if __name__ == "__main__":
    main()
