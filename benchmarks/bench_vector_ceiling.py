"""What the vector envs themselves allow: a stand-in env that only spins for a fixed time per
step, with a small or a 30-value info, through Gymnasium's ``AsyncVectorEnv`` (one env per
process) and ``agrinav_gym.make_vec`` (4 envs per worker), 1 and 2 workers each, interleaved.

The ratio a real env reaches in ``bench_env.py`` section 7 is bounded by these: whatever the
env, the main process's work per step and the pipes are paid the same way.

    python benchmarks/bench_vector_ceiling.py [--spin-us 700] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Any

import gymnasium as gym
import numpy as np

from agrinav_gym import vector

PER_WORKER = 4
ID = "bench_vector_ceiling:Spin-v0"


class Spin(gym.Env[dict[str, np.ndarray], np.ndarray]):
    """Spins ``spin_us`` per step; observations shaped like the state-only env's."""

    def __init__(self, spin_us: int = 700, info_keys: int = 2) -> None:
        self.spin = spin_us * 1e-6
        self.info = {f"k{i}": 0.1 for i in range(info_keys)}
        self.observation_space = gym.spaces.Dict(
            {k: gym.spaces.Box(-1e9, 1e9, (n,), np.float32) for k, n in (("a", 10), ("b", 40))}
        )
        self.action_space = gym.spaces.Box(-1, 1, (2,), np.float32)
        self._obs = {k: np.zeros(s.shape, np.float32) for k, s in self.observation_space.items()}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        super().reset(seed=seed)
        return {k: v.copy() for k, v in self._obs.items()}, {}

    def step(self, action: np.ndarray) -> Any:
        end = time.perf_counter() + self.spin
        while time.perf_counter() < end:
            pass
        return {k: v.copy() for k, v in self._obs.items()}, 0.0, False, False, dict(self.info)


gym.register("Spin-v0", entry_point="bench_vector_ceiling:Spin")


def _make(kind: str, workers: int, spin_us: int, info_keys: int) -> gym.vector.VectorEnv:
    kw = {"spin_us": spin_us, "info_keys": info_keys}
    if kind == "batched":
        return vector.BatchedVectorEnv(
            ID, PER_WORKER * workers, workers, kw, "spawn", gym.vector.AutoresetMode.NEXT_STEP
        )
    return gym.make_vec(
        ID, num_envs=workers, vectorization_mode="async", vector_kwargs={"context": "spawn"}, **kw
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spin-us", type=int, default=700)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--steps", type=int, default=600, help="env steps per timed run")
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores; stand-in step {args.spin_us} µs; median of {args.repeat}")
    for info_keys in (2, 30):
        envs = {
            (kind, n): _make(kind, n, args.spin_us, info_keys)
            for kind in ("async", "batched")
            for n in (1, 2)
        }
        rates: dict[tuple[str, int], list[float]] = {k: [] for k in envs}
        try:
            for venv in envs.values():
                venv.reset(seed=0)
            for _ in range(args.repeat):
                for key, venv in envs.items():
                    a = np.zeros((venv.num_envs, 2), np.float32)
                    n = max(1, args.steps // venv.num_envs)
                    t0 = time.perf_counter()
                    for _ in range(n):
                        venv.step(a)
                    rates[key].append(n * venv.num_envs / (time.perf_counter() - t0))
        finally:
            for venv in envs.values():
                venv.close()
        for kind, name in (("async", "AsyncVectorEnv, 1 env/process"), ("batched", "make_vec")):
            one = statistics.median(rates[kind, 1])
            two = statistics.median(rates[kind, 2])
            print(
                f"  {info_keys:2d}-value info, {name:30s}: 1 worker {one:5.0f} steps/s, "
                f"2 workers {two:5.0f}: {two / one:.2f}x"
            )
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
