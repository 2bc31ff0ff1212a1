import numpy as np
import pytest

from .helpers import FLAT, STILL, make


def test_reward_parts_have_the_right_signs() -> None:
    env = make(scenario_overrides=FLAT, config=STILL)
    try:
        env.reset(seed=0, options={"lane": 3})
        parts_seen = []
        for i in range(30):
            a = np.array([1.0, 0.3 if i % 2 else -0.3], np.float32)
            _, r, _term, _, info = env.step(a)
            parts_seen.append(info["rewards"])
        p = parts_seen[-1]
        assert set(p) == {"progress", "cte", "heading", "crop_contact", "action_rate", "terminal"}
        assert p["progress"] > 0  # driving along the lane
        assert all(
            q["cte"] <= 0 and q["heading"] <= 0 and q["crop_contact"] <= 0 and q["action_rate"] <= 0
            for q in parts_seen
        )
        assert any(q["action_rate"] < 0 for q in parts_seen)
        assert r == pytest.approx(sum(p.values()))
    finally:
        env.close()
    # reversing makes progress negative
    env = make(scenario_overrides=FLAT, config=STILL)
    try:
        env.reset(seed=0, options={"lane": 3})
        for _ in range(15):
            _, _, _, _, info = env.step(np.array([-1.0, 0.0], np.float32))
        assert info["rewards"]["progress"] < 0
    finally:
        env.close()


def test_leaving_the_corridor_is_a_failure_with_negative_terminal() -> None:
    env = make(scenario_overrides=FLAT, config={"task": {"corridor": 0.05}})
    try:
        env.reset(seed=0, options={"lane": 3})
        for _ in range(200):
            _, _, term, _trunc, info = env.step(np.array([0.5, 1.0], np.float32))
            if term:
                break
        assert term and info["termination"] == "corridor"
        assert info["rewards"]["terminal"] < 0 and not info["is_success"]
        assert "metrics" in info and info["metrics"]["completion"] < 100
    finally:
        env.close()


def test_success_at_the_lane_end() -> None:
    env = make(
        scenario_overrides=FLAT, config={**STILL, "task": {**STILL["task"], "max_crops_hit": 10**6}}
    )
    try:
        obs, _ = env.reset(seed=0, options={"lane": 3})
        for _ in range(600):
            route = obs["route"].reshape(-1, 3)
            steer = float(np.clip(2.0 * route[2, 1], -1, 1))  # aim at a point 1.2 m ahead
            obs, _, term, trunc, info = env.step(np.array([1.0, steer], np.float32))
            if term or trunc:
                break
        assert term and info["is_success"] and info["termination"] == "success"
        assert info["rewards"]["terminal"] > 0
        m = info["metrics"]
        assert m["completion"] > 95 and m["rmse"] < 0.05
        # inside the corridor the tracked nearest segment is the global one: the running
        # metrics equal a full recomputation from the pose log
        exact = env.unwrapped.episode_metrics()
        for key in ("rmse", "mae", "max", "in_furrow_rmse", "poses", "crops_hit"):
            assert m[key] == pytest.approx(exact[key], rel=1e-9, abs=1e-12), key
    finally:
        env.close()


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf]])
def test_nan_action_is_a_clear_error(bad: list) -> None:
    env = make()
    try:
        env.reset(seed=0)
        with pytest.raises(ValueError, match="action"):
            env.step(np.array(bad, np.float32))
        with pytest.raises(ValueError, match="shape"):
            env.step(np.zeros(3, np.float32))
    finally:
        env.close()


def test_out_of_range_action_is_clipped() -> None:
    a, b = make(), make()
    try:
        a.reset(seed=2)
        b.reset(seed=2)
        for _ in range(10):
            oa, ra, *_ = a.step(np.array([5.0, -3.0], np.float32))
            ob, rb, *_ = b.step(np.array([1.0, -1.0], np.float32))
        np.testing.assert_array_equal(oa["route"], ob["route"])
        assert ra == rb
    finally:
        a.close()
        b.close()


def test_progress_weighted_by_cross_track_error() -> None:
    """With ``reward.progress.cte_scale`` = k, progress pays exp(−|cte| / (k·corridor)) of it."""
    k = 0.1
    runs = []
    for reward in ({}, {"progress": {"cte_scale": k}}):
        env = make(scenario_overrides=FLAT, config={**STILL, "reward": reward})
        try:
            env.reset(seed=0, options={"lane": 3})
            steps = []
            for i in range(40):  # weave so that the error is not zero
                a = np.array([0.8, 0.4 if (i // 10) % 2 else -0.4], np.float32)
                _, r, _, _, info = env.step(a)
                steps.append((info["rewards"]["progress"], info["cte"], r, info["rewards"]))
            corridor = 0.5 * env.unwrapped.scenario.rows.spacing
            runs.append(steps)
        finally:
            env.close()
    plain, weighted = runs
    errors = []
    for (p0, cte0, _, _), (p1, cte1, r1, parts1) in zip(plain, weighted, strict=True):
        assert cte1 == cte0  # the reward does not change the physics
        assert p1 == pytest.approx(p0 * np.exp(-abs(cte0) / (k * corridor)), rel=1e-9)
        assert r1 == pytest.approx(sum(parts1.values()))
        errors.append(abs(cte0))
    assert max(errors) > 0.02  # the weighting was exercised, not just a factor of ~1
