"""Gymnasium-suite style checks over every registered AgriNav id."""

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import agrinav_gym
from agrinav_gym.scenarios import FixedFieldWarning

from .helpers import TINY, make

IDS = list(agrinav_gym.ENV_IDS)

# SB3's checker flags any 3-D float observation as "an image that is not uint8". The depth
# observation is metric float32 on purpose (metres, 0 = invalid, as the D455 reports), so these
# two messages are expected for envs that observe depth — and only for those.
DEPTH_IMAGE_WARNINGS = ("is an image but its `dtype`", "is an image but the upper and lower")


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_check_env(env_id: str) -> None:
    """The full checker, render check included: it makes the env in every declared render
    mode, so a mode that cannot work here (``human`` without a display) must not be declared."""
    env = make(env_id)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            # the checker makes envs of its own: their one-field notice is not its finding
            warnings.filterwarnings("ignore", category=FixedFieldWarning)
            check_env(env.unwrapped)
        assert [str(w.message) for w in caught] == []
    finally:
        env.close()


def test_human_mode_is_declared_only_with_a_display() -> None:
    from agrinav_gym.env import AgriNavEnv

    modes = AgriNavEnv.metadata["render_modes"]
    assert "rgb_array" in modes
    import os

    assert ("human" in modes) == bool(os.environ.get("DISPLAY"))
    if "human" not in modes:
        from agrinav_gym.envs import FurrowFollowEnv

        with pytest.raises(agrinav_gym.InputError, match="display"):
            FurrowFollowEnv(scenario_overrides=TINY, render_mode="human")


@pytest.mark.parametrize("env_id", IDS)
def test_gym_make_human_headless_is_refused_in_one_line(
    env_id: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Not wrapped in Gymnasium's pygame HumanRendering (which fails at the first reset)."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.raises(agrinav_gym.InputError, match="needs a display"):
        gym.make(env_id, render_mode="human", scenario_overrides=TINY)


@pytest.mark.parametrize("env_id", ["AgriNav/FurrowFollowDepth-v3", "AgriNav/FieldRoute-v3"])
def test_camera_extras_and_fresh_arrays_every_step(env_id: str) -> None:
    """info carries the current RGB and segmentation after every step at every camera rate,
    and every observation is a new array (nothing the caller keeps changes under it)."""
    for rate in (20, 5):
        env = make(env_id, config={"camera": {"rgb": True, "segmentation": True, "rate_hz": rate}})
        try:
            obs, info = env.reset(seed=0)
            assert info["rgb"].shape == (48, 64, 3) and info["segmentation"].shape == (48, 64)
            kept = {k: v.copy() for k, v in obs.items()}
            held = obs
            for _ in range(6):
                obs, _, _, _, info = env.step(np.array([0.4, 0.0], np.float32))
                assert "rgb" in info and "segmentation" in info
                for k in obs:
                    assert not np.shares_memory(obs[k], held[k])
                    np.testing.assert_array_equal(held[k], kept[k])  # the old one is untouched
        finally:
            env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_sb3_check_env(env_id: str) -> None:
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = make(env_id)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sb3_check(env.unwrapped)
        messages = [str(w.message) for w in caught]
        unexplained = [m for m in messages if not any(d in m for d in DEPTH_IMAGE_WARNINGS)]
        assert unexplained == []
        if "depth" not in env.unwrapped.observation_names:
            assert messages == []
    finally:
        env.close()


def _rollout(env: gym.Env, seed: int, steps: int = 40) -> list:
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(rng.uniform(-0.3, 1.0, 2).astype(np.float32))
        out.append((obs, r, term, trunc, info["cte"]))
        if term or trunc:
            obs, _ = env.reset()
            out.append(obs)
    return out


def _same(a: object, b: object) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)  # type: ignore[attr-defined]
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))  # type: ignore[arg-type]
    return bool(np.array_equal(a, b))


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_rollout(env_id: str) -> None:
    a, b, c = make(env_id), make(env_id), make(env_id)
    try:
        ra, rb, rc = _rollout(a, 3), _rollout(b, 3), _rollout(c, 4)
        assert _same(ra, rb)
        assert not _same(ra, rc)
    finally:
        a.close()
        b.close()
        c.close()


@pytest.mark.parametrize("env_id", IDS)
def test_observations_come_in_the_spaces_key_order(env_id: str) -> None:
    """gymnasium's Dict sorts its keys: an observation in the same order lines up with
    ``flatten(space, obs)`` when a user concatenates its values."""
    from gymnasium import spaces

    env = make(env_id)
    try:
        obs, _ = env.reset(seed=0)
        keys = list(env.observation_space.spaces)
        assert list(obs) == keys
        obs, *_ = env.step(env.action_space.sample())
        assert list(obs) == keys
        flat = np.concatenate([np.ravel(obs[k]) for k in obs])
        np.testing.assert_array_equal(flat, spaces.flatten(env.observation_space, obs))
    finally:
        env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_env_pickles(env_id: str) -> None:
    env = make(env_id)
    try:
        clone = pickle.loads(pickle.dumps(env))
        try:
            assert _same(_rollout(env, 1, 10), _rollout(clone, 1, 10))
        finally:
            clone.close()
    finally:
        env.close()


def test_async_vector_env() -> None:
    envs = gym.vector.AsyncVectorEnv(
        [lambda: gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)] * 2
    )
    try:
        obs, _ = envs.reset(seed=[0, 1])
        assert obs["route"].shape == (2, 30)
        for _ in range(5):
            obs, r, _term, _trunc, _info = envs.step(
                np.tile([[0.5, 0.0]], (2, 1)).astype(np.float32)
            )
        assert r.shape == (2,) and np.isfinite(r).all()
    finally:
        envs.close()


def test_sb3_subproc_vec_env() -> None:
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # forkserver workers start fresh: the "module:id" form imports agrinav_gym there first
    venv = make_vec_env(
        "agrinav_gym:AgriNav/FurrowFollow-v3",
        n_envs=2,
        seed=0,
        vec_env_cls=SubprocVecEnv,
        env_kwargs={"scenario_overrides": TINY},
    )
    try:
        obs = venv.reset()
        for _ in range(5):
            obs, r, _done, _info = venv.step(np.tile([[0.5, 0.0]], (2, 1)))
        assert obs["imu"].shape == (2, 10) and r.shape == (2,)
    finally:
        venv.close()


def test_registration_is_idempotent_and_namespaced() -> None:
    agrinav_gym.register_envs()
    agrinav_gym.register_envs()
    ids = [i for i in gym.registry if i.startswith("AgriNav/")]
    assert set(IDS) <= set(ids)
    for env_id in IDS:
        env_cls = gym.spec(env_id)
        assert env_cls.max_episode_steps is not None
        doc = gym.make(env_id, scenario_overrides=TINY).unwrapped.__doc__ or ""
        for section in (
            "## Description",
            "## Action Space",
            "## Observation Space",
            "## Rewards",
            "## Starting State",
            "## Episode End",
            "## Arguments",
            "## Version History",
        ):
            assert section in doc, (env_id, section)
        # the history names the registered version, as Gymnasium's envs do
        version = env_id.rpartition("-v")[2]
        assert f"* v{version}:" in doc.partition("## Version History")[2], env_id


def test_rgb_array_render() -> None:
    env = make(render_mode="rgb_array")
    try:
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
        assert frame.std() > 5  # not a blank image: terrain, robot and plants are drawn
    finally:
        env.close()


def test_design_notes_list_every_observation_with_its_shape() -> None:
    """docs/design.md's observation table is the users' reference: it must match the code."""
    from pathlib import Path

    from agrinav_gym.interface import GPS_FIELDS, IMU_FIELDS, ODOM_FIELDS
    from agrinav_gym.observations import OBSERVATION_MODELS

    text = (Path(__file__).resolve().parents[2] / "docs" / "design.md").read_text()
    rows = {
        line.split("|")[1].strip(" `"): line for line in text.splitlines() if line.startswith("| `")
    }
    assert set(OBSERVATION_MODELS) <= set(rows)
    for key, n in (("gps", len(GPS_FIELDS)), ("imu", len(IMU_FIELDS)), ("odom", len(ODOM_FIELDS))):
        assert f"| ({n},) |" in rows[key]


@pytest.mark.parametrize("old", ["v0", "v1", "v2"])
def test_older_ids_point_to_the_current_version(old: str) -> None:
    from gymnasium.error import DeprecatedEnv

    with pytest.raises(DeprecatedEnv, match="AgriNav/FurrowFollow-v3"):
        gym.make(f"AgriNav/FurrowFollow-{old}")


def test_an_env_that_drives_one_field_says_so_once() -> None:
    """Without randomized scenario keys or a bank every reset reuses one field: a one-line
    notice when the env is made, none at its resets, none where a field is drawn per reset."""

    def notices(caught: list[warnings.WarningMessage]) -> list[str]:
        return [str(w.message) for w in caught if issubclass(w.category, FixedFieldWarning)]

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = make(scenario_seeds=[0, 10])
        try:
            env.reset(seed=0)
            env.reset(seed=1)
        finally:
            env.close()
        drawn = make(randomize={"layout.plant_spacing": [0.15, 0.25]})
        drawn.close()
        only_soil = make(randomize={"soil_colour": [[0.3, 0.2, 0.1], [0.5, 0.4, 0.3]]})
        only_soil.close()
    said = notices(caught)
    assert len(said) == 2, said  # the fixed env's and the one randomizing the soil alone
    assert said[0].startswith("FurrowFollowEnv: every reset drives one field, preset 'default'")
    assert "scenario_seeds alone changes nothing" in said[0] and "randomize=" in said[0]
    assert all("\n" not in m for m in said)
