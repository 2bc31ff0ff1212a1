"""The ONNX actor acts as the torch policy does: raw observations in (normalisation folded in),
the clipped deterministic action out; checked with onnxruntime on space samples and real steps."""

from __future__ import annotations

import json
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from policies import checkpoint, make_policy, shipped_model
from policies.onnx_export import OUTPUT, actor_graph, onnx_actions, torch_actions
from scenario_gen import InputError

from ..fields import TINY

pytest.importorskip("onnx", reason="the export extra is not installed")
pytest.importorskip("onnxruntime", reason="the export extra is not installed")

FR = "AgriNav/FieldRoute-v3"
OBS = ["imu", "odom", "route"]


def _stack(observations: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    return {k: np.stack([o[k] for o in observations]) for k in observations[0]}


def observations(env: gym.Env, policy: Any, space_samples: int, steps: int) -> list[dict]:
    """``space_samples`` drawn from the env's observation space, then ``steps`` observations of
    ``policy`` driving the env (reset when an episode ends)."""
    space = env.observation_space
    space.seed(0)
    out = [space.sample() for _ in range(space_samples)]
    obs, _ = env.reset(seed=10**9)
    for i in range(steps):
        out.append(obs)
        obs, _, term, trunc, _ = env.step(policy.act(obs))
        if term or trunc:
            obs, _ = env.reset(seed=10**9 + i)
    return out


def test_onnx_actor_matches_the_torch_policy_on_1000_observations() -> None:
    env = gym.make(FR, scenario_overrides=TINY, observations=OBS)
    try:
        policy = make_policy("ppo:shipped", env)
        obs = observations(env, policy, 500, 500)
    finally:
        env.close()
    loaded = checkpoint.load(shipped_model(FR))
    assert loaded.normalizer is not None  # the case that needs the folding
    model = actor_graph(loaded)
    got = onnx_actions(model, _stack(obs))
    want = np.stack([policy.act(o) for o in obs])
    diff = float(np.abs(got - want).max())
    assert diff <= 1e-5, diff
    assert got.dtype == np.float32 and got.shape == (1000, 2)
    assert np.ptp(want[500:], axis=0).min() > 0.1  # the real steps exercise the network

    import onnx

    proto = onnx.load_from_string(model)
    assert [i.name for i in proto.graph.input] == OBS  # one input per key, sorted
    assert [o.name for o in proto.graph.output] == [OUTPUT]
    props = {p.key: p.value for p in proto.metadata_props}
    inputs = json.loads(props["agrinav.inputs"])
    assert [(d["name"], d["shape"]) for d in inputs] == [
        ("imu", ["batch", 10]),
        ("odom", ["batch", 2]),
        ("route", ["batch", 30]),
    ]
    assert inputs[0]["fields"][:3] == ["fx", "fy", "fz"]
    assert inputs[2]["fields"][:3] == ["x0", "y0", "furrow0"]
    assert "folded in" in props["agrinav.normalization"]


def test_the_depth_cnn_exports_too() -> None:
    loaded = checkpoint.load(shipped_model("AgriNav/FurrowFollowDepth-v3"))
    space = loaded.policy.observation_space
    space.seed(1)
    batch = _stack([space.sample() for _ in range(200)])
    model = actor_graph(loaded)
    diff = float(np.abs(onnx_actions(model, batch) - torch_actions(loaded, batch)).max())
    assert diff <= 1e-5, diff


def test_a_layer_outside_the_list_is_refused_by_name() -> None:
    from torch import nn

    loaded = checkpoint.load(shipped_model(FR))
    loaded.policy.mlp_extractor.policy_net[1] = nn.Sigmoid()
    with pytest.raises(InputError, match="layer Sigmoid"):
        actor_graph(loaded)
