"""A PPO policy's actor as an ONNX graph: normalisation folded in, the deterministic action out.

Inputs: one per observation key the policy reads, named by the key (``imu``, ``route``, ...),
float32, shape ``(batch, *space shape)`` — the raw observation as the env returns it, laid out
as ``agrinav_gym.interface`` defines (``input_layout`` lists the fields). The observation
normalisation (VecNormalize's ``clip((x − mean) / √(var + ε), ±clip)``) runs inside the graph
in float64, as it does in numpy, so that large raw values (a GNSS fix in metres) lose nothing.
Output ``action``: float32 ``(batch, action dim)``, the Gaussian's mean clipped to the action
space — what ``PPOPolicy.act`` returns.

The graph is written node by node with ``onnx.helper`` from the network's own layers (Linear,
Conv2d, Flatten and the activations a checkpoint may name), so it needs neither torch's ONNX
exporter nor onnxscript; a layer outside that list is refused by name. ``onnx`` and
``onnxruntime`` are the optional extra ``export`` (``require_onnx``).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agrinav_gym.interface import (
    GPS_FIELDS,
    IMU_FIELDS,
    OBS_DEPTH,
    OBS_GPS,
    OBS_IMU,
    OBS_ODOM,
    OBS_ROUTE,
    ODOM_FIELDS,
    ROUTE_POINT_FIELDS,
)
from scenario_gen.errors import InputError

from .checkpoint import Loaded

#: ONNX operator set and IR version: opset 17 / IR 8 run on onnxruntime ≥ 1.13 and most
#: embedded runtimes; nothing newer is needed for these layers.
OPSET = 17
IR_VERSION = 8
OUTPUT = "action"
#: The largest difference between onnxruntime and the torch policy an export accepts.
TOLERANCE = 1e-5
EXTRA = "export"
LAYERS = ("Linear", "Conv2d", "Flatten", "ReLU", "Tanh", "ELU", "LeakyReLU", "Identity")


def require_onnx() -> None:
    """One line naming the extra to install when onnx or onnxruntime is missing."""
    for name in ("onnx", "onnxruntime"):
        try:
            __import__(name)
        except ImportError:
            raise InputError(
                "--to onnx",
                f"{name} is not installed",
                f"install the extra: pip install 'agrinav-gym[{EXTRA}]'",
            ) from None


def input_layout(obs_space: spaces.Dict) -> list[dict[str, Any]]:
    """The graph's inputs, in order: name, shape (``batch`` first), dtype and fields."""
    out = []
    for key in sorted(obs_space.spaces):
        shape = obs_space.spaces[key].shape
        assert shape is not None
        out.append(
            {"name": key, "shape": ["batch", *shape], "dtype": "float32", **_fields(key, shape)}
        )
    return out


def _fields(key: str, shape: tuple[int, ...]) -> dict[str, Any]:
    vectors = {OBS_GPS: GPS_FIELDS, OBS_IMU: IMU_FIELDS, OBS_ODOM: ODOM_FIELDS}
    if key in vectors and shape == (len(vectors[key]),):
        return {"fields": list(vectors[key])}
    if key == OBS_ROUTE and len(shape) == 1 and shape[0] % len(ROUTE_POINT_FIELDS) == 0:
        k = shape[0] // len(ROUTE_POINT_FIELDS)
        return {"fields": [f"{f}{i}" for i in range(k) for f in ROUTE_POINT_FIELDS]}
    if key == OBS_DEPTH:
        return {"layout": "(1, H, W) z-depth along the optical axis, m; 0 = invalid"}
    return {}


class _Graph:
    """Nodes and initializers, each with a fresh name."""

    def __init__(self) -> None:
        self.nodes: list[Any] = []
        self.initializers: list[Any] = []
        self._n = 0

    def _name(self, hint: str) -> str:
        self._n += 1
        return f"{hint}_{self._n}"

    def const(self, hint: str, value: NDArray[Any]) -> str:
        from onnx import numpy_helper

        name = self._name(hint)
        self.initializers.append(numpy_helper.from_array(np.ascontiguousarray(value), name))
        return name

    def op(self, op_type: str, inputs: list[str], hint: str, **attrs: Any) -> str:
        from onnx import helper

        out = self._name(hint)
        self.nodes.append(helper.make_node(op_type, inputs, [out], name=out, **attrs))
        return out


def _f32(t: Any) -> NDArray[np.float32]:
    return np.asarray(t.detach().cpu().numpy(), np.float32)


def _layer(g: _Graph, m: Any, x: str, hint: str) -> str:
    """One torch module applied to ``x``."""
    from torch import nn

    if isinstance(m, nn.Sequential):
        for i, sub in enumerate(m):
            x = _layer(g, sub, x, f"{hint}.{i}")
        return x
    if isinstance(m, nn.Linear):
        ins = [x, g.const(f"{hint}.weight", _f32(m.weight))]
        if m.bias is not None:
            ins.append(g.const(f"{hint}.bias", _f32(m.bias)))
        return g.op("Gemm", ins, hint, transB=1)
    if isinstance(m, nn.Conv2d):
        if m.padding_mode != "zeros" or isinstance(m.padding, str):
            raise InputError("export", f"Conv2d padding {m.padding!r}", "allowed: zero padding")
        ins = [x, g.const(f"{hint}.weight", _f32(m.weight))]
        if m.bias is not None:
            ins.append(g.const(f"{hint}.bias", _f32(m.bias)))
        ph, pw = m.padding
        return g.op(
            "Conv",
            ins,
            hint,
            kernel_shape=list(m.kernel_size),
            strides=list(m.stride),
            pads=[ph, pw, ph, pw],
            dilations=list(m.dilation),
            group=m.groups,
        )
    if isinstance(m, nn.Flatten):
        if m.end_dim != -1 or m.start_dim < 1:
            raise InputError("export", f"Flatten({m.start_dim}, {m.end_dim})", "allowed: (1, -1)")
        return g.op("Flatten", [x], hint, axis=m.start_dim)
    if isinstance(m, nn.ReLU):
        return g.op("Relu", [x], hint)
    if isinstance(m, nn.Tanh):
        return g.op("Tanh", [x], hint)
    if isinstance(m, nn.ELU):
        return g.op("Elu", [x], hint, alpha=float(m.alpha))
    if isinstance(m, nn.LeakyReLU):
        return g.op("LeakyRelu", [x], hint, alpha=float(m.negative_slope))
    if isinstance(m, nn.Identity):
        return x
    raise InputError("export", f"layer {type(m).__name__}", f"allowed: {', '.join(LAYERS)}")


def _features(g: _Graph, ext: Any, inputs: dict[str, str]) -> str:
    """The feature extractor: SB3's CombinedExtractor (each key flattened, in its order) or
    the depth CNN's ``DepthAndVector`` (vectors in sorted order, then the CNN's features)."""
    from stable_baselines3.common.torch_layers import CombinedExtractor

    from .extractors import DepthAndVector

    if isinstance(ext, CombinedExtractor):
        parts = [_layer(g, sub, inputs[k], f"features.{k}") for k, sub in ext.extractors.items()]
    elif isinstance(ext, DepthAndVector):
        parts = [inputs[k] for k in ext.vec_keys]
        if ext.cnn is not None:
            scale = g.const("depth.range", np.array(ext.max_range, np.float32))
            depth = g.op("Div", [inputs[OBS_DEPTH], scale], "depth.scaled")
            parts.append(_layer(g, ext.cnn, depth, "features.cnn"))
    else:
        raise InputError(
            "export",
            f"feature extractor {type(ext).__name__}",
            "allowed: CombinedExtractor, DepthAndVector",
        )
    return parts[0] if len(parts) == 1 else g.op("Concat", parts, "features", axis=1)


def _normalised(g: _Graph, loaded: Loaded, key: str, x: str) -> str:
    """``clip((x − mean) / √(var + ε), ±clip)`` in float64, back to float32."""
    from onnx import TensorProto

    n = loaded.normalizer
    if n is None or key not in n.mean:
        return x
    mean = g.const(f"norm.{key}.mean", np.asarray(n.mean[key], np.float64))
    std = g.const(f"norm.{key}.std", np.sqrt(np.asarray(n.var[key], np.float64) + n.epsilon))
    lo = g.const(f"norm.{key}.low", np.array(-n.clip, np.float64))
    hi = g.const(f"norm.{key}.high", np.array(n.clip, np.float64))
    y = g.op("Cast", [x], f"norm.{key}.f64", to=TensorProto.DOUBLE)
    y = g.op("Div", [g.op("Sub", [y, mean], f"norm.{key}.centred"), std], f"norm.{key}.scaled")
    y = g.op("Min", [g.op("Max", [y, lo], f"norm.{key}.max"), hi], f"norm.{key}.clipped")
    return g.op("Cast", [y], f"norm.{key}.f32", to=TensorProto.FLOAT)


def actor_graph(loaded: Loaded, properties: dict[str, str] | None = None) -> bytes:
    """The serialised ONNX model of ``loaded``'s deterministic actor (see the module doc);
    ``properties`` are added to its metadata."""
    import onnx
    from onnx import TensorProto, helper
    from stable_baselines3.common.distributions import DiagGaussianDistribution

    policy = loaded.policy
    obs_space, act_space = policy.observation_space, policy.action_space
    if not isinstance(obs_space, spaces.Dict) or not isinstance(act_space, spaces.Box):
        raise InputError(
            "export", type(obs_space).__name__, "allowed: Dict observations, Box actions"
        )
    if not isinstance(policy.action_dist, DiagGaussianDistribution) or policy.squash_output:
        raise InputError(
            "export",
            type(policy.action_dist).__name__,
            "allowed: a diagonal Gaussian policy without squashing (use_sde off)",
        )
    g = _Graph()
    layout = input_layout(obs_space)
    inputs = {d["name"]: _normalised(g, loaded, d["name"], d["name"]) for d in layout}
    x = _features(g, policy.pi_features_extractor, inputs)
    x = _layer(g, policy.mlp_extractor.policy_net, x, "policy_net")
    x = _layer(g, policy.action_net, x, "action_net")
    low = g.const("action.low", np.asarray(act_space.low, np.float32))
    high = g.const("action.high", np.asarray(act_space.high, np.float32))
    x = g.op("Max", [x, low], "action.max")
    g.nodes.append(helper.make_node("Min", [x, high], [OUTPUT], name=OUTPUT))
    n_act = int(np.prod(act_space.shape))
    graph = helper.make_graph(
        g.nodes,
        "agrinav_ppo_actor",
        [helper.make_tensor_value_info(d["name"], TensorProto.FLOAT, d["shape"]) for d in layout],
        [helper.make_tensor_value_info(OUTPUT, TensorProto.FLOAT, ["batch", n_act])],
        g.initializers,
    )
    model = helper.make_model(
        graph,
        opset_imports=[helper.make_opsetid("", OPSET)],
        producer_name="agrinav-gym",
        doc_string=__doc__.splitlines()[0] if __doc__ else "",
    )
    model.ir_version = IR_VERSION
    props = {
        "agrinav.inputs": json.dumps(layout),
        "agrinav.output": json.dumps(
            {
                "name": OUTPUT,
                "shape": ["batch", n_act],
                "dtype": "float32",
                "low": np.asarray(act_space.low, np.float64).tolist(),
                "high": np.asarray(act_space.high, np.float64).tolist(),
                "meaning": "deterministic action: the Gaussian's mean, clipped to [low, high]",
            }
        ),
        "agrinav.normalization": (
            "none"
            if loaded.normalizer is None
            else f"folded in, float64: clip((x - mean) / sqrt(var + {loaded.normalizer.epsilon}), "
            f"+-{loaded.normalizer.clip}) for {sorted(loaded.normalizer.mean)}"
        ),
        **(properties or {}),
    }
    helper.set_model_props(model, props)
    onnx.checker.check_model(model, full_check=True)
    return bytes(model.SerializeToString())


def torch_actions(loaded: Loaded, obs: dict[str, NDArray[Any]]) -> NDArray[np.float32]:
    """The torch policy's deterministic actions for a batch of raw observations (what
    ``PPOPolicy.act`` returns for each)."""
    import torch

    o = {k: np.asarray(obs[k], np.float32) for k in sorted(loaded.policy.observation_space.spaces)}
    if loaded.normalizer is not None:
        o = loaded.normalizer(o)
    # one thread: a threaded float32 GEMM may split its sums by the threads free at the moment,
    # so the reference would move with the machine's load (measured: 4e-5 on an extreme input)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        action, _ = loaded.policy.predict(o, deterministic=True)
    finally:
        torch.set_num_threads(threads)
    space = loaded.policy.action_space
    return np.clip(np.asarray(action, np.float64), space.low, space.high).astype(np.float32)


def onnx_actions(model: bytes, obs: dict[str, NDArray[Any]]) -> NDArray[np.float32]:
    """onnxruntime's actions (CPU) for a batch of raw observations."""
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.log_severity_level = 3
    opts.intra_op_num_threads = 1  # the same sums whatever the load (see torch_actions)
    sess = ort.InferenceSession(model, opts, providers=["CPUExecutionProvider"])
    feeds = {i.name: np.asarray(obs[i.name], np.float32) for i in sess.get_inputs()}
    return np.asarray(sess.run([OUTPUT], feeds)[0], np.float32)


def sample_observations(loaded: Loaded, n: int, seed: int = 0) -> dict[str, NDArray[np.float32]]:
    """``n`` observations: half drawn uniformly from the observation space (extremes, clipped
    by the normalisation), half around the normalisation statistics (the values training saw),
    clipped to the space."""
    space = loaded.policy.observation_space
    rng = np.random.default_rng(seed)
    out: dict[str, NDArray[np.float32]] = {}
    half = n // 2
    for k in sorted(space.spaces):
        box = space.spaces[k]
        lo = np.maximum(np.asarray(box.low, np.float64), -1e6)  # unbounded: a wide range
        hi = np.minimum(np.asarray(box.high, np.float64), 1e6)
        uniform = rng.uniform(lo, hi, (half, *box.shape))
        n_ = loaded.normalizer
        if n_ is not None and k in n_.mean:
            centre, spread = n_.mean[k], np.sqrt(n_.var[k])
        else:
            centre, spread = (lo + hi) / 2, (hi - lo) / 8
        near = np.clip(centre + spread * rng.standard_normal((n - half, *box.shape)), lo, hi)
        out[k] = np.concatenate([uniform, near]).astype(np.float32)
    return out
