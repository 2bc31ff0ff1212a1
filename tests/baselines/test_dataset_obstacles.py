"""Obstacles in the perception dataset's labels: a stone in front of the camera is labelled
(kind, pixels, boxes), a field without obstacles lists none, and the card counts them."""

from __future__ import annotations

import dataclasses
import io
import json
import tarfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.render.classes import CROP, OBSTACLE, WEED
from agrinav_gym.sensors.d455 import color_model
from baselines.dataset import load_spec
from baselines.dataset.card import write_card
from baselines.dataset.labels import bbox_2d, to_camera
from baselines.dataset.perception import _frame, write_tar
from baselines.dataset.run import MANIFEST
from scenario_gen import Scenario, generate
from scenario_gen.obstacles import STONE, Obstacles

from ..fields import STILL
from ..scenario_gen.helpers import plane

SPEC = load_spec(None, {"width": 212, "height": 120})
STONE_SIZE = (0.26, 0.18, 0.12)


def make_env(scn: Scenario) -> Any:
    """The dataset's env (mesh camera, RGB, segmentation) on one fixed field, started on the
    lane centre facing along it."""
    return gym.make(
        SPEC.env,
        scenario=scn,
        config={
            "camera": {
                "model": "mesh",
                "width": SPEC.width,
                "height": SPEC.height,
                "rgb": True,
                "segmentation": True,
            },
            "task": STILL["task"],
        },
        observations=["gps", "imu", "odom", "depth"],
    )


def frame_of(scn: Scenario) -> tuple[Any, Any]:
    """One dataset frame (``perception._frame``) after the first step; the env's base pose."""
    env = make_env(scn)
    try:
        u = env.unwrapped
        env.reset(seed=0)
        obs, _, _, _, info = env.step(np.zeros(2, np.float32))
        depth_cam = u.interface.camera
        cams = {"depth": depth_cam, "rgb": color_model(depth_cam)}
        f = _frame("000000_00000", u, obs, info, cams, SPEC, ("train", 0, 0, 1))
        return f, (np.asarray(u.state.pos, float), np.asarray(u.state.rot, float))
    finally:
        env.close()


@pytest.fixture(scope="module")
def without() -> tuple[Scenario, Any, Any]:
    scn = generate(plane(crop={"stage": 2}), 0)
    f, pose = frame_of(scn)
    return scn, f, pose


@pytest.fixture(scope="module")
def with_stone(without: tuple[Scenario, Any, Any]) -> tuple[Scenario, Any, Any]:
    """The same field with a stone 1.6 m ahead of where the robot stood in the first frame."""
    scn, _, (pos, rot) = without
    xy = pos[:2] + 1.6 * rot[:2, 0]
    z = float(scn.terrain.height_at(xy[0], xy[1]))
    one = np.array
    stone = Obstacles(
        one([STONE], "<U6"), one([xy[0]]), one([xy[1]]), one([z]), one([0.0]), one([0.0]),
        one([0.7]), one([STONE_SIZE[0]]), one([STONE_SIZE[1]]), one([STONE_SIZE[2]]),
        one([11], np.int64),
    )  # fmt: skip
    scn2 = dataclasses.replace(scn, obstacles=stone)
    f, pose = frame_of(scn2)
    return scn2, f, pose


def test_a_field_without_obstacles_labels_none(without: tuple[Scenario, Any, Any]) -> None:
    _, f, _ = without
    assert f.labels["obstacles"] == []
    assert not (f.semantic == OBSTACLE).any()


def test_a_stone_in_front_of_the_camera_is_labelled(with_stone: tuple[Scenario, Any, Any]) -> None:
    scn, f, (pos, rot) = with_stone
    (rec,) = f.labels["obstacles"]
    assert rec["id"] == 0 and rec["kind"] == STONE
    mine = (f.semantic == OBSTACLE) & (f.instance == 0)
    assert rec["visible_pixels"] == int(mine.sum()) > 20
    # the 2-D box holds every pixel centre the stone covers in the depth camera's images
    u0, v0, u1, v1 = rec["bbox_2d_depth"]
    rows, cols = np.nonzero(mine)
    assert u0 <= cols.min() and cols.max() <= u1 and v0 <= rows.min() and rows.max() <= v1
    # ... and is no wider than a pixel around them (the mesh's image, not the box's)
    assert cols.min() - u0 <= 1.5 and u1 - cols.max() <= 1.5
    assert rows.min() - v0 <= 1.5 and v1 - rows.max() <= 1.5
    assert rec["bbox_2d_rgb"] is not None
    # the 3-D box: the stone's size, its centre half its height above the ground, ahead
    box = rec["box_3d"]
    assert box["size"] == pytest.approx(list(STONE_SIZE), abs=1e-4)
    obs = scn.obstacles
    centre = np.array([obs.x[0], obs.y[0], obs.z[0] + 0.5 * STONE_SIZE[2]])
    cam = f.labels["cameras"]["depth"]
    assert cam["width"] == 212
    q = np.array(box["centre"])
    assert np.linalg.norm(q) == pytest.approx(
        np.linalg.norm(centre - (pos + rot @ np.asarray(depth_mount(f)))), abs=1e-3
    )
    corners = np.array(box["corners"])
    assert corners.shape == (8, 3)
    assert corners.mean(axis=0) == pytest.approx(q, abs=1e-4)
    # the yaw: the stone's heading (0.7 rad in ENU) less the camera's, about the vertical
    heading = float(np.arctan2(rot[1, 0], rot[0, 0]))  # the camera looks along base_link's x
    assert box["yaw"] == pytest.approx(0.7 - heading, abs=1e-4)
    # plant pixel counts leave the stone's pixels out (its id 0 is also a plant's row)
    for p in f.labels["plants"]:
        own = (f.instance == p["id"]) & np.isin(f.semantic, (CROP, WEED))
        assert p["visible_pixels"] == int(own.sum())


def depth_mount(f: Any) -> Any:
    """The depth camera's position in base_link, from the labels' extrinsics."""
    return np.array(f.labels["cameras"]["depth"]["T_base_optical"])[:3, 3]


def test_bbox_of_a_mesh_crossing_the_camera_plane_is_clipped() -> None:
    """A box from behind the camera to in front of it: only the part in front projects."""
    from agrinav_gym.interface import CameraModel

    cam = CameraModel.from_fov(100, 80, 1.2, 1.0, (0.0, 0.0, 0.0), 0.0, 0.1, 10.0)
    v = np.array([[x, y, z] for x in (-1.0, 2.0) for y in (-0.2, 0.2) for z in (-0.1, 0.1)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])  # fmt: skip
    box = bbox_2d(to_camera(v, np.zeros(3), np.eye(3), cam), f, cam)
    assert box == [-0.5, -0.5, 99.5, 79.5]  # it fills the view: clipped to the image
    assert bbox_2d(to_camera(v - [3.0, 0, 0], np.zeros(3), np.eye(3), cam), f, cam) is None


def test_the_card_counts_obstacles_by_kind(
    with_stone: tuple[Scenario, Any, Any], tmp_path: Path
) -> None:
    _, f, _ = with_stone
    out = tmp_path / "ds"
    out.mkdir()
    buf = io.BytesIO()
    write_tar(iter([f]), buf)
    (out / "shard-000000.tar").write_bytes(buf.getvalue())
    man = {
        "schema": f.labels["schema"], "seed": 0, "digest": "x", "shards": 1,
        "frames_per_shard": 1, "spec": {"width": 212, "height": 120, "env": SPEC.env,
        "policy": SPEC.policy, "steer_noise": SPEC.steer_noise},
        "splits": {"train": {"scenario_seeds": [0, 1], "shards": ["shard-000000.tar"]}},
    }  # fmt: skip
    (out / MANIFEST).write_text(json.dumps(man))
    write_card(out)
    text = (out / "README.md").read_text()
    assert "stone: 1 (1), litter: 0 (0), stalk: 0 (0)" in text
    with tarfile.open(out / "shard-000000.tar") as tar:
        assert any(m.name.endswith(".json") for m in tar.getmembers())
