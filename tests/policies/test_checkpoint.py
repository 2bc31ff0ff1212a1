"""Checkpoints cannot run code; bad ones fail with one clear error; shipped ones load safely."""

import inspect
import json
import os
import pickle
import shutil
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from policies import checkpoint, make_policy, shipped_model
from scenario_gen import InputError

from ..fields import TINY

FR = "AgriNav/FieldRoute-v3"
OBS = ["imu", "odom", "route"]


class _Boom:
    """Unpickling this writes a marker file: proof that code ran."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path(self.marker).write_text, ("pwned",))


def _env() -> gym.Env:
    return gym.make(FR, scenario_overrides=TINY, observations=OBS)


def test_a_crafted_sb3_checkpoint_runs_nothing_without_trust(tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    bad = tmp_path / "bad"
    bad.mkdir()
    with zipfile.ZipFile(bad / "model.zip", "w") as z:
        z.writestr("data", json.dumps({"policy_class": {":serialized:": "x"}}))
        z.writestr("policy.pth", pickle.dumps(_Boom(str(marker))))
    (bad / "vecnormalize.pkl").write_bytes(pickle.dumps(_Boom(str(marker))))
    env = _env()
    try:
        for spec in (f"ppo:{bad}", f"ppo:{bad / 'model.zip'}"):
            with pytest.raises(InputError, match="trust-checkpoint"):
                make_policy(spec, env)
        # and the safe loader never unpickles: an object array in policy.npz is refused
        fake = tmp_path / "fake"
        shutil.copytree(shipped_model(FR), fake)
        arrays = dict(np.load(fake / "policy.npz"))
        arrays["log_std"] = np.array([_Boom(str(marker))], dtype=object)
        np.savez(fake / "policy.npz", **arrays)
        with pytest.raises(InputError, match="cannot be read as weights"):
            make_policy(f"ppo:{fake}", env)
    finally:
        env.close()
    assert not marker.exists()


def _shipped_copy(tmp_path: Path) -> Path:
    d = tmp_path / "ckpt"
    shutil.copytree(shipped_model(FR), d)
    return d


def _edit(d: Path, change: Any) -> None:
    """Apply ``change`` to the copy's checkpoint.json: a mapping of top-level keys to set, or a
    function editing the parsed document in place."""
    meta = json.loads((d / "checkpoint.json").read_text())
    if callable(change):
        change(meta)
    else:
        meta.update(change)
    (d / "checkpoint.json").write_text(json.dumps(meta))


def _swap_bounds(m: dict) -> None:
    box = m["action_space"]
    box["low"], box["high"] = box["high"], box["low"]


@pytest.mark.parametrize(
    "change,needle",
    [
        ({"normalization": None}, "normalisation statistics"),
        ({"policy": "os.system"}, "checkpoint policy"),
        ({"policy_kwargs": {"activation_fn": "Sigmoid"}}, "activation_fn"),
        ({"policy_kwargs": {"net_arch": [64, 64]}}, r"needs \(64"),
        ({"format": "pickle"}, "format"),
        ({"policy_kwargs": {"net_arch": [64, -3]}}, "net_arch"),
        ({"policy_kwargs": {"net_arch": {"pi": [10**6], "vf": [64]}}}, "net_arch"),
        (_swap_bounds, "low <= high"),
        (lambda m: m["normalization"].update(clip=-1.0), "clip > 0"),
        (lambda m: m["normalization"].update(epsilon=0.0), "epsilon > 0"),
    ],
)
def test_bad_checkpoints_give_one_clear_error(tmp_path: Path, change: Any, needle: str) -> None:
    """checkpoint.json is checked like a config: each edit is one clear error."""
    d = _shipped_copy(tmp_path)
    _edit(d, change)
    env = _env()
    try:
        with pytest.raises(InputError, match=needle):
            make_policy(f"ppo:{d}", env)
    finally:
        env.close()


def test_truncated_or_binary_files_are_refused(tmp_path: Path) -> None:
    d = _shipped_copy(tmp_path)
    (d / "policy.npz").write_bytes((d / "policy.npz").read_bytes()[:100])
    env = _env()
    try:
        with pytest.raises(InputError, match="cannot be read as weights"):
            make_policy(f"ppo:{d}", env)
        (d / "checkpoint.json").write_bytes(b"\x00\xff" * 10)
        with pytest.raises(InputError, match="checkpoint"):
            make_policy(f"ppo:{d}", env)
        with pytest.raises(InputError, match="checkpoint.json"):
            make_policy(f"ppo:{tmp_path / 'missing'}", env)
    finally:
        env.close()


def test_spaces_are_checked_against_the_env() -> None:
    env = gym.make(
        FR, scenario_overrides=TINY, observations=OBS, config={"task": {"route_points": 5}}
    )
    try:
        with pytest.raises(InputError, match="'route'"):
            make_policy("ppo:shipped", env)
    finally:
        env.close()


def test_round_trip_keeps_actions_and_normalisation(tmp_path: Path) -> None:
    loaded = checkpoint.load(shipped_model(FR))
    assert loaded.normalizer is not None
    d = tmp_path / "again"
    checkpoint.save(
        d,
        loaded.policy,
        "MultiInputPolicy",
        {"net_arch": [128, 128], "log_std_init": -1.0},
        None,
        {},
    )
    again = checkpoint.load(d)
    rng = np.random.default_rng(0)
    for _ in range(20):
        o = {
            k: rng.uniform(-1, 1, s.shape).astype(np.float32)
            for k, s in loaded.policy.observation_space.spaces.items()
        }
        a, _ = loaded.policy.predict(o, deterministic=True)
        b, _ = again.policy.predict(o, deterministic=True)
        np.testing.assert_array_equal(a, b)


def test_hyperparameter_file_is_readable_by_rl_baselines3_zoo() -> None:
    """Every key is one zoo consumes itself or a PPO constructor argument, n_timesteps is
    there, a dotted policy imports, and our own validation accepts every entry."""
    from importlib import import_module, resources

    import yaml
    from stable_baselines3 import PPO

    from baselines import hyperparams

    zoo_keys = {"n_envs", "n_timesteps", "normalize", "frame_stack", "env_wrapper", "callback"}
    ppo_args = set(inspect.signature(PPO.__init__).parameters) - {"self", "env"}
    table = yaml.safe_load(resources.files("baselines.hyperparams").joinpath("ppo.yml").read_text())
    for env_id, entry in table.items():
        assert set(entry) <= zoo_keys | ppo_args, set(entry) - zoo_keys - ppo_args
        assert "n_timesteps" in entry
        if "." in entry["policy"]:
            module, _, name = entry["policy"].rpartition(".")
            assert inspect.isclass(getattr(import_module(module), name))
        hyperparams.load(env_id)


def _npz_lying_about_its_shape(path: Path) -> None:
    """A member whose header claims 10¹⁰ float32s over a few bytes of data."""
    import io
    import zipfile

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": "<f4", "fortran_order": False, "shape": (10**10,)}
    )
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("w.npy", buf.getvalue() + b"\0" * 16)


def _npz_with_twin_members(path: Path) -> None:
    import io
    import warnings
    import zipfile

    buf = io.BytesIO()
    np.save(buf, np.zeros(3, np.float32))
    with warnings.catch_warnings(), zipfile.ZipFile(path, "w") as z:
        warnings.simplefilter("ignore")  # zipfile warns about the duplicate name itself
        z.writestr("w.npy", buf.getvalue())
        z.writestr("w.npy", buf.getvalue())


@pytest.mark.parametrize(
    "make,needle",
    [
        (lambda p: os.mkfifo(p), "regular file"),  # a FIFO blocked the loader forever
        (_npz_lying_about_its_shape, "claims 40,000,000,000 bytes"),
        (_npz_with_twin_members, "two members of the same name"),
    ],
)
def test_weights_are_checked_before_anything_is_read(tmp_path: Path, make, needle: str) -> None:  # type: ignore[no-untyped-def]
    from policies.checkpoint import read_npz

    path = tmp_path / "policy.npz"
    make(path)
    with pytest.raises(InputError, match=needle):
        read_npz(path, "checkpoint")


@pytest.mark.parametrize(
    "change,needle",
    [
        ({"num_timesteps": "lots"}, "num_timesteps"),
        ({"num_timesteps": -5}, "num_timesteps"),
        ({"num_timesteps": 1e300}, "num_timesteps"),
    ],
)
def test_a_corrupt_step_count_is_refused_naming_it(
    tmp_path: Path, change: dict, needle: str
) -> None:
    folder = tmp_path / "ck"
    shutil.copytree(shipped_model("AgriNav/FurrowFollow-v3"), folder)
    meta = json.loads((folder / "checkpoint.json").read_text())
    (folder / "checkpoint.json").write_text(json.dumps({**meta, **change}))
    with pytest.raises(InputError, match=needle):
        checkpoint.read_meta(folder)


def test_a_corrupt_normalisation_count_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "ck"
    shutil.copytree(shipped_model("AgriNav/FurrowFollow-v3"), folder)
    meta = json.loads((folder / "checkpoint.json").read_text())
    meta["normalization"]["count"] = {k: "x" for k in meta["normalization"]["count"]}
    (folder / "checkpoint.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="count"):
        checkpoint.load(folder)


def test_a_tensor_of_strings_is_refused_naming_it(tmp_path: Path) -> None:
    """np.isfinite on a string array was a TypeError from deep inside the loader."""
    d = _shipped_copy(tmp_path)
    with np.load(d / checkpoint.WEIGHTS) as npz:
        arrays = {k: npz[k] for k in npz.files}
    name = sorted(arrays)[0]
    arrays[name] = np.array(["a"] * arrays[name].size).reshape(arrays[name].shape)
    np.savez(d / checkpoint.WEIGHTS, **arrays)
    env = _env()
    try:
        with pytest.raises(InputError, match=f"tensor {name} holds <U1 values; allowed: numbers"):
            make_policy(f"ppo:{d}", env)
    finally:
        env.close()


def test_a_policy_of_another_kind_of_observation_is_refused_in_one_line() -> None:
    """An SB3 model of a Box-observation env (CartPole) was an AttributeError traceback."""
    from gymnasium import spaces

    from policies.ppo import check_spaces

    env = _env()
    try:
        u = env.unwrapped
        box = spaces.Box(-1.0, 1.0, (4,))
        with pytest.raises(InputError, match="trained on a Box observation space"):
            check_spaces(box, u.observation_space, u.action_space, u.action_space, "cartpole")
    finally:
        env.close()
