"""SB3 over ``make_vec``: a model sees through ``BatchedSB3VecEnv`` exactly what it sees
through SB3's own vector env of the same envs and seeds."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

from baselines.sb3_vec import BatchedSB3VecEnv, unbatch_info
from scenario_gen.errors import InputError

from ..fields import TINY

ENV = "AgriNav/FurrowFollow-v3"
# short episodes, each env on its own seed: they end (and reset) at different steps
KW: dict[str, Any] = {"scenario_overrides": TINY, "max_episode_steps": 25}


def _same(a: Any, b: Any, where: str) -> None:
    if isinstance(a, dict):
        assert sorted(a) == sorted(b), where
        for k in a:
            _same(a[k], b[k], f"{where}.{k}")
    else:
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=where)


def test_batched_sb3_vec_env_matches_sb3s_own_step_for_step() -> None:
    ref = make_vec_env(
        f"agrinav_gym:{ENV}", n_envs=3, seed=11, vec_env_cls=DummyVecEnv, env_kwargs=KW
    )
    ours = BatchedSB3VecEnv(ENV, 3, workers=2, env_kwargs=KW)
    try:
        assert ours.workers == 2 and ours.observation_space == ref.observation_space
        ours.seed(11)
        _same(ref.reset(), ours.reset(), "reset")
        rng = np.random.default_rng(0)
        ends = 0
        for t in range(60):
            a = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
            o1, r1, d1, i1 = ref.step(a)
            o2, r2, d2, i2 = ours.step(a)
            _same(o1, o2, f"obs {t}")
            np.testing.assert_array_equal(r1, r2.astype(r1.dtype))  # DummyVecEnv: float32
            np.testing.assert_array_equal(d1, d2)
            for k in range(3):
                e1, e2 = dict(i1[k]), dict(i2[k])
                if d1[k]:
                    ends += 1
                    _same(e1.pop("terminal_observation"), e2.pop("terminal_observation"), "final")
                    assert e1.pop("TimeLimit.truncated") == e2.pop("TimeLimit.truncated")
                    m1, m2 = e1.pop("episode"), e2.pop("episode")
                    assert m1["l"] == m2["l"] and m1["r"] == pytest.approx(m2["r"], abs=1e-5)
                _same(e1, e2, f"info {t}/{k}")
        assert ends >= 3  # every env ended at least once: the autoreset path was compared
        assert ours.env_is_wrapped(Monitor) == [False] * 3
        assert ours.get_attr("dt") == ref.get_attr("dt")
    finally:
        ref.close()
        ours.close()


def test_unbatch_info_keeps_only_what_each_env_had() -> None:
    info = {
        "a": np.array([1.5, 0.0]),
        "_a": np.array([True, False]),
        "d": {"x": np.array([1, 2]), "_x": np.array([True, True])},
        "_d": np.array([True, True]),
    }
    assert unbatch_info(info, 2) == [{"a": 1.5, "d": {"x": 1}}, {"d": {"x": 2}}]


def test_a_subset_of_envs_is_refused_where_every_env_is_meant() -> None:
    venv = BatchedSB3VecEnv(ENV, 2, workers=1, env_kwargs=KW)
    try:
        with pytest.raises(InputError, match="indices"):
            venv.env_method("close", indices=[0])
    finally:
        venv.close()
