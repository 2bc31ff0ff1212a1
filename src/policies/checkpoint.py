"""PPO checkpoints in a format that cannot execute code.

A checkpoint folder holds ``policy.npz`` (the network's tensors; read with
``allow_pickle=False``), optionally ``optimizer.npz`` (Adam's moments, for resuming training)
and ``checkpoint.json``: the observation and action spaces, the policy class (one of a fixed
list) and its keyword arguments (plain JSON), the observation-normalisation statistics and the
training metadata. Loading builds the network from that description and fills it with the
arrays: nothing is unpickled, so a crafted checkpoint can at worst fail to load.

Stable-Baselines3's own ``model.zip`` unpickles Python objects (and ``vecnormalize.pkl`` is a
pickle): those load only through ``load_sb3_trusted``, behind ``--trust-checkpoint`` — SB3's
pair in one folder, or an rl-baselines3-zoo run (``<env>.zip`` beside ``<env>/vecnormalize.pkl``
and ``<env>/config.yml``), whose normalisation is applied, or refused when its statistics are
missing. ``load_policy`` picks the loader a path needs.
"""

from __future__ import annotations

import json
import math
import stat
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from scenario_gen.errors import InputError, Notice
from scenario_gen.schema import parse_json

FORMAT = "agrinav-ppo"
VERSION = 1
META = "checkpoint.json"
WEIGHTS = "policy.npz"
OPTIMIZER = "optimizer.npz"
MAX_META_BYTES = 1 << 20
MAX_TIMESTEPS = 10**12  # a step count past this is a corrupt file, not a training run
MAX_LAYER = 4096  # units in one hidden layer: 160 GB networks are typos, not checkpoints
ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU")
POLICY_KWARGS = {
    "net_arch",
    "activation_fn",
    "ortho_init",
    "log_std_init",
    "share_features_extractor",
    "features_extractor_kwargs",
}


@dataclass(frozen=True)
class Normalizer:
    """Observation normalisation as VecNormalize applies it: clip((x − mean)/√(var + ε))."""

    mean: dict[str, NDArray[np.float64]]
    var: dict[str, NDArray[np.float64]]
    clip: float
    epsilon: float

    def __call__(self, obs: dict[str, NDArray[np.float32]]) -> dict[str, NDArray[np.float32]]:
        out = dict(obs)
        for k in self.mean:
            z = (np.asarray(obs[k], np.float64) - self.mean[k]) / np.sqrt(
                self.var[k] + self.epsilon
            )
            out[k] = np.clip(z, -self.clip, self.clip).astype(np.float32)
        return out


def space_to_json(space: spaces.Space[Any]) -> dict[str, Any]:
    if isinstance(space, spaces.Dict):
        return {"type": "Dict", "spaces": {k: space_to_json(v) for k, v in space.spaces.items()}}
    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "shape": list(space.shape),
            "low": _bound(space.low),
            "high": _bound(space.high),
            "dtype": str(space.dtype),
        }
    raise InputError("checkpoint space", type(space).__name__, "allowed: Dict of Box, or Box")


def _bound(a: NDArray[Any]) -> float | list[float]:
    """A bound as one number when it is the same everywhere (images), else per element."""
    flat = np.asarray(a, np.float64).ravel()
    return float(flat[0]) if (flat == flat[0]).all() else flat.tolist()


def space_from_json(d: Any, where: str) -> spaces.Space[Any]:
    if not isinstance(d, dict) or d.get("type") not in ("Dict", "Box"):
        raise InputError(where, d, "allowed: a Dict or Box space description")
    if d["type"] == "Dict":
        sub = d.get("spaces")
        if not isinstance(sub, dict) or not sub:
            raise InputError(where, sub, "allowed: a mapping of observation keys to spaces")
        return spaces.Dict({str(k): space_from_json(v, f"{where}.{k}") for k, v in sub.items()})
    shape = d.get("shape")
    if not (isinstance(shape, list) and all(isinstance(n, int) and 0 < n < 10**6 for n in shape)):
        raise InputError(where, shape, "allowed: a list of positive integers")
    size = math.prod(shape)
    try:
        low = np.broadcast_to(np.asarray(d["low"], np.float64), size).reshape(shape)
        high = np.broadcast_to(np.asarray(d["high"], np.float64), size).reshape(shape)
    except (KeyError, TypeError, ValueError):
        raise InputError(where, "low/high", f"allowed: {size} numbers each") from None
    if d.get("dtype") not in ("float32", "float64"):
        raise InputError(where, d.get("dtype"), "allowed: float32 or float64")
    if np.isnan(low).any() or np.isnan(high).any() or (low > high).any():
        raise InputError(where, "low/high", "allowed: bounds without NaN, low <= high")
    dtype = np.dtype(d["dtype"])
    return spaces.Box(low.astype(dtype), high.astype(dtype), dtype=dtype)


def _policy_class(name: Any) -> type:
    from stable_baselines3.common.policies import MultiInputActorCriticPolicy

    from .extractors import DepthMultiInputPolicy

    classes = {
        "MultiInputPolicy": MultiInputActorCriticPolicy,
        "DepthMultiInputPolicy": DepthMultiInputPolicy,
    }
    if name not in classes:
        raise InputError("checkpoint policy", name, f"allowed: one of {', '.join(classes)}")
    return classes[name]


def policy_kwargs_from_json(d: Any, where: str = "checkpoint") -> dict[str, Any]:
    """Only plain, known keyword arguments; class-valued ones come from a fixed list (a
    checkpoint's, or ``hyperparams`` given to training: ``where`` names which)."""
    from torch import nn

    field = f"{where}.policy_kwargs"
    if not isinstance(d, dict) or set(d) - POLICY_KWARGS:
        raise InputError(field, d, f"allowed keys: {', '.join(sorted(POLICY_KWARGS))}")
    out = dict(d)
    for key in ("ortho_init", "share_features_extractor"):
        if key in out and not isinstance(out[key], bool):
            raise InputError(f"{field}.{key}", out[key], "allowed: true or false")
    std = out.get("log_std_init")
    if std is not None and (
        isinstance(std, bool) or not isinstance(std, (int, float)) or not -20 <= std <= 5
    ):
        raise InputError(f"{field}.log_std_init", std, "allowed: a number in [-20, 5]")
    extractor = out.get("features_extractor_kwargs")
    if extractor is not None and not isinstance(extractor, dict):
        raise InputError(f"{field}.features_extractor_kwargs", extractor, "allowed: a mapping")
    arch = out.get("net_arch")
    if isinstance(arch, dict) and (not arch or set(arch) - {"pi", "vf"}):
        # SB3 reads only pi and vf: other keys left a network of no hidden layers silently
        raise InputError(
            f"{field}.net_arch", arch, "allowed: a list of layer sizes, or a mapping of pi, vf"
        )
    if arch is not None:
        layers = list(arch.values()) if isinstance(arch, dict) else [arch]
        sizes = [n for group in layers for n in (group if isinstance(group, list) else [group])]
        if not sizes or not all(
            isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= MAX_LAYER for n in sizes
        ):
            raise InputError(
                f"{field}.net_arch", arch, f"allowed: layer sizes from 1 to {MAX_LAYER}"
            )
    if "activation_fn" in out:
        if out["activation_fn"] not in ACTIVATIONS:
            raise InputError(
                f"{field}.activation_fn",
                out["activation_fn"],
                f"allowed: {', '.join(ACTIVATIONS)}",
            )
        out["activation_fn"] = getattr(nn, out["activation_fn"])
    return out


def policy_kwargs_to_json(kwargs: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in kwargs.items() if k in POLICY_KWARGS}
    if "activation_fn" in out and not isinstance(out["activation_fn"], str):
        out["activation_fn"] = out["activation_fn"].__name__  # a class; a name stays a name
    return json.loads(json.dumps(out))


def save(
    folder: Path,
    policy: Any,
    policy_name: str,
    policy_kwargs: dict[str, Any],
    normalizer: Any | None,
    meta: dict[str, Any],
    optimizer: bool = False,
) -> None:
    """Write a checkpoint of an SB3 ActorCritic ``policy`` (and a VecNormalize, if any)."""
    folder.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(folder / WEIGHTS, **_tensors(policy))  # type: ignore[arg-type]
    norm = None
    if normalizer is not None:
        rms = normalizer.obs_rms
        norm = {
            "mean": {k: r.mean.tolist() for k, r in rms.items()},
            "var": {k: r.var.tolist() for k, r in rms.items()},
            "count": {k: float(r.count) for k, r in rms.items()},
            "clip": float(normalizer.clip_obs),
            "epsilon": float(normalizer.epsilon),
        }
    opt_meta = None
    if optimizer:
        opt = policy.optimizer.state_dict()
        params = [n for n, _ in policy.named_parameters()]
        arrays: dict[str, NDArray[Any]] = {}
        for idx, st in opt["state"].items():
            for key, val in st.items():
                arrays[f"{params[idx]}/{key}"] = np.asarray(val.detach().cpu().numpy())
        np.savez_compressed(folder / OPTIMIZER, **arrays)  # type: ignore[arg-type]
        group = {k: v for k, v in opt["param_groups"][0].items() if k != "params"}
        opt_meta = {"group": json.loads(json.dumps(group, default=float)), "params": params}
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "policy": policy_name,
        "policy_kwargs": policy_kwargs_to_json(policy_kwargs),
        "observation_space": space_to_json(policy.observation_space),
        "action_space": space_to_json(policy.action_space),
        "normalize": norm is not None,
        "normalization": norm,
        "optimizer": opt_meta,
        **meta,
    }
    (folder / META).write_text(json.dumps(doc, indent=1))


def _tensors(policy: Any) -> dict[str, NDArray[Any]]:
    """Parameters and buffers by name, each once (shared feature extractors appear under
    several names in a state dict)."""
    named = [*policy.named_parameters(), *policy.named_buffers()]
    return {k: v.detach().cpu().numpy() for k, v in named}


@dataclass
class Loaded:
    policy: Any  # an SB3 ActorCriticPolicy on the CPU, eval mode
    normalizer: Normalizer | None
    meta: dict[str, Any]


#: Weights of the largest network a config may ask for, with room: 4 × 10⁷ float32 parameters.
MAX_NPZ_BYTES = 160 << 20


def read_npz(path: Path, what: str, max_bytes: int = MAX_NPZ_BYTES) -> dict[str, NDArray[Any]]:
    """The arrays of an ``.npz`` file, checked before anything is allocated: a regular file
    (a FIFO would block forever), a zip whose members are distinct ``.npy`` files, and whose
    arrays — by their headers — fit in ``max_bytes`` and in the bytes each member holds."""
    where = str(path)
    try:
        st = path.lstat()
    except OSError as exc:
        raise InputError(what, where, f"cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(what, where, "allowed: a regular file (not a link, FIFO or device)")
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            names = [i.filename for i in infos]
            if len(set(names)) != len(names):
                raise InputError(what, where, "holds two members of the same name")
            total = 0
            for info in infos:
                with zf.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    header = {
                        (1, 0): np.lib.format.read_array_header_1_0,
                        (2, 0): np.lib.format.read_array_header_2_0,
                    }.get(version)
                    if header is None:
                        raise InputError(what, where, f"npy format {version}; allowed: 1.0, 2.0")
                    shape, _, dtype = header(f, max_header_size=10_000)
                if dtype.hasobject:
                    raise InputError(what, where, f"member {info.filename} holds Python objects")
                need = int(np.prod(shape, dtype=object)) * dtype.itemsize
                total += need
                if need > info.file_size or total > max_bytes:
                    raise InputError(
                        what,
                        where,
                        f"member {info.filename} claims {need:,} bytes; allowed: arrays that "
                        f"its {info.file_size:,} bytes hold, {max_bytes:,} in all",
                    )
        with np.load(path, allow_pickle=False) as z:
            return {k: np.array(z[k]) for k in z.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(what, where, f"cannot be read as weights ({exc})") from None


def read_meta(folder: Path) -> dict[str, Any]:
    path = folder / META
    if not path.is_file() or path.is_symlink():
        raise InputError("checkpoint", str(folder), f"holds no {META} (a safe AgriNav checkpoint)")
    if path.stat().st_size > MAX_META_BYTES:
        raise InputError("checkpoint", str(path), f"allowed: at most {MAX_META_BYTES} bytes")
    meta = parse_json(path.read_bytes(), "checkpoint", str(path))
    if not isinstance(meta, dict) or meta.get("format") != FORMAT or meta.get("version") != VERSION:
        raise InputError("checkpoint", str(path), f"allowed: format {FORMAT!r} version {VERSION}")
    steps = meta.get("num_timesteps", 0)
    if isinstance(steps, bool) or not isinstance(steps, int) or not 0 <= steps <= MAX_TIMESTEPS:
        raise InputError(
            f"{path} num_timesteps", steps, f"allowed: an integer in [0, {MAX_TIMESTEPS:,}]"
        )
    return meta


def load(folder: str | Path) -> Loaded:
    """Build the network described by ``checkpoint.json`` and fill it from ``policy.npz``."""
    import torch

    folder = Path(folder)
    meta = read_meta(folder)
    obs_space = space_from_json(meta.get("observation_space"), "checkpoint observation_space")
    act_space = space_from_json(meta.get("action_space"), "checkpoint action_space")
    if not isinstance(obs_space, spaces.Dict) or not isinstance(act_space, spaces.Box):
        raise InputError("checkpoint", str(folder), "allowed: Dict observations, Box actions")
    cls = _policy_class(meta.get("policy"))
    kwargs = policy_kwargs_from_json(meta.get("policy_kwargs", {}))
    try:
        policy = cls(obs_space, act_space, lambda _: 0.0, **kwargs)
    except (TypeError, ValueError) as exc:
        raise InputError(
            "checkpoint policy_kwargs",
            meta.get("policy_kwargs"),
            f"cannot build the network ({exc})",
        ) from None
    where = str(folder / WEIGHTS)
    arrays = read_npz(folder / WEIGHTS, "checkpoint")
    targets = dict([*policy.named_parameters(), *policy.named_buffers()])
    if set(arrays) != set(targets):
        odd = sorted(set(arrays) ^ set(targets))[:3]
        raise InputError("checkpoint", where, f"does not fit the network (tensors {odd})")
    with torch.no_grad():
        for name, t in targets.items():
            a = arrays[name]
            if a.dtype.kind not in "fiu":  # strings or objects: no number to copy
                raise InputError(
                    "checkpoint", where, f"tensor {name} holds {a.dtype} values; allowed: numbers"
                )
            if a.shape != tuple(t.shape) or not np.isfinite(a).all():
                raise InputError(
                    "checkpoint",
                    where,
                    f"tensor {name}: shape {a.shape} or non-finite values; "
                    f"the network needs {tuple(t.shape)}",
                )
            t.copy_(torch.from_numpy(a).to(t.dtype))
    policy.set_training_mode(False)
    return Loaded(policy, _normalizer(meta, obs_space, folder), meta)


def _normalizer(meta: dict[str, Any], obs_space: spaces.Dict, folder: Path) -> Normalizer | None:
    if not meta.get("normalize"):
        return None
    n = meta.get("normalization")
    if not isinstance(n, dict):
        raise InputError(
            "checkpoint",
            str(folder),
            "was trained with normalised observations but holds no normalisation statistics",
        )
    mean, var = {}, {}
    try:
        for k, sp in obs_space.spaces.items():
            mean[k] = np.asarray(n["mean"][k], np.float64).reshape(sp.shape)
            var[k] = np.asarray(n["var"][k], np.float64).reshape(sp.shape)
        clip, eps = float(n["clip"]), float(n["epsilon"])
    except (KeyError, TypeError, ValueError):
        raise InputError(
            "checkpoint normalization",
            str(folder),
            "allowed: mean and var per observation, clip, epsilon",
        ) from None
    if any((v < 0).any() or not np.isfinite(v).all() for v in var.values()):
        raise InputError(
            "checkpoint normalization", str(folder), "variances must be finite and >= 0"
        )
    if any(not np.isfinite(m).all() for m in mean.values()):
        raise InputError("checkpoint normalization", str(folder), "means must be finite")
    counts = n.get("count")
    if counts is not None and not (
        isinstance(counts, dict)
        and all(
            isinstance(counts.get(k), (int, float))
            and not isinstance(counts.get(k), bool)
            and math.isfinite(counts[k])
            and counts[k] >= 0
            for k in obs_space.spaces
        )
    ):
        raise InputError(
            "checkpoint normalization count",
            str(folder),
            "allowed: a finite count >= 0 per observation",
        )
    if not (math.isfinite(clip) and clip > 0 and math.isfinite(eps) and eps > 0):
        # clip <= 0 made every observation 0: a blind policy that still "ran"
        raise InputError(
            "checkpoint normalization", [clip, eps], "allowed: clip > 0 and epsilon > 0, finite"
        )
    return Normalizer(mean, var, clip, eps)


#: Stable-Baselines3's files: the model and VecNormalize's statistics, and rl-baselines3-zoo's
#: hyperparameter record (in the ``<env>/`` folder beside its ``<env>.zip``)
SB3_MODEL = "model.zip"
SB3_STATS = "vecnormalize.pkl"
ZOO_CONFIG = "config.yml"
MAX_ZOO_CONFIG_BYTES = 1 << 20
#: the first line of a config.yml that zoo wrote (``yaml.dump`` of an ``OrderedDict``)
_ORDERED_DICT_TAG = "!!python/object/apply:collections.OrderedDict"


def load_policy(path: str | Path, trust: bool, where: str) -> Loaded:
    """A policy from ``path``: an AgriNav checkpoint folder (safe), or — only with ``trust``
    (``--trust-checkpoint``) — a Stable-Baselines3 model (``find_sb3``)."""
    p = Path(path)
    if (p / META).is_file():
        return load(p)
    model = find_sb3(p)
    if model is not None and trust:
        return load_sb3_trusted(model)
    if model is not None or p.suffix == ".zip":
        raise InputError(
            "policy",
            where,
            "is a Stable-Baselines3 model.zip, which unpickles code when loaded; "
            "allowed: an AgriNav checkpoint folder, or --trust-checkpoint for a file you trust",
        )
    raise InputError("policy", where, f"allowed: a checkpoint folder holding {META}")


def find_sb3(path: Path) -> Path | None:
    """The SB3 model at ``path``: a ``.zip`` file, a folder's ``model.zip``, or the one
    ``<env>.zip`` of an rl-baselines3-zoo run folder (the zip beside its ``<env>/`` folder)."""
    if path.suffix == ".zip" and path.is_file():
        return path
    if (path / SB3_MODEL).is_file():
        return path / SB3_MODEL
    if path.is_dir():
        zoo = [z for z in sorted(path.glob("*.zip")) if z.is_file() and (path / z.stem).is_dir()]
        if len(zoo) == 1:
            return zoo[0]
    return None


def sb3_stats(model_file: Path) -> tuple[Path | None, Path | None]:
    """(the ``vecnormalize.pkl`` that goes with ``model_file`` or None, zoo's ``config.yml``
    or None). SB3's own pair keeps both files in one folder; rl-baselines3-zoo writes
    ``<env>.zip`` and, beside it, ``<env>/vecnormalize.pkl`` and ``<env>/config.yml`` (its
    ``best_model.zip`` and step checkpoints share that folder)."""
    folder = model_file.parent
    params: Path | None = folder / model_file.stem
    if not (folder / model_file.stem).is_dir():
        found = [d for d in sorted(folder.iterdir()) if d.is_dir() and (d / ZOO_CONFIG).is_file()]
        params = found[0] if len(found) == 1 else None
    places = [folder / SB3_STATS] if params is None else [params / SB3_STATS, folder / SB3_STATS]
    stats = [p for p in places if p.is_file()]
    if len(stats) > 1:
        raise InputError(
            "policy",
            str(model_file),
            f"has two normalisation files ({stats[0]}, {stats[1]}); allowed: one",
        )
    config = params / ZOO_CONFIG if params is not None else None
    return (stats[0] if stats else None), (config if config and config.is_file() else None)


def zoo_normalizes(config: Path) -> bool:
    """Whether rl-baselines3-zoo's ``config.yml`` says the observations were normalised.

    Zoo writes the file with ``yaml.dump`` of an ``OrderedDict`` (a Python tag, read back with
    yaml's unsafe loader); here the tag line is dropped and the list of (key, value) pairs
    under it read with the safe, bounded ``parse_yaml``. ``normalize`` is a bool, a mapping
    (``norm_obs``) or a Python expression zoo evaluates (read here as a literal only)."""
    import ast

    from scenario_gen.schema import parse_yaml

    if config.stat().st_size > MAX_ZOO_CONFIG_BYTES:
        raise InputError("policy", str(config), f"allowed: at most {MAX_ZOO_CONFIG_BYTES} bytes")
    try:
        text = config.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError("policy", str(config), f"cannot be read ({exc})") from None
    head, _, rest = text.partition("\n")
    data = parse_yaml(rest, str(config)) if head.strip() == _ORDERED_DICT_TAG else None
    if data is None:
        data = parse_yaml(text, str(config))
    elif isinstance(data, list) and len(data) == 1 and isinstance(data[0], list):
        pairs = data[0]
        if not all(isinstance(kv, list) and len(kv) == 2 for kv in pairs):
            raise InputError("policy", str(config), "allowed: zoo's (key, value) pairs")
        data = {str(k): v for k, v in pairs}
    if not isinstance(data, dict):
        raise InputError("policy", str(config), "allowed: rl-baselines3-zoo's hyperparameters")
    value = data.get("normalize", False)
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            return True  # an expression zoo evaluates (``dict(norm_obs=True)``): normalised
    if isinstance(value, dict):
        return bool(value.get("norm_obs", True))
    return bool(value)


def load_sb3_trusted(model_file: Path) -> Loaded:
    """An SB3 model (``model.zip``, or rl-baselines3-zoo's ``<env>.zip``) and the
    ``vecnormalize.pkl`` that goes with it (``sb3_stats``): unpickles, so it can run code —
    only for checkpoints the user trusts (``--trust-checkpoint``).

    The observations are normalised as the statistics say; a model whose zoo ``config.yml``
    says it was trained on normalised observations but whose statistics are missing is
    refused, naming the file (it would run on raw inputs and drive nonsense)."""
    import pickle

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    warnings.warn(
        f"loading {model_file} with pickle (--trust-checkpoint): a crafted file can run code",
        stacklevel=2,
    )
    stats, config = sb3_stats(model_file)
    if stats is None and config is not None and zoo_normalizes(config):
        missing = config.parent / SB3_STATS
        raise InputError(
            "policy",
            missing.name,
            f"not found at {missing}, though {config} says the model was trained on "
            "normalised observations; allowed: the run folder as rl-baselines3-zoo wrote it, "
            "with its statistics",
        )
    _check_actor_critic(model_file)
    try:
        model = PPO.load(model_file, device="cpu")
    except Exception as exc:  # a malformed zip fails anywhere in SB3's loader: one line
        raise InputError(
            "policy",
            str(model_file),
            f"cannot be loaded as a Stable-Baselines3 PPO model ({type(exc).__name__}: {exc})",
        ) from None
    obs_space = model.policy.observation_space
    norm = None
    if stats is not None:
        try:
            with open(stats, "rb") as f:
                vn = pickle.load(f)
        except Exception as exc:  # truncated or not a pickle
            raise InputError(
                "policy", str(stats), f"cannot be unpickled ({type(exc).__name__}: {exc})"
            ) from None
        if not isinstance(vn, VecNormalize):
            raise InputError("policy", str(stats), "allowed: a pickled VecNormalize")
        if vn.norm_obs:
            norm = _sb3_normalizer(vn, obs_space, stats)
    if stats is None and config is None:
        # SB3's zip does not record VecNormalize: a normalised policy's statistics left behind
        # would run it on raw observations (and drive nonsense) without a word
        warnings.warn(
            Notice(
                f"no {SB3_STATS} beside {model_file}: the policy reads raw observations; if it "
                f"was trained under VecNormalize, put its {SB3_STATS} in the same folder"
            ),
            stacklevel=2,
        )
    meta = {
        "policy": type(model.policy).__name__,
        "num_timesteps": int(model.num_timesteps),
        "normalization_file": str(stats) if stats is not None else None,
    }
    return Loaded(model.policy, norm, meta)


#: SB3 and sb3-contrib algorithms whose policies are not the actor-critic ``PPO.load`` builds
#: (PPO's and A2C's are one class; a custom subclass of it is left to the loader)
_OTHER_FAMILIES = frozenset(
    {"sac", "td3", "ddpg", "dqn", "qrdqn", "tqc", "crossq", "ppo_recurrent"}
)
_SB3_PACKAGES = ("stable_baselines3", "sb3_contrib")
MAX_SB3_DATA_BYTES = 16 << 20


def _check_actor_critic(model_file: Path) -> None:
    """Refuse, by name, an SB3 model of another algorithm family (SAC, TD3, DQN: their zips
    fail inside ``PPO.load`` with a constructor's TypeError). The zip's ``data`` JSON names the
    policy class's module without unpickling it; a zip that does not say is left to the
    loader."""
    try:
        with zipfile.ZipFile(model_file) as zf:
            info = zf.getinfo("data")
            if info.file_size > MAX_SB3_DATA_BYTES:
                return
            data = json.loads(zf.read(info))
        module = data["policy_class"]["__module__"]
    except Exception:  # not SB3's layout: PPO.load says what is wrong with it
        return
    parts = module.split(".") if isinstance(module, str) else []
    if len(parts) < 2 or parts[0] not in _SB3_PACKAGES or parts[1] not in _OTHER_FAMILIES:
        return
    family = "RecurrentPPO" if parts[1] == "ppo_recurrent" else parts[1].upper()
    raise InputError(
        "policy",
        str(model_file),
        f"is a {family} model ({module}); allowed: a PPO or A2C model (an actor-critic "
        "policy, which agrinav runs as PPO)",
    )


def _sb3_normalizer(vn: Any, obs_space: Any, stats: Path) -> Normalizer:
    """VecNormalize's observation statistics, checked against the model's spaces."""
    rms = vn.obs_rms
    keys = sorted(getattr(obs_space, "spaces", {}))
    if not isinstance(rms, dict) or not set(rms) <= set(keys):
        found = sorted(rms) if isinstance(rms, dict) else type(rms).__name__
        raise InputError(
            "policy",
            str(stats),
            f"holds statistics for {found}; the model observes {keys}",
        )
    mean, var = {}, {}
    for k, r in rms.items():
        shape = obs_space.spaces[k].shape
        m, v = np.asarray(r.mean, np.float64), np.asarray(r.var, np.float64)
        if m.shape != shape or v.shape != shape or not (np.isfinite(m).all() and (v >= 0).all()):
            raise InputError(
                "policy", str(stats), f"statistics of {k!r} do not fit its space {shape}"
            )
        mean[k], var[k] = m, v
    clip, eps = float(vn.clip_obs), float(vn.epsilon)
    if not (math.isfinite(clip) and clip > 0 and math.isfinite(eps) and eps > 0):
        raise InputError("policy", str(stats), "allowed: clip_obs > 0 and epsilon > 0, finite")
    return Normalizer(mean, var, clip, eps)
