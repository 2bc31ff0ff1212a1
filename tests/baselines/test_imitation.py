"""The PPO warm start: demonstrations, their returns, and the clone fitting them."""

from __future__ import annotations

import numpy as np
import pytest

from baselines import hyperparams as hpmod
from baselines.imitation import WarmStart, _discounted, clone, demonstrate
from scenario_gen.errors import InputError

TINY = {"field": {"width": 6.0, "length": 10.0}, "layout": {"headland": 2.0}}
KWARGS = {"scenario_overrides": TINY, "observations": ["imu", "odom", "route"]}


def test_discounted_returns_run_backwards_from_the_end() -> None:
    r = np.array([1.0, 0.0, 2.0])
    assert _discounted(r, 0.5).tolist() == [1.5, 1.0, 2.0]


def test_demonstrations_label_the_controllers_own_actions() -> None:
    ws = WarmStart(episodes=1, steer_noise=0.0)
    d = demonstrate("AgriNav/FurrowFollow-v3", KWARGS, ws, 0.99, seed=0)
    again = demonstrate("AgriNav/FurrowFollow-v3", KWARGS, ws, 0.99, seed=0)
    assert len(d) > 50 and d.successes == 1  # RPP drives a short straight lane to its end
    assert set(d.obs) == {"imu", "odom", "route"} and d.obs["route"].shape == (len(d), 30)
    np.testing.assert_array_equal(d.actions, again.actions)  # one seed, one rollout
    # with a perturbation executed the labels stay the controller's: they differ from what
    # was driven, but the states still come from a driven lane
    noisy = demonstrate("AgriNav/FurrowFollow-v3", KWARGS, WarmStart(episodes=1), 0.99, seed=0)
    assert noisy.successes == 1 and not np.array_equal(noisy.actions[:50], d.actions[:50])


def test_the_clone_fits_the_demonstrated_actions_and_returns() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    d = demonstrate("AgriNav/FurrowFollow-v3", KWARGS, WarmStart(episodes=1), 0.95, seed=1)
    venv = VecNormalize(make_vec_env("agrinav_gym:AgriNav/FurrowFollow-v3", 1, env_kwargs=KWARGS))
    try:
        model = PPO("MultiInputPolicy", venv, seed=0, n_steps=64, batch_size=64)
        before = clone(model, venv, d, WarmStart(epochs=1, learning_rate=1e-12), seed=0)
        after = clone(model, venv, d, WarmStart(epochs=200), seed=0)
    finally:
        venv.close()
    # the returns' spread is the scale the critic must learn: it must explain most of it
    assert after["action_mse"] < 0.25 * before["action_mse"]
    assert after["value_mse"] < 0.25 * float(np.var(d.returns))
    # the normaliser starts from the demonstrations' statistics
    np.testing.assert_allclose(venv.obs_rms["odom"].mean, d.obs["odom"].mean(axis=0), rtol=1e-5)


def test_a_bad_warm_start_section_is_refused() -> None:
    import dataclasses

    _, setup = hpmod.load("AgriNav/FieldRoute-v3")
    assert setup.warm("AgriNav/FieldRoute-v3").policy == "rpp"
    bad = dataclasses.replace(setup, warm_start={"policy": "rpp", "episdoes": 3})
    with pytest.raises(InputError, match="episdoes"):
        bad.warm("AgriNav/FieldRoute-v3")
    bad = dataclasses.replace(setup, warm_start={"policy": "pid"})
    with pytest.raises(InputError, match="pid"):
        bad.warm("AgriNav/FieldRoute-v3")
