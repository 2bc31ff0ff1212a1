"""PPO checkpoints in a format that cannot execute code.

A checkpoint folder holds ``policy.npz`` (the network's tensors; read with
``allow_pickle=False``), optionally ``optimizer.npz`` (Adam's moments, for resuming training)
and ``checkpoint.json``: the observation and action spaces, the policy class (one of a fixed
list) and its keyword arguments (plain JSON), the observation-normalisation statistics and the
training metadata. Loading builds the network from that description and fills it with the
arrays: nothing is unpickled, so a crafted checkpoint can at worst fail to load.

Stable-Baselines3's own ``model.zip`` unpickles Python objects (and ``vecnormalize.pkl`` is a
pickle): those load only through ``load_sb3_trusted``, behind ``--trust-checkpoint``.
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

from scenario_gen.errors import InputError
from scenario_gen.schema import parse_json

FORMAT = "agrinav-ppo"
VERSION = 1
META = "checkpoint.json"
WEIGHTS = "policy.npz"
OPTIMIZER = "optimizer.npz"
MAX_META_BYTES = 1 << 20
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


def policy_kwargs_from_json(d: Any) -> dict[str, Any]:
    """Only plain, known keyword arguments; class-valued ones come from a fixed list."""
    from torch import nn

    if not isinstance(d, dict) or set(d) - POLICY_KWARGS:
        raise InputError(
            "checkpoint policy_kwargs", d, f"allowed keys: {', '.join(sorted(POLICY_KWARGS))}"
        )
    out = dict(d)
    arch = out.get("net_arch")
    if arch is not None:
        layers = list(arch.values()) if isinstance(arch, dict) else [arch]
        sizes = [n for group in layers for n in (group if isinstance(group, list) else [group])]
        if not sizes or not all(
            isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= MAX_LAYER for n in sizes
        ):
            raise InputError(
                "checkpoint net_arch", arch, f"allowed: layer sizes from 1 to {MAX_LAYER}"
            )
    if "activation_fn" in out:
        if out["activation_fn"] not in ACTIVATIONS:
            raise InputError(
                "checkpoint activation_fn",
                out["activation_fn"],
                f"allowed: {', '.join(ACTIVATIONS)}",
            )
        out["activation_fn"] = getattr(nn, out["activation_fn"])
    return out


def policy_kwargs_to_json(kwargs: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in kwargs.items() if k in POLICY_KWARGS}
    if "activation_fn" in out:
        out["activation_fn"] = out["activation_fn"].__name__
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
    if not (math.isfinite(clip) and clip > 0 and math.isfinite(eps) and eps > 0):
        # clip <= 0 made every observation 0: a blind policy that still "ran"
        raise InputError(
            "checkpoint normalization", [clip, eps], "allowed: clip > 0 and epsilon > 0, finite"
        )
    return Normalizer(mean, var, clip, eps)


def load_sb3_trusted(model_file: Path) -> Loaded:
    """An SB3 ``model.zip`` (+ ``vecnormalize.pkl``): unpickles, so it can run code — only for
    checkpoints the user trusts (``--trust-checkpoint``)."""
    import pickle

    from stable_baselines3 import PPO

    warnings.warn(
        f"loading {model_file} with pickle (--trust-checkpoint): a crafted file can run code",
        stacklevel=2,
    )
    model = PPO.load(model_file, device="cpu")
    stats = model_file.parent / "vecnormalize.pkl"
    norm = None
    if stats.is_file():
        with open(stats, "rb") as f:
            vn = pickle.load(f)
        norm = Normalizer(
            {k: r.mean for k, r in vn.obs_rms.items()},
            {k: r.var for k, r in vn.obs_rms.items()},
            float(vn.clip_obs),
            float(vn.epsilon),
        )
    return Loaded(model.policy, norm, {"policy": type(model.policy).__name__})
