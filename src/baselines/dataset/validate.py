"""Is the data useful? A tiny lane-offset regressor trained on some fields, tested on others.

Ridge regression from the depth image (block-averaged, invalid pixels as 0) to the robot's
lateral offset from the lane centre: the simplest learner that could use the rows' geometry.
Shards hold different fields, so holding out whole shards holds out fields. It must beat
predicting the training mean on the held-out fields, or the labels and images do not agree.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray
from scenario_gen.errors import InputError

from .loader import PerceptionDataset


@dataclass(frozen=True)
class Validation:
    train_frames: int
    test_frames: int
    model_mae: float  # m, held-out fields
    mean_mae: float  # m, predicting the training mean

    def __str__(self) -> str:
        return (
            f"lane offset on {self.test_frames} held-out frames (trained on "
            f"{self.train_frames}): ridge on depth {self.model_mae * 100:.1f} cm MAE, "
            f"training mean {self.mean_mae * 100:.1f} cm"
        )


def features(depth: NDArray[np.float32], block: int = 4) -> FloatArray:
    """Block means of the depth image (metres, invalid pixels 0), flattened, plus a bias."""
    h, w = depth.shape
    d = np.asarray(depth[: h - h % block, : w - w % block], np.float64)
    f = d.reshape(h // block, block, w // block, block).mean(axis=(1, 3)).ravel()
    return np.concatenate([f, [1.0]])


def validate(root: str | Path, ridge: float = 1.0) -> Validation:
    """Train on the ``train`` split's frames, test on the ``test`` split's (other fields,
    scenario seeds of another range)."""
    ds = PerceptionDataset(root)
    xs: dict[bool, list[FloatArray]] = {True: [], False: []}
    ys: dict[bool, list[float]] = {True: [], False: []}
    for i in range(len(ds)):
        s = ds[i]
        off = s["lateral_offset"]
        if s["split"] not in ("train", "test") or not np.isfinite(off):
            continue
        is_test = s["split"] == "test"
        xs[is_test].append(features(s["depth"]))
        ys[is_test].append(float(off))
    if not ys[False] or not ys[True]:
        raise InputError("dataset", str(root), "has no lane labels in the train or test fields")
    x, y = np.array(xs[False]), np.array(ys[False])
    mu, sd = x.mean(axis=0), x.std(axis=0) + 1e-6
    sd[-1], mu[-1] = 1.0, 0.0  # keep the bias column
    z = (x - mu) / sd
    w = np.linalg.solve(z.T @ z + ridge * len(y) * np.eye(z.shape[1]), z.T @ (y - 0.0))
    xt, yt = (np.array(xs[True]) - mu) / sd, np.array(ys[True])
    pred = xt @ w
    return Validation(
        len(y),
        len(yt),
        float(np.mean(np.abs(pred - yt))),
        float(np.mean(np.abs(y.mean() - yt))),
    )


@dataclass(frozen=True)
class FollowerCheck:
    frames: int
    estimated: int  # frames where both rows gave the lane centre
    mae: float  # m, |estimated offset − labelled offset|

    def __str__(self) -> str:
        return (
            f"depth follower's lane offset: estimated on {self.estimated} of {self.frames} "
            f"frames, {self.mae * 100:.1f} cm MAE against the labels"
        )


def _camera(c: dict[str, object]) -> object:
    """The depth camera of a frame's labels as a ``CameraModel``."""
    import math

    from agrinav_gym.interface import CameraModel

    t = np.asarray(c["T_base_optical"], np.float64)
    body_from_optical = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    r = t[:3, :3] @ body_from_optical.T  # R_y(pitch)
    pitch = math.atan2(r[0, 2], r[0, 0])
    f = {k: float(c[k]) for k in ("fx", "fy", "cx", "cy", "min_range", "max_range")}  # type: ignore[arg-type]
    return CameraModel(
        int(c["width"]),  # type: ignore[call-overload]
        int(c["height"]),  # type: ignore[call-overload]
        f["fx"],
        f["fy"],
        f["cx"],
        f["cy"],
        (float(t[0, 3]), float(t[1, 3]), float(t[2, 3])),
        pitch,
        f["min_range"],
        f["max_range"],
    )


def depth_follower_check(root: str | Path) -> FollowerCheck:
    """The depth follower's lane estimate on every frame against the lane label: it reports the
    lane centre's offset in the robot frame, the label the robot's offset from the centre
    (left positive along the direction of travel), so a perfect estimate is minus the label."""
    import dataclasses

    import gymnasium as gym

    import agrinav_gym  # noqa: F401
    from policies.depth_follower import DepthFurrowFollower

    env: Any = gym.make("AgriNav/FurrowFollowDepth-v3")
    try:
        base = env.unwrapped.interface
        obs_space, act_space = env.observation_space, env.action_space
    finally:
        env.close()
    ds = PerceptionDataset(root, parse_labels=True)
    errs: list[float] = []
    for i in range(len(ds)):
        s = ds[i]
        lab = s["labels"]
        off = lab["lane"]["lateral_offset"]
        if off is None:
            continue
        robot = dataclasses.replace(base, camera=_camera(lab["cameras"]["depth"]))
        follower = DepthFurrowFollower(
            obs_space, act_space, robot
        )  # fresh: no half-width carried over
        est = follower.lane(s["depth"])
        if est is not None and est[0] is not None:
            errs.append(abs(est[0] + off))
    return FollowerCheck(len(ds), len(errs), float(np.mean(errs)) if errs else float("nan"))


@dataclass(frozen=True)
class DrivingCheck:
    """How far off the lane centre a policy drives, measured by the labels of the frames taken
    while it drove (no injected perturbation)."""

    policy: str
    frames: int
    labelled: int  # frames with a lane label (a field with at least two rows)
    episodes: int  # episodes the frames span (an episode ends early when the robot leaves)
    mae: float  # m, mean |lateral offset|
    rmse: float  # m
    p95: float  # m, 95th percentile of |lateral offset|
    heading_mae_deg: float

    def __str__(self) -> str:
        return (
            f"{self.policy} driving: |lateral offset| {self.mae * 100:.1f} cm mean, "
            f"{self.rmse * 100:.1f} cm RMS, {self.p95 * 100:.1f} cm p95, heading "
            f"{self.heading_mae_deg:.1f}° mean on {self.labelled}/{self.frames} frames "
            f"({self.episodes} episodes)"
        )


#: A set for judging controllers: the RL camera (64×48 at the default mount, where the
#: learned depth policy was trained) and the policy driving on its own.
DRIVING_SPEC = {
    "width": 64,
    "height": 48,
    "frames_per_shard": 64,
    "frame_every": 4,
    "steer_noise": 0.0,
    "camera_height": [0.55, 0.55],
    "camera_pitch_deg": [25.0, 25.0],
}


def driving_check(
    policy: str,
    out: str | Path,
    frames: int,
    seed: int = 0,
    workers: int = 1,
    overrides: dict[str, Any] | None = None,
) -> DrivingCheck:
    """Generate frames with ``policy`` driving (``DRIVING_SPEC`` plus ``overrides``) into
    ``out`` and score its lateral and heading offsets from the labels."""
    from .run import generate
    from .spec import load_spec

    spec = load_spec(None, {**DRIVING_SPEC, "policy": policy, **(overrides or {})})
    generate(spec, out, seed=seed, frames=frames, workers=workers)
    return score_driving(policy, out)


def score_driving(policy: str, root: str | Path) -> DrivingCheck:
    """The labels' lateral and heading offsets over a generated set's frames."""
    ds = PerceptionDataset(root)
    off: list[float] = []
    head: list[float] = []
    episodes: set[tuple[Path, int]] = set()
    for i, (shard, _, _) in enumerate(ds.index):
        lab = ds.labels(i)
        episodes.add((shard, int(lab["episode"])))
        lane = lab["lane"]
        if lane["lateral_offset"] is None:
            continue
        off.append(abs(float(lane["lateral_offset"])))
        head.append(abs(float(lane["heading_offset"])))
    if not off:
        raise InputError("dataset", str(root), "has no frame inside a lane to score")
    a = np.asarray(off)
    return DrivingCheck(
        policy,
        len(ds),
        len(a),
        len(episodes),
        float(a.mean()),
        float(np.sqrt((a**2).mean())),
        float(np.percentile(a, 95)),
        float(np.degrees(np.mean(head))),
    )
