"""Memory per reset stays within a budget (what a long training run may grow by).

A reset loads a fresh robot body (so no contact cache carries over from one episode to the
next); pybullet keeps ≈ 12 kB of every URDF load even after the body is removed
(benchmarks/bench_reset_memory.py measures it in a bare client). The budget, 25 kB per reset on
one field, lets 10⁴ episodes grow a process by at most 250 MB; keeping each episode's field
(the tiny field's terrain alone is 176 kB) would exceed it many times over. Measured
after ``malloc_trim(0)``: glibc otherwise keeps freed heap it may reuse, which is not growth.
"""

from __future__ import annotations

import ctypes
import gc
import sys

import pytest

from .helpers import make

BUDGET_KB = 25.0


def _rss_kb() -> int:
    ctypes.CDLL("libc.so.6").malloc_trim(0)
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS"))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and glibc")
@pytest.mark.parametrize("model", ["proxy", "mesh"])
def test_resets_on_one_field_stay_within_the_memory_budget(model: str) -> None:
    env = make(
        "AgriNav/FurrowFollowDepth-v3",
        config={"camera": {"model": model, "width": 32, "height": 24}},
    )
    try:
        for i in range(30):  # warm-up: caches, allocator pools
            env.reset(seed=i)
        gc.collect()
        before = _rss_kb()
        n = 200
        for i in range(30, 30 + n):
            env.reset(seed=i)
            env.step(env.action_space.sample())
        gc.collect()
        per_reset = (_rss_kb() - before) / n
    finally:
        env.close()
    assert per_reset < BUDGET_KB, per_reset
