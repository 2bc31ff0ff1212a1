"""Soak: memory stays flat over long use (slow; `make test-all`)."""

import gc

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401

from .helpers import TINY

BOUND = 50 * 2**20  # bytes of RSS growth allowed after warm-up


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


@pytest.mark.slow
def test_rss_stays_flat_over_steps_resets_and_env_lifetimes() -> None:
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(2000):  # warm-up: caches, allocator pools
        if any(env.step(rng.uniform(-0.2, 1, 2).astype(np.float32))[2:4]):
            env.reset()
    base = _rss()
    for _ in range(100_000):
        if any(env.step(rng.uniform(-0.2, 1, 2).astype(np.float32))[2:4]):
            env.reset()
    assert _rss() - base < BOUND, "100k steps"
    env.close()

    env = gym.make(
        "AgriNav/FurrowFollow-v3",
        scenario_overrides=TINY,
        randomize={"crop.stage": [1, 5], "layout.plant_spacing": [0.15, 0.3]},
    )
    for i in range(20):
        env.reset(seed=i)
    base = _rss()
    for i in range(1000):
        env.reset(seed=100 + i)
        env.step(np.array([0.5, 0.0], np.float32))
    assert _rss() - base < BOUND, "1000 randomized resets"
    env.close()

    for _ in range(10):
        gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY).close()
    gc.collect()
    base = _rss()
    for i in range(200):
        e = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)
        e.reset(seed=i)
        e.close()
    gc.collect()
    assert _rss() - base < BOUND, "200 make/close cycles"
