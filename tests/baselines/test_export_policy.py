"""``agrinav export-policy``: ONNX and Stable-Baselines3 / rl-baselines3-zoo files that act as
the project's policy does, written atomically; zoo runs read back with their normalisation."""

from __future__ import annotations

import json
import shutil
import sys
import warnings
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

import agrinav_gym  # noqa: F401
from baselines.cli import main
from policies import make_policy
from scenario_gen import InputError

from ..fields import TINY
from ..policies.test_onnx_export import observations

FR = "AgriNav/FieldRoute-v3"
OBS = ["imu", "odom", "route"]
#: rl-baselines3-zoo's names: the env id with "/" as "-"; run folders <log>/<algo>/<env>_<n>
ZOO_ENV = "AgriNav-FieldRoute-v3"


def _env() -> gym.Env:
    return gym.make(FR, scenario_overrides=TINY, observations=OBS)


def _export(tmp_path: Path, to: str, capsys: pytest.CaptureFixture[str]) -> Path:
    out = tmp_path / to
    assert main(["export-policy", f"shipped:{FR}", "--to", to, "--out", str(out)]) == 0
    assert "max_abs_diff" in capsys.readouterr().out
    assert (out / ".agrinav-output").is_file() and (out / "README.md").is_file()
    assert [p.name for p in tmp_path.iterdir()] == [to]  # no temporaries, no lock left
    return out


def test_onnx_export_writes_the_model_and_its_layout(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("onnxruntime", reason="the export extra is not installed")
    from policies.onnx_export import onnx_actions

    out = _export(tmp_path, "onnx", capsys)
    readme = (out / "README.md").read_text()
    assert "| `route` | (batch, 30) |" in readme and "float64" in readme
    env = _env()
    try:
        policy = make_policy("ppo:shipped", env)
        obs = observations(env, policy, 0, 200)
    finally:
        env.close()
    batch = {k: np.stack([o[k] for o in obs]) for k in OBS}
    got = onnx_actions((out / "policy.onnx").read_bytes(), batch)
    assert np.abs(got - np.stack([policy.act(o) for o in obs])).max() <= 1e-5


def test_sb3_export_is_a_zoo_run_that_sb3_runs_as_our_policy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    out = _export(tmp_path, "sb3", capsys)
    # rl-baselines3-zoo's enjoy: -f OUT --exp-id 1 -> OUT/ppo/<env>_1/<env>.zip, its statistics
    # and records in OUT/ppo/<env>_1/<env>/ (config.yml read with yaml's unsafe loader)
    run = out / "ppo" / f"{ZOO_ENV}_1"
    stats = run / ZOO_ENV
    config = yaml.load((stats / "config.yml").read_text(), Loader=yaml.UnsafeLoader)
    args = yaml.load((stats / "args.yml").read_text(), Loader=yaml.UnsafeLoader)
    assert config["normalize"] == {"norm_obs": True, "norm_reward": False}
    assert config["policy"] == "MultiInputPolicy" and config["n_timesteps"] == 1_000_000
    assert args["env"] == FR and args["env_kwargs"]["observations"] == OBS
    assert "agrinav_gym" in args["gym_packages"]

    env = _env()
    venv = DummyVecEnv([lambda: _env()])
    try:
        policy = make_policy("ppo:shipped", env)
        obs = observations(env, policy, 500, 500)
        model = PPO.load(run / f"{ZOO_ENV}.zip", device="cpu")
        vn = VecNormalize.load(str(stats / "vecnormalize.pkl"), venv)
        vn.training, vn.norm_reward = False, False
        assert model.num_timesteps == 1_003_520
        batch = {k: np.stack([o[k] for o in obs]) for k in OBS}
        got, _ = model.predict(vn.normalize_obs(batch), deterministic=True)
        want = np.stack([policy.act(o) for o in obs])
        assert np.abs(got - want).max() <= 1e-5
    finally:
        env.close()
        venv.close()


def _trusted(spec: str, env: gym.Env) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the --trust-checkpoint warning
        return make_policy(spec, env, trust_checkpoint=True)


def test_a_zoo_run_loads_with_its_normalisation_or_not_at_all(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--trust-checkpoint on zoo's layout used to miss <env>/vecnormalize.pkl and run the
    policy on raw observations; it now reads the statistics, or refuses naming the file."""
    run = _export(tmp_path, "sb3", capsys) / "ppo" / f"{ZOO_ENV}_1"
    env = _env()
    try:
        ours = make_policy("ppo:shipped", env)
        obs = observations(env, ours, 100, 100)
        for spec in (f"ppo:{run}", f"ppo:{run / f'{ZOO_ENV}.zip'}"):
            zoo = _trusted(spec, env)
            assert zoo.normalize is not None
            assert max(np.abs(zoo.act(o) - ours.act(o)).max() for o in obs) <= 1e-5
        with pytest.raises(InputError, match="trust-checkpoint"):
            make_policy(f"ppo:{run}", env)  # never unpickled without trust
        stats = run / ZOO_ENV / "vecnormalize.pkl"
        stats.write_bytes(stats.read_bytes()[:40])  # truncated
        with pytest.raises(InputError, match=r"cannot be unpickled \(UnpicklingError"):
            _trusted(f"ppo:{run}", env)
        stats.unlink()
        with pytest.raises(
            InputError,
            match=r"vecnormalize\.pkl'; not found at .*AgriNav-FieldRoute-v3/vecnormalize\.pkl",
        ):
            _trusted(f"ppo:{run}", env)
        model = tmp_path / "model.zip"
        model.write_bytes(b"PK\x03\x04 not really a zip")  # malformed
        with pytest.raises(InputError, match="cannot be loaded as a Stable-Baselines3 PPO model"):
            _trusted(f"ppo:{model}", env)
    finally:
        env.close()


def test_a_lone_zip_is_noted_and_another_algorithm_is_refused_by_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A normalised policy's zip copied without its vecnormalize.pkl ran on raw observations
    without a word; a SAC or DQN zip failed inside PPO.load with a constructor's TypeError."""
    from scenario_gen.errors import Notice

    run = _export(tmp_path, "sb3", capsys) / "ppo" / f"{ZOO_ENV}_1"
    lone = tmp_path / "lone" / "model.zip"
    lone.parent.mkdir()
    shutil.copy(run / f"{ZOO_ENV}.zip", lone)
    env = _env()
    try:
        with pytest.warns(Notice, match=r"no vecnormalize\.pkl beside .*model\.zip"):
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", "loading .* with pickle")
                policy = make_policy(f"ppo:{lone}", env, trust_checkpoint=True)
        assert policy.normalize is None
        other = tmp_path / "sac.zip"
        with zipfile.ZipFile(lone) as src, zipfile.ZipFile(other, "w") as dst:
            for item in src.infolist():
                data = src.read(item)
                if item.filename == "data":
                    meta = json.loads(data)
                    meta["policy_class"]["__module__"] = "stable_baselines3.sac.policies"
                    data = json.dumps(meta).encode()
                dst.writestr(item, data)
        with pytest.raises(InputError, match=r"is a SAC model .*allowed: a PPO or A2C model"):
            _trusted(f"ppo:{other}", env)
    finally:
        env.close()


def test_a_trusted_zoo_run_exports_to_onnx_with_its_normalisation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("onnxruntime", reason="the export extra is not installed")
    from policies.onnx_export import onnx_actions

    run = _export(tmp_path, "sb3", capsys) / "ppo" / f"{ZOO_ENV}_1"
    out = tmp_path / "onnx"
    argv = ["export-policy", str(run), "--to", "onnx", "--out", str(out)]
    assert main(argv) == 2 and "trust-checkpoint" in capsys.readouterr().err
    # to sb3 again: refused before the trusted pickle is loaded (no warning about loading it)
    sb3 = ["export-policy", str(run), "--to", "sb3", "--out", str(tmp_path / "again")]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main([*sb3, "--trust-checkpoint"]) == 2
    assert "is not an AgriNav checkpoint" in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([*argv, "--trust-checkpoint"]) == 0
    env = _env()
    try:
        ours = make_policy("ppo:shipped", env)
        obs = observations(env, ours, 100, 100)
    finally:
        env.close()
    got = onnx_actions(
        (out / "policy.onnx").read_bytes(), {k: np.stack([o[k] for o in obs]) for k in OBS}
    )
    assert np.abs(got - np.stack([ours.act(o) for o in obs])).max() <= 1e-5


def test_the_zoo_config_is_read_safely_in_each_of_its_forms(tmp_path: Path) -> None:
    from collections import OrderedDict

    from policies.checkpoint import zoo_normalizes

    cases = {
        "ordered": (yaml.dump(OrderedDict([("normalize", True), ("n_envs", 4)])), True),
        "mapping": (yaml.safe_dump({"normalize": {"norm_obs": False}}), False),
        "expression": (yaml.safe_dump({"normalize": "dict(norm_obs=True)"}), True),
        "literal": (yaml.safe_dump({"normalize": "{'norm_obs': False}"}), False),
        "absent": (yaml.safe_dump({"n_envs": 1}), False),
    }
    for name, (text, expected) in cases.items():
        (tmp_path / name).write_text(text)
        assert zoo_normalizes(tmp_path / name) is expected, name
    (tmp_path / "code").write_text("!!python/object/apply:os.system ['touch pwned']\n")
    with pytest.raises(InputError):
        zoo_normalizes(tmp_path / "code")
    assert not Path("pwned").exists()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["shipped:AgriNav/Nope-v2", "--to", "onnx"], "allowed shipped ids"),
        (["ppo:shipped", "--to", "sb3"], "shipped:ENV_ID"),
        (["/no/such/checkpoint", "--to", "sb3"], "does not exist"),
        (["ppo:/no/such/checkpoint", "--to", "sb3"], "ppo:/no/such/checkpoint"),
        ([f"shipped:{FR}", "--to", "tflite"], "--to"),
        ([f"shipped:{FR}", "--to", "sb3", "--out", "/dev/null/out"], "--out"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path, args: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = ["--out", str(tmp_path / "out")] if "--out" not in args else []
    assert main(["export-policy", *args, *out]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_folder_is_replaced_only_with_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "onnx"
    out.mkdir()
    (out / "mine.txt").write_text("mine")
    argv = ["export-policy", f"shipped:{FR}", "--to", "sb3", "--out", str(out)]
    assert main(argv) == 2 and "--force" in capsys.readouterr().err
    assert main([*argv, "--force"]) == 2 and "not written by agrinav" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["mine.txt"]
    shutil.rmtree(out)
    assert main(argv) == 0 and main([*argv, "--force"]) == 0


def test_an_empty_folder_made_ahead_is_written_into(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``mkdir out`` first was refused without --force ("exists") and with it ("not written by
    agrinav"): an empty folder has nothing to lose."""
    out = tmp_path / "onnx"
    out.mkdir()
    assert main(["export-policy", f"shipped:{FR}", "--to", "onnx", "--out", str(out)]) == 0
    assert (out / "policy.onnx").is_file()


def test_a_missing_onnx_names_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "onnx", None)  # import onnx raises ImportError
    out = tmp_path / "out"
    assert main(["export-policy", f"shipped:{FR}", "--to", "onnx", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "pip install 'agrinav-gym[export]'" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_an_export_that_does_not_reproduce_the_policy_is_not_published(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import policies.onnx_export

    monkeypatch.setattr(policies.onnx_export, "TOLERANCE", -1.0)  # every check fails
    for to in ("sb3", "onnx"):
        out = tmp_path / to
        assert main(["export-policy", f"shipped:{FR}", "--to", to, "--out", str(out)]) == 2
        assert "max abs difference" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # neither the folders nor their temporaries


@pytest.mark.parametrize("env_id", [FR, "AgriNav/FurrowFollowDepth-v3"])
def test_the_sb3_exports_own_readme_code_runs(tmp_path: Path, env_id: str) -> None:
    """The README's snippet made the env with gym.make(ENV_ID) alone: a policy of fewer
    observations than the env's default (FieldRoute's, the depth policy's) failed in
    PPO.load. It makes the env from args.yml's env_kwargs, as zoo's enjoy does."""
    import re
    import subprocess

    out = tmp_path / "sb3"
    assert main(["export-policy", f"shipped:{env_id}", "--to", "sb3", "--out", str(out)]) == 0
    (code,) = re.findall(r"```python\n(.*?)```", (out / "README.md").read_text(), re.S)
    code += "\nassert venv.action_space.contains(action[0]), action\nprint('acted')\n"
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=out, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0 and done.stdout.strip().endswith("acted"), done.stderr[-2000:]


def test_a_checkpoint_of_an_older_env_version_exports_for_the_registered_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped checkpoint's folder, given by path, names AgriNav/FieldRoute-v2 (what it was
    trained on): --to sb3 refused it as unregistered; it now names v3, with a note, its spaces
    checked against v3. An env id that is not an AgriNav one is refused for ONNX too (it was
    written into the model's metadata and README as it stood)."""
    from policies import shipped_model

    folder = tmp_path / "ckpt"
    shutil.copytree(shipped_model(FR), folder)
    assert json.loads((folder / "checkpoint.json").read_text())["env_id"] == "AgriNav/FieldRoute-v2"
    out = tmp_path / "sb3"
    assert main(["export-policy", str(folder), "--to", "sb3", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "trained on AgriNav/FieldRoute-v2; the export names AgriNav/FieldRoute-v3" in err
    args = yaml.load(
        (out / "ppo" / f"{ZOO_ENV}_1" / ZOO_ENV / "args.yml").read_text(), Loader=yaml.UnsafeLoader
    )
    assert args["env"] == FR
    meta = json.loads((folder / "checkpoint.json").read_text())
    meta["env_id"] = "os:system\n# x"
    (folder / "checkpoint.json").write_text(json.dumps(meta))
    onnx = ["export-policy", str(folder), "--to", "onnx", "--out", str(tmp_path / "onnx")]
    assert main(onnx) == 2
    assert "checkpoint env_id" in capsys.readouterr().err and not (tmp_path / "onnx").exists()


def test_successor_names_only_older_versions_of_built_in_envs() -> None:
    from agrinav_gym.registration import successor

    assert successor("AgriNav/FieldRoute-v2") == FR
    assert successor("AgriNav/FurrowFollow-v0") == "AgriNav/FurrowFollow-v3"
    for other in (FR, "AgriNav/FieldRoute-v4", "AgriNav/Other-v1", "x:AgriNav/FieldRoute-v2", 3):
        assert successor(other) is None
