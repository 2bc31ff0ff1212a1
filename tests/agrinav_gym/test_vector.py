"""``agrinav_gym.make_vec``: envs batched into worker processes give exactly what one
``SyncVectorEnv`` of the same envs gives, and bad arguments are refused in one line."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym
from agrinav_gym.vector import _join_info

from ..fields import TINY

ENV = "AgriNav/FurrowFollow-v3"
# A short step limit so that envs end (and autoreset) inside the drive, at different steps
# because each env starts on its own seed.
KW: dict[str, Any] = {"scenario_overrides": TINY, "max_episode_steps": 25}


def _drive(venv: Any, steps: int) -> list[tuple[Any, ...]]:
    out = [venv.reset(seed=7)]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1, 1, (venv.num_envs, 2)).astype(np.float32)
        out.append(venv.step(a))
    return out


def _same(a: Any, b: Any, where: str) -> None:
    if isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            _same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    else:
        x, y = np.asarray(a), np.asarray(b)
        assert x.dtype == y.dtype and x.shape == y.shape, where
        if x.dtype == object:  # final_obs: None or an env's observation
            for i, (p, q) in enumerate(zip(x, y, strict=True)):
                assert (p is None) == (q is None), where
                if p is not None:
                    _same(p, q, f"{where}[{i}]")
        else:
            np.testing.assert_array_equal(x, y, err_msg=where)


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep"])
def test_batched_workers_match_one_sync_vector_env(autoreset_mode: str) -> None:
    mode = gym.vector.AutoresetMode(autoreset_mode)
    sync = gym.make_vec(
        ENV, num_envs=3, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **KW
    )
    batched = agrinav_gym.make_vec(ENV, 3, workers=2, autoreset_mode=autoreset_mode, **KW)
    try:
        assert batched.sizes == (2, 1)
        assert batched.single_observation_space == sync.single_observation_space
        assert batched.observation_space == sync.observation_space
        assert batched.action_space == sync.action_space
        assert batched.metadata["autoreset_mode"] == mode
        a, b = _drive(sync, 60), _drive(batched, 60)
        ended = sum(int(np.sum(r[2] | r[3])) for r in a[1:])
        assert ended >= 3  # the drive crossed episode ends, so autoreset was compared too
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"step {i}")
        assert batched.get_attr("spec")[0].id == ENV
    finally:
        sync.close()
        batched.close()
    assert all(not p.is_alive() for p in batched.processes)


def test_info_join_blanks_keys_some_workers_lack() -> None:
    left = {"cte": np.array([0.1, 0.2]), "_cte": np.array([True, True])}
    right = {
        "cte": np.array([0.3]),
        "_cte": np.array([True]),
        "termination": np.array(["goal"], dtype=object),
        "_termination": np.array([True]),
        "metrics": {"rmse": np.array([0.05]), "_rmse": np.array([True])},
        "_metrics": np.array([True]),
    }
    out = _join_info([left, right], [2, 1])
    np.testing.assert_array_equal(out["cte"], [0.1, 0.2, 0.3])
    assert list(out["termination"]) == [None, None, "goal"]
    np.testing.assert_array_equal(out["_termination"], [False, False, True])
    np.testing.assert_array_equal(out["metrics"]["rmse"], [0.0, 0.0, 0.05])
    np.testing.assert_array_equal(out["metrics"]["_rmse"], [False, False, True])
    np.testing.assert_array_equal(out["_metrics"], [False, False, True])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"num_envs": 0}, "num_envs"),
        ({"num_envs": 2, "workers": 3}, "workers"),
        ({"num_envs": 2, "workers": 0}, "workers"),
        ({"num_envs": 2, "autoreset_mode": "Sometimes"}, "autoreset_mode"),
        ({"num_envs": 2, "context": "teleport"}, "context"),
        ({"num_envs": 2, "wrappers": ["RecordEpisodeStatistics"]}, "wrappers"),
        ({"num_envs": 2, "pin_workers": "yes"}, "pin_workers"),
    ],
)
def test_bad_arguments_are_refused_before_any_process_starts(
    kwargs: dict[str, Any], field: str
) -> None:
    with pytest.raises(agrinav_gym.InputError, match=field):
        agrinav_gym.make_vec(ENV, **kwargs)


def test_a_worker_that_cannot_build_its_env_names_itself_and_leaves_no_process() -> None:
    import multiprocessing as mp

    # bad input in a worker is the InputError one process raises: one line, not a traceback
    # per worker
    with pytest.raises(agrinav_gym.InputError) as info:
        agrinav_gym.make_vec(ENV, 2, workers=2, observations=["sonar"], **KW)
    assert info.value.field == "observations" and "\n" not in str(info.value)
    assert not [p for p in mp.active_children() if p.name.startswith("AgriNavBatched")]


def test_bad_calls_are_refused_before_any_worker_steps() -> None:
    """A batch of the wrong size (a longer one used to lose its extra rows silently, a
    shorter one stepped some envs only), odd seeds, calls after close and wrappers a worker
    cannot receive: one InputError each, and the envs stay in step."""
    with pytest.raises(agrinav_gym.InputError, match=r"wrappers\[0\]"):
        agrinav_gym.make_vec(ENV, 2, workers=2, wrappers=[lambda e: e], **KW)
    venv = agrinav_gym.make_vec(ENV, 4, workers=2, **KW)
    try:
        venv.reset(seed=np.int64(3))  # numpy's integers are integers
        for bad in (np.zeros((5, 2)), np.zeros((3, 2)), None, [[0, 0]] * 3 + [[0]]):
            with pytest.raises(agrinav_gym.InputError) as info:
                venv.step(bad)
            assert info.value.field == "actions" and "(4, 2)" in str(info.value)
        assert venv.get_attr("_steps") == (0, 0, 0, 0)
        venv.step(np.zeros((4, 2), np.float32))
        assert venv.get_attr("_steps") == (1, 1, 1, 1)
        for seed in (True, 1.0, "3", [1, 2]):
            with pytest.raises(agrinav_gym.InputError, match="seed"):
                venv.reset(seed=seed)
        with pytest.raises(agrinav_gym.InputError) as info:  # a worker's env refuses it
            venv.reset(seed=-1)
        assert info.value.field == "seed" and "\n" not in str(info.value)
    finally:
        venv.close()
    for call in (lambda: venv.step(np.zeros((4, 2))), lambda: venv.reset(), venv.render):
        with pytest.raises(agrinav_gym.InputError, match="after close"):
            call()


def test_an_id_registered_in_this_process_runs_in_the_workers(tmp_path: Any) -> None:
    import scenario_gen as sg

    sg.save(sg.generate(sg.preset("default", **TINY), 0), tmp_path / "tiny", preview=False)
    env_id = agrinav_gym.register_scenario("VectorTiny", tmp_path / "tiny")
    venv = agrinav_gym.make_vec(env_id, 2, workers=2)
    try:
        obs, _ = venv.reset(seed=0)
        assert venv.get_attr("spec")[1].id == env_id
        assert all(len(v) == 2 for v in obs.values())
    finally:
        venv.close()


def test_wrappers_wrap_every_env_and_set_attr_reaches_each() -> None:
    from gymnasium.wrappers import RecordEpisodeStatistics

    venv = agrinav_gym.make_vec(
        ENV, 3, workers=2, autoreset_mode="SameStep", wrappers=(RecordEpisodeStatistics,), **KW
    )
    try:
        venv.reset(seed=1)
        lengths = np.zeros(3, np.int64)
        for _ in range(30):  # past the 25-step limit: every env ends once
            *_, info = venv.step(np.zeros((3, 2), np.float32))
            if "final_info" in info:
                done = info["final_info"]["_episode"]
                lengths[done] = info["final_info"]["episode"]["l"][done]
        np.testing.assert_array_equal(lengths, 25)  # the wrapper's episode statistics
        venv.set_attr("marker", [1, 2, 3])
        assert venv.get_attr("marker") == (1, 2, 3)
        venv.set_attr("marker", 7)
        assert venv.get_attr("marker") == (7, 7, 7)
        with pytest.raises(agrinav_gym.InputError, match="values"):
            venv.set_attr("marker", [1, 2])
    finally:
        venv.close()


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_pinned_workers_each_keep_to_one_core_in_turn() -> None:
    import os

    cores = sorted(os.sched_getaffinity(0))
    venv = agrinav_gym.make_vec(ENV, 3, workers=3, pin_workers=True, **KW)
    try:
        got = [os.sched_getaffinity(p.pid) for p in venv.unwrapped.processes]
        assert got == [{cores[i % len(cores)]} for i in range(3)]
        assert os.sched_getaffinity(0) == set(cores)  # this process is left as it was
        obs, _ = venv.reset(seed=0)
        assert all(len(v) == 3 for v in obs.values())
    finally:
        venv.close()
