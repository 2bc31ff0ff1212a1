"""``agrinav dataset perception``: labelled RGB-D frames from randomized fields, in tar shards.

Shard ``i`` depends only on (spec, seed, i): its own ``SeedSequence([seed, i])`` draws the
camera mount, the episodes' reset seeds and the steering perturbation, and the fields come from
scenario seeds of a range no training or evaluation split uses. A shard is written to a hidden
temporary file and renamed into place, so a killed run leaves whole shards only; a rerun skips
the shards that exist (a finished dataset is a no-op) and the same spec and seed give
byte-identical shards.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import tarfile
import warnings
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from agrinav_gym.interface import OBS_DEPTH, OBS_GPS, OBS_IMU, OBS_ODOM, OBSERVATION_KEYS
from scenario_gen.atomic import atomic_write
from scenario_gen.errors import InputError

from .labels import camera_dict, camera_reach, lane_offset, obstacles, plants, row_lines
from .spec import SCHEMA_VERSION, PerceptionSpec

#: Scenario seeds of dataset fields, one range per split: disjoint from each other and from the
#: RL envs' train [0, 1e6), validation [5e8, +1e6) and test [1e9, +1e6) ranges.
SPLIT_SEEDS = {
    "train": (2_000_000_000, 2_800_000_000),
    "validation": (2_800_000_000, 2_900_000_000),
    "test": (2_900_000_000, 3_000_000_000),
}
#: every split's fields together (one range: what a dataset's fields may be drawn from)
DATASET_SCENARIO_SEEDS = (
    min(lo for lo, _ in SPLIT_SEEDS.values()),
    max(hi for _, hi in SPLIT_SEEDS.values()),
)
#: The split of shard i: a cycle of ten shards, 8 train, 1 validation, 1 test (the first three
#: shards already cover all three, so even a small dataset can be evaluated on unseen fields).
SPLIT_CYCLE = ("train", "validation", "test", *("train",) * 7)


def split_of(index: int) -> str:
    return SPLIT_CYCLE[index % len(SPLIT_CYCLE)]


OBSERVATIONS = list(OBSERVATION_KEYS)


@dataclass
class Frame:
    key: str
    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    semantic: NDArray[np.uint8]
    instance: NDArray[np.int32]
    labels: dict[str, Any]


def make_env(
    spec: PerceptionSpec, camera_height: float, pitch_deg: float, split: str = "train"
) -> Any:
    """The env a shard's frames come from: mesh camera with RGB and segmentation at the spec's
    size, rendering only on frame steps, fields from the split's scenario seeds."""
    import gymnasium as gym

    import agrinav_gym

    control_hz = 20
    config = {
        "camera": {
            "model": "mesh",
            "width": spec.width,
            "height": spec.height,
            "rgb": True,
            "segmentation": True,
            "rate_hz": control_hz // spec.frame_every if control_hz % spec.frame_every == 0 else 20,
        },
        "robot": {"camera_height": camera_height, "camera_pitch_deg": pitch_deg},
    }
    return gym.make(
        agrinav_gym.check_env_id(spec.env, "spec.env"),
        scenario=spec.preset,
        scenario_overrides={"field": {"length": spec.field_length}},
        randomize=spec.randomize,
        scenario_seeds=list(SPLIT_SEEDS[split]),
        config=config,
        observations=OBSERVATIONS,
    )


@contextlib.contextmanager
def field_rules(spec: PerceptionSpec) -> Iterator[None]:
    """A field the spec cannot lay out names the rule it broke and the spec's fields that
    shape every field (the rule's own field, e.g. ``layout.headland``, is the env's)."""
    try:
        yield
    except InputError as exc:
        if exc.field.startswith("spec."):
            raise
        raise InputError(
            exc.field,
            exc.value,
            f"{exc.allowed} (in the dataset's fields: spec.preset {spec.preset!r} "
            f"{spec.field_length:g} m long (spec.field_length), drawn from spec.randomize)",
        ) from None


def check(spec: PerceptionSpec) -> None:
    """Build one env with the spec's randomization (every range is checked by the env's own
    ``Randomization``), generate its first field and build the policy against it, before a
    file is written: a field the spec cannot lay out, or a checkpoint made for other
    observations, is refused here, not in a worker mid-run."""
    from agrinav_gym.scenarios import FixedFieldWarning
    from policies import check_policy_spec, make_policy

    check_policy_spec(spec.policy)
    if 20 % spec.frame_every:
        raise InputError(
            "spec.frame_every", spec.frame_every, "allowed: a divisor of the 20 Hz control rate"
        )
    with field_rules(spec), warnings.catch_warnings():
        warnings.simplefilter("ignore", FixedFieldWarning)  # refused below, in the spec's words
        env = make_env(spec, spec.camera_height[0], spec.camera_pitch_deg[0])
    try:
        if env.unwrapped.source.fixed_field() is not None:
            # the splits' disjoint seed ranges would draw one field for all three
            raise InputError(
                "spec.randomize",
                sorted(spec.randomize),
                "holds no scenario key, so every shard of every split would show the same "
                "field; allowed: at least one scenario key (e.g. layout.plant_spacing, "
                "crop.stage): its draws make each split's fields its own",
            )
        with field_rules(spec):
            env.reset(seed=0)
        make_policy(spec.policy, env)
    finally:
        env.close()


def shard_frames(spec: PerceptionSpec, seed: int, index: int) -> Iterator[Frame]:
    """The frames of shard ``index``: a policy drives, perturbed, and every ``frame_every``-th
    step is a frame."""
    from agrinav_gym.sensors.d455 import color_model
    from policies import make_policy

    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(index)]))
    cam_h = float(rng.uniform(*spec.camera_height))
    pitch = float(rng.uniform(*spec.camera_pitch_deg))
    split = split_of(index)
    with field_rules(spec):
        env = make_env(spec, cam_h, pitch, split)
    try:
        u = env.unwrapped
        depth_cam = u.interface.camera
        cams = {"depth": depth_cam, "rgb": color_model(depth_cam)}
        pi = make_policy(spec.policy, env)
        dt, w_max = u.dt, u.interface.w_max
        a = math.exp(-dt / spec.steer_noise_tau)
        made, episode = 0, 0
        while made < spec.frames_per_shard:
            reset_seed = int(rng.integers(2**31))
            with field_rules(spec):
                obs, info = env.reset(seed=reset_seed)
            pi.reset()
            noise, step = 0.0, 0
            while made < spec.frames_per_shard:
                act = np.asarray(pi.act(obs), np.float32).copy()
                noise = a * noise + spec.steer_noise * math.sqrt(1 - a * a) * rng.normal()
                act[1] = np.clip(act[1] + noise / w_max, -1.0, 1.0)
                obs, _, term, trunc, info = env.step(act)
                step += 1
                if step % spec.frame_every == 0:
                    key = f"{index:06d}_{made:05d}"
                    yield _frame(key, u, obs, info, cams, spec, (split, episode, reset_seed, step))
                    made += 1
                if term or trunc:
                    break
            episode += 1
    finally:
        env.close()


def _frame(
    key: str,
    u: Any,
    obs: dict[str, Any],
    info: dict[str, Any],
    cams: dict[str, Any],
    spec: PerceptionSpec,
    where: tuple[str, int, int, int],  # split, episode, reset seed, step
) -> Frame:
    split, episode, reset_seed, step = where
    reach = spec.label_range if spec.label_range is not None else camera_reach(cams)
    scn, st = u.scenario, u.state
    pos, rot = np.asarray(st.pos, np.float64), np.asarray(st.rot, np.float64)
    yaw = float(st.rpy[2])
    lat, lon, alt = scn.geo.enu_to_geodetic(pos[0], pos[1], pos[2])
    instance = np.asarray(info["instance"], np.int32)
    semantic = np.asarray(info["segmentation"], np.uint8)
    labels = {
        "schema": SCHEMA_VERSION,
        "key": key,
        "split": split,
        "scenario": {
            "seed": scn.seed,
            "species": scn.spec.crop.species,
            "stage": scn.spec.crop.stage,
            "row_spacing": scn.spec.layout.row_spacing,
            "row_angle_rad": round(float(scn.rows.angle), 6),
            "site": scn.spec.terrain.site,
        },
        "episode": episode,
        "reset_seed": reset_seed,
        "step": step,
        "pose": {
            "enu": np.round(pos, 4).tolist(),
            "rpy": np.round(np.asarray(st.rpy, np.float64), 5).tolist(),
            "lat": round(float(np.asarray(lat)), 9),
            "lon": round(float(np.asarray(lon)), 9),
            "alt": round(float(np.asarray(alt)), 4),
        },
        "gnss": np.round(np.asarray(obs[OBS_GPS], np.float64), 5).tolist(),
        "imu": np.round(np.asarray(obs[OBS_IMU], np.float64), 5).tolist(),
        "odom": np.round(np.asarray(obs[OBS_ODOM], np.float64), 5).tolist(),
        "cameras": {name: camera_dict(c) for name, c in cams.items()},
        "lane": lane_offset(scn, pos[:2], yaw),
        "route_cte": round(float(info["cte"]), 4),  # the env's own cross-track error, m
        "rows": row_lines(scn, pos, rot, cams, reach),
        "plants": plants(scn, pos, rot, cams, instance, reach, semantic),
        "obstacles": obstacles(scn, pos, rot, cams, semantic, instance, reach),
    }
    # the env hands out copies (observations.Depth), so a frame may be encoded while it steps on
    depth = np.asarray(obs[OBS_DEPTH], np.float32).reshape(spec.height, spec.width)
    return Frame(
        key,
        np.asarray(info["rgb"], np.uint8),
        depth,
        semantic,
        instance,
        labels,
    )


# ------------------------------------------------------------------------------- storage
def _png(img: NDArray[Any]) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".png", img[..., ::-1] if img.ndim == 3 else img)
    if not ok:  # pragma: no cover
        raise OSError("PNG encoding failed")
    return bytes(buf)


def _npy(arr: NDArray[Any]) -> bytes:
    b = io.BytesIO()
    np.save(b, arr, allow_pickle=False)
    return b.getvalue()


def _add(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    ti = tarfile.TarInfo(name)
    ti.size, ti.mtime, ti.mode, ti.uid, ti.gid = len(data), 0, 0o644, 0, 0
    ti.uname = ti.gname = ""
    tar.addfile(ti, io.BytesIO(data))


def _encode(f: Frame) -> list[tuple[str, bytes]]:
    """A frame's tar members, in order."""
    text = json.dumps(f.labels, sort_keys=True, allow_nan=False, default=_nan)
    return [
        (f"{f.key}.rgb.png", _png(f.rgb)),
        (f"{f.key}.depth.npy", _npy(f.depth)),
        (f"{f.key}.semantic.png", _png(f.semantic)),
        (f"{f.key}.instance.npy", _npy(f.instance)),
        (f"{f.key}.json", text.encode()),
    ]


def _encoded(frames: Iterator[Frame], overlap: bool) -> Iterator[list[tuple[str, bytes]]]:
    """Each frame's members, in frame order; with ``overlap`` frame k is encoded in a second
    thread while frame k + 1 is made."""
    if not overlap:
        yield from map(_encode, frames)
        return
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="agrinav-encode") as pool:
        pending: Future[list[tuple[str, bytes]]] | None = None
        for f in frames:
            job = pool.submit(_encode, f)
            if pending is not None:
                yield pending.result()
            pending = job
        if pending is not None:
            yield pending.result()


def write_tar(frames: Iterator[Frame], fileobj: BinaryIO, overlap: bool = False) -> int:
    """WebDataset layout: ``<key>.rgb.png``, ``.depth.npy`` (float32 m, 0 invalid),
    ``.semantic.png``, ``.instance.npy`` (int32: the row of plants.csv on crop and weed
    pixels, of obstacles.csv on obstacle pixels, -1 elsewhere), ``.json``. With
    ``overlap`` a frame is encoded (PNG mostly, which releases the GIL) in a second thread while
    the next one renders: for a core the workers leave idle. The members are written in frame
    order either way, so the bytes are the same."""
    n = 0
    with tarfile.open(fileobj=fileobj, mode="w", format=tarfile.USTAR_FORMAT) as tar:
        for members in _encoded(frames, overlap):
            for name, data in members:
                _add(tar, name, data)
            n += 1
    return n


def write_shard(frames: Iterator[Frame], path: Path, overlap: bool = False) -> int:
    """The frames as a tar shard at ``path``, written to a temporary file and renamed, so the
    shard exists whole or not at all (``overlap``: see ``write_tar``)."""

    def write(tmp: Path) -> int:
        with open(tmp, "wb") as fh:
            return write_tar(frames, fh, overlap)

    return atomic_write(path, write)


def shard_bytes(spec: PerceptionSpec, seed: int, index: int) -> tuple[int, int, bytes]:
    """Shard ``index`` in memory: (index, frames, tar bytes) — what a Ray task returns."""
    buf = io.BytesIO()
    n = write_tar(shard_frames(spec, seed, index), buf)
    return index, n, buf.getvalue()


def save_shard(data: bytes, path: Path) -> None:
    """Tar bytes made elsewhere, written and renamed like ``write_shard``."""
    atomic_write(path, lambda tmp: tmp.write_bytes(data))


def _nan(obj: Any) -> Any:  # pragma: no cover  (labels are plain)
    raise TypeError(f"not JSON: {type(obj).__name__}")
