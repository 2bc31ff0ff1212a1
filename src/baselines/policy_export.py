"""``agrinav export-policy``: a PPO checkpoint as ONNX, or as Stable-Baselines3 files laid out
as rl-baselines3-zoo writes a run.

``onnx``: ``policy.onnx`` (``policies.onnx_export``: the actor with the observation
normalisation folded in, raw observations in, the deterministic action out) and a README with
its input layout. ``sb3``: ``ppo/<env>_1/<env>.zip`` (``PPO.save``'s format: weights, Adam's
state, hyperparameters) and, in ``ppo/<env>_1/<env>/``, ``vecnormalize.pkl`` (``VecNormalize``'s
statistics), ``config.yml`` and ``args.yml`` (zoo's records of the hyperparameters and of the
env id and kwargs) — the folder ``rl_zoo3.enjoy -f OUT`` reads, where ``<env>`` is the env id
with ``/`` as ``-`` (zoo's naming).

Every export is checked before it is published: the written model runs on 1,000 observations
(half drawn from the observation space, half around the normalisation statistics) next to the
project's torch policy, and an export whose actions differ by more than ``TOLERANCE`` is
refused. The output folder appears whole or not at all (``scenario_gen.atomic.output_dir``).
"""

from __future__ import annotations

import shlex
import warnings
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from policies import SHIPPED, check_policy_spec, checkpoint, shipped_model
from policies.checkpoint import Loaded
from policies.spec import SHIPPED_ARG, PolicySpec
from scenario_gen.atomic import check_output_dir, output_dir
from scenario_gen.errors import InputError, Notice
from scenario_gen.schema import from_mapping

from . import hyperparams as hpmod

TARGETS = ("onnx", "sb3")
#: ``shipped:ENV_ID``: the checkpoint shipped for an env id
SHIPPED_PREFIX = "shipped"
ONNX_FILE = "policy.onnx"
ZOO_ALGO = "ppo"
SAMPLES = 1000
FIELD = "CHECKPOINT"
FORMS = "a checkpoint folder (checkpoint.json), ppo:PATH or shipped:ENV_ID"


@dataclass(frozen=True)
class Source:
    loaded: Loaded
    folder: Path | None  # the AgriNav checkpoint folder; None for a (trusted) SB3 model
    env_id: str | None
    label: str  # as the user named it
    path: Path  # the file or folder read (which an --out replaced with --force must not hold)


def resolve_source(text: str, trust: bool = False) -> Source:
    """The policy ``text`` names: a checkpoint folder, ``ppo:PATH``, ``shipped:ENV_ID`` — or,
    with ``trust`` (``--trust-checkpoint``), a Stable-Baselines3 model or zoo run folder."""
    path, env_id = _source_path(text)
    loaded = checkpoint.load_policy(path, trust, text)
    safe = (path / checkpoint.META).is_file()
    return Source(loaded, path if safe else None, env_id or loaded.meta.get("env_id"), text, path)


def _source_path(text: str) -> tuple[Path, str | None]:
    """Where the policy ``text`` names lies (checked to exist), and its env id where the name
    says it (``shipped:ENV_ID``); nothing is read yet."""
    if not isinstance(text, str) or not text:
        raise InputError(FIELD, text, f"allowed: {FORMS}")
    name, arg = PolicySpec.parse(text)
    env_id: str | None = None
    if name == SHIPPED_PREFIX:
        if arg not in SHIPPED:
            raise InputError(FIELD, text, f"allowed shipped ids: {', '.join(SHIPPED)}")
        path, env_id = shipped_model(arg), arg
    elif name == "ppo" and arg == SHIPPED_ARG:
        raise InputError(
            FIELD,
            text,
            f"ppo:shipped needs an env id; allowed: shipped:ENV_ID ({', '.join(SHIPPED)})",
        )
    elif name == "ppo":
        check_policy_spec(text)
        path = Path(arg)
    else:
        path = Path(text)
    if not path.exists():
        raise InputError(FIELD, text, f"does not exist; allowed: {FORMS}")
    return path, env_id


def export_policy(
    source: str,
    to: str,
    out: str | Path,
    force: bool = False,
    trust: bool = False,
    argv: list[str] | None = None,
) -> dict[str, Any]:
    """Write ``source``'s policy to ``out`` in format ``to``; what was written, and the largest
    difference between the exported model's actions and the torch policy's."""
    if to not in TARGETS:
        raise InputError("--to", to, f"allowed: {', '.join(TARGETS)}")
    if to == "onnx":
        from policies.onnx_export import require_onnx

        require_onnx()
    check_output_dir(out, force, "--out", "policy export")
    if to == "sb3" and not (_source_path(source)[0] / checkpoint.META).is_file():
        # refused before a (trusted) pickle is loaded only to be refused
        raise InputError(FIELD, source, f"is not an AgriNav checkpoint; allowed for sb3: {FORMS}")
    src = resolve_source(source, trust)
    check_output_dir(out, force, "--out", "policy export", inputs=[src.path])
    command = " ".join(shlex.quote(a) for a in (argv or ["agrinav", "export-policy", source]))
    if to == "onnx":
        return _export_onnx(src, Path(out), force, command)
    return _export_sb3(src, Path(out), force, command)


def _describe(src: Source) -> str:
    steps = src.loaded.meta.get("num_timesteps")
    device = src.loaded.meta.get("device")
    return (
        f"`{src.label}`"
        + (f", {steps:,} training steps" if steps else "")
        + (f", trained on {device}" if device else "")
    )


def export_env_id(src: Source, required: bool = True) -> str | None:
    """The env an export names: the checkpoint's, checked as every env id read from a file is
    (an SB3 model names none: None where ``required`` is false). A checkpoint trained on an
    older version of a built-in env (the shipped ones: ``-v2``) names the registered version,
    with a note, once its spaces are checked against it: zoo can make only registered ids."""
    import agrinav_gym
    from agrinav_gym.registration import successor
    from policies.ppo import check_spaces

    if src.env_id is None and not required:
        return None
    newer = successor(src.env_id)
    if newer is None:
        return agrinav_gym.check_env_id(src.env_id, "checkpoint env_id")
    space = src.loaded.policy.observation_space
    kwargs = dict(src.loaded.meta.get("env_kwargs") or {})
    kwargs.setdefault("observations", sorted(getattr(space, "spaces", {})))
    try:
        env = gym.make(newer, **kwargs)
    except InputError as exc:
        raise InputError(
            "checkpoint env_kwargs", exc.value, f"do not make {newer}: {exc.allowed}"
        ) from None
    try:
        u: Any = env.unwrapped  # an AgriNavEnv: a Dict observation space, a Box action space
        check_spaces(
            space, u.observation_space, src.loaded.policy.action_space, u.action_space, src.label
        )
    finally:
        env.close()
    warnings.warn(
        Notice(f"{src.label} was trained on {src.env_id}; the export names {newer}"),
        stacklevel=2,
    )
    return newer


# ----------------------------------------------------------------------------------- ONNX


def _export_onnx(src: Source, out: Path, force: bool, command: str) -> dict[str, Any]:
    from policies.onnx_export import (
        OPSET,
        OUTPUT,
        TOLERANCE,
        actor_graph,
        input_layout,
        onnx_actions,
        sample_observations,
        torch_actions,
    )

    meta = src.loaded.meta
    env_id = export_env_id(src, required=False)
    props = {
        "agrinav.env_id": env_id or "",
        "agrinav.source": src.label,
        "agrinav.num_timesteps": str(meta.get("num_timesteps", "")),
        "agrinav.training_device": str(meta.get("device", "")),
    }
    model = actor_graph(src.loaded, props)
    obs = sample_observations(src.loaded, SAMPLES)
    diff = float(np.abs(onnx_actions(model, obs) - torch_actions(src.loaded, obs)).max())
    if diff > TOLERANCE:
        raise InputError(
            "export", f"max abs difference {diff:.3g}", f"allowed: at most {TOLERANCE:g}"
        )
    layout = input_layout(src.loaded.policy.observation_space)
    space = src.loaded.policy.action_space
    with output_dir(out, force, "--out", "policy export", inputs=[src.path]) as tmp:
        (tmp / ONNX_FILE).write_bytes(model)
        (tmp / "README.md").write_text(
            _onnx_readme(src, env_id, layout, space, diff, command, OPSET, OUTPUT)
        )
    return {
        "onnx": str(out / ONNX_FILE),
        "inputs": ", ".join(f"{d['name']}{tuple(d['shape'][1:])}" for d in layout),
        "output": f"{OUTPUT} (batch, {int(np.prod(space.shape))})",
        "max_abs_diff": f"{diff:.3g} over {SAMPLES} observations (onnxruntime vs torch)",
    }


def _fields_text(d: dict[str, Any]) -> str:
    fields = d.get("fields")
    if not fields:
        return str(d.get("layout", ""))
    if len(fields) > 12:  # the route: K points of (x, y, furrow)
        fields = [*fields[:6], "…", *fields[-3:]]
    return ", ".join(fields)


def _onnx_readme(
    src: Source,
    env_id: str | None,
    layout: list[dict[str, Any]],
    space: Any,
    diff: float,
    command: str,
    opset: int,
    output: str,
) -> str:
    norm = src.loaded.normalizer
    rows = "\n".join(
        f"| `{d['name']}` | ({', '.join(map(str, d['shape']))}) | {_fields_text(d)} |"
        for d in layout
    )
    folded = (
        "none (the policy was trained on raw observations)"
        if norm is None
        else f"folded into the graph: `clip((x − mean) / √(var + {norm.epsilon:g}), "
        f"±{norm.clip:g})` for {', '.join(f'`{k}`' for k in sorted(norm.mean))}, computed in "
        "float64 as VecNormalize does, with the statistics the policy was trained with"
    )
    feeds = ", ".join(f'"{d["name"]}": obs["{d["name"]}"][None]' for d in layout)
    return f"""# {env_id or "PPO"} policy — ONNX

`policy.onnx`: the actor of the PPO policy {_describe(src)}. Raw observations in, the
deterministic action out; ONNX opset {opset}, IR version 8.

Written by `{command}`.

## Inputs

One input per observation key, named by the key, float32, the batch first — the observation
exactly as the env returns it (layouts: AgriNav's `agrinav_gym/interface.py`, docs/design.md
section 4). The same list is in the model's metadata (`agrinav.inputs`, JSON).

| input | shape | layout |
|---|---|---|
{rows}

Normalisation: {folded}.

## Output

`{output}`: float32 (batch, {int(np.prod(space.shape))}), the Gaussian's mean clipped to the
action space [{np.asarray(space.low).tolist()}, {np.asarray(space.high).tolist()}] — the env's
normalised twist (forward speed / v_max, yaw rate / w_max), as `PPOPolicy.act` returns it
(`agrinav.output` in the metadata).

## Check

onnxruntime against the torch policy on {SAMPLES} observations (half drawn from the
observation space, half around the normalisation statistics): max |difference| = {diff:.3g}.

```python
import onnxruntime as ort
session = ort.InferenceSession("policy.onnx", providers=["CPUExecutionProvider"])
action = session.run(["{output}"], {{{feeds}}})[0][0]
```
"""


# ------------------------------------------------------------------------------------ SB3


class _SpacesOnly(gym.Env):
    """An env that is only its spaces: PPO and VecNormalize are built from an env, never
    stepped here."""

    def __init__(self, observation_space: Any, action_space: Any) -> None:
        self.observation_space = observation_space
        self.action_space = action_space

    def reset(self, **_: Any) -> Any:
        raise RuntimeError("a spaces-only env cannot be reset")

    def step(self, _action: Any) -> Any:
        raise RuntimeError("a spaces-only env cannot be stepped")


def _venv(loaded: Loaded, n: int = 1) -> Any:
    from stable_baselines3.common.vec_env import DummyVecEnv

    p = loaded.policy
    return DummyVecEnv([lambda: _SpacesOnly(p.observation_space, p.action_space)] * n)


def zoo_name(env_id: str) -> str:
    """An env id as rl-baselines3-zoo names its files and folders (``/`` → ``-``)."""
    return env_id.replace("/", "-")


def _hyperparams(src: Source) -> hpmod.PPOHyperparams:
    """The training hyperparameters (the checkpoint's, or the defaults where it holds none)
    with the policy, network and normalisation the checkpoint actually has."""
    meta = src.loaded.meta
    data = dict(meta.get("hyperparams") or {})
    depth = meta.get("policy") == "DepthMultiInputPolicy"
    data["policy"] = hpmod.POLICIES[1] if depth else hpmod.POLICIES[0]
    data["policy_kwargs"] = meta.get("policy_kwargs") or {}
    norm = src.loaded.normalizer is not None
    data["normalize"] = {"norm_obs": True, "norm_reward": False} if norm else False
    hp: hpmod.PPOHyperparams = from_mapping(hpmod.PPOHyperparams, data, "checkpoint hyperparams.")
    return hp


def _sb3_model(src: Source, hp: hpmod.PPOHyperparams) -> tuple[Any, Any]:
    """A PPO model holding the checkpoint (weights, Adam's state, step count) and its
    VecNormalize (or None)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from .train import restore

    assert src.folder is not None
    venv = _venv(src.loaded, hp.n_envs)
    kwargs = hp.ppo_kwargs()
    policy = kwargs.pop("policy")
    kwargs["policy_kwargs"] = checkpoint.policy_kwargs_from_json(kwargs["policy_kwargs"])
    model = PPO(policy, venv, device="cpu", verbose=0, **kwargs)
    norm = None
    n = src.loaded.normalizer
    if n is not None:
        # saved in training mode, as zoo saves its training env's (evaluation turns it off)
        norm = VecNormalize(
            venv,
            norm_obs=True,
            norm_reward=False,
            clip_obs=n.clip,
            gamma=hp.gamma,
            epsilon=n.epsilon,
            norm_obs_keys=sorted(n.mean),
        )
    # Adam's state where the checkpoint has it (the shipped ones carry weights only)
    restore(model, norm, src.folder, FIELD, (src.folder / checkpoint.OPTIMIZER).is_file())
    return model, norm


def _sb3_actions(model_file: Path, stats: Path | None, loaded: Loaded, obs: Any) -> Any:
    """What SB3 does with the written files: ``PPO.load``, ``VecNormalize.load`` (evaluation
    mode), ``predict(normalize_obs(obs), deterministic=True)``."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    model = PPO.load(model_file, device="cpu")
    if stats is not None:
        vn = VecNormalize.load(str(stats), _venv(loaded))
        vn.training = False
        obs = vn.normalize_obs(obs)
    return model.predict(obs, deterministic=True)[0]


def _export_sb3(src: Source, out: Path, force: bool, command: str) -> dict[str, Any]:
    import yaml

    from policies.onnx_export import TOLERANCE, sample_observations, torch_actions

    if src.folder is None:
        raise InputError(
            FIELD, src.label, f"is a Stable-Baselines3 model already; allowed for sb3: {FORMS}"
        )
    env_id = export_env_id(src)
    assert env_id is not None
    hp = _hyperparams(src)
    model, norm = _sb3_model(src, hp)
    name = zoo_name(env_id)
    meta = src.loaded.meta
    # the env as the policy reads it: a policy of fewer observations than the env's default
    # (FieldRoute's and the depth policy's) fits only an env made with those (zoo's enjoy and
    # the README's snippet both make it from these kwargs)
    env_kwargs = dict(meta.get("env_kwargs") or {})
    env_kwargs.setdefault("observations", sorted(src.loaded.policy.observation_space.spaces))
    config = OrderedDict(sorted(hpmod.to_zoo(hp).items()))
    args = OrderedDict(
        sorted(
            {
                "algo": ZOO_ALGO,
                "env": env_id,
                "env_kwargs": env_kwargs,
                "gym_packages": ["agrinav_gym"],
                "n_timesteps": hp.n_timesteps,
                "seed": meta.get("seed", 0),
                "device": "auto",
            }.items()
        )
    )
    obs = sample_observations(src.loaded, SAMPLES)
    with output_dir(out, force, "--out", "policy export", inputs=[src.path]) as tmp:
        run = tmp / ZOO_ALGO / f"{name}_1"
        params = run / name
        params.mkdir(parents=True)
        model.save(run / f"{name}.zip")
        stats = None
        if norm is not None:
            stats = params / checkpoint.SB3_STATS
            norm.save(str(stats))
        (params / checkpoint.ZOO_CONFIG).write_text(yaml.dump(config))  # as zoo writes them
        (params / "args.yml").write_text(yaml.dump(args))
        (params / "command.txt").write_text(command + "\n")
        actions = _sb3_actions(run / f"{name}.zip", stats, src.loaded, obs)
        diff = float(np.abs(actions - torch_actions(src.loaded, obs)).max())
        if diff > TOLERANCE:
            raise InputError(
                "export", f"max abs difference {diff:.3g}", f"allowed: at most {TOLERANCE:g}"
            )
        readme = _sb3_readme(src, env_id, name, norm is not None, diff, env_kwargs)
        (tmp / "README.md").write_text(readme)
    rel = Path(ZOO_ALGO) / f"{name}_1"
    return {
        "model": str(out / rel / f"{name}.zip"),
        "vecnormalize": str(out / rel / name / checkpoint.SB3_STATS) if norm else "none",
        "zoo": f"python -m rl_zoo3.enjoy --algo ppo --env {env_id} --gym-packages agrinav_gym "
        f"-f {out} --exp-id 1",
        "max_abs_diff": f"{diff:.3g} over {SAMPLES} observations (SB3 vs AgriNav's policy)",
    }


def _sb3_readme(
    src: Source,
    env_id: str,
    name: str,
    normalized: bool,
    diff: float,
    env_kwargs: dict[str, Any],
) -> str:
    run = f"{ZOO_ALGO}/{name}_1"
    has_adam = src.folder is not None and (src.folder / checkpoint.OPTIMIZER).is_file()
    adam = ", Adam's state (to train on)" if has_adam else ""
    stats_row = (
        f"| `{run}/{name}/vecnormalize.pkl` | `VecNormalize.save`: the observation statistics "
        "(clip ±10), saved in training mode as zoo saves them |\n"
        if normalized
        else ""
    )
    load_stats = (
        f"""venv = VecNormalize.load("{run}/{name}/vecnormalize.pkl", venv)
venv.training, venv.norm_reward = False, False  # evaluation: frozen statistics
"""
        if normalized
        else ""
    )
    return f"""# {env_id} PPO policy — Stable-Baselines3 / rl-baselines3-zoo

The PPO policy {_describe(src)}, as Stable-Baselines3 files in the folder layout
rl-baselines3-zoo writes (`<log folder>/ppo/<env>_<run>/`, `<env>` the env id with `/` as `-`).

| file | content |
|---|---|
| `{run}/{name}.zip` | `PPO.save`: weights, hyperparameters, step count{adam} |
{stats_row}| `{run}/{name}/config.yml` | the hyperparameters, as zoo records them |
| `{run}/{name}/args.yml` | env id, env kwargs and gym package, as zoo records them |

Both `.zip` and `.pkl` are pickles: they run code when loaded, so load them only from a source
you trust.

```python
import gymnasium as gym
import agrinav_gym  # registers the AgriNav envs
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

# the env as the policy was trained on it: its observations (args.yml's env_kwargs)
env_kwargs = {env_kwargs!r}
venv = DummyVecEnv([lambda: gym.make("{env_id}", **env_kwargs)])
{load_stats}model = PPO.load("{run}/{name}.zip", env=venv)
obs = venv.reset()
action, _ = model.predict(obs, deterministic=True)
```

rl-baselines3-zoo: `python -m rl_zoo3.enjoy --algo ppo --env {env_id} --gym-packages
agrinav_gym -f . --exp-id 1`. In AgriNav: `--policies ppo:{run} --trust-checkpoint`.

Checked: SB3 (`PPO.load`, `VecNormalize.load`, `predict(..., deterministic=True)`) against
AgriNav's policy on {SAMPLES} observations (half drawn from the observation space, half around
the normalisation statistics): max |difference| = {diff:.3g}.
"""
