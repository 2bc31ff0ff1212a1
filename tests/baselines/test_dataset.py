"""agrinav dataset perception: labels, determinism, resumption, bad input, the loader."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from baselines.cli import main
from baselines.dataset import PerceptionDataset, generate, load_spec
from baselines.dataset.perception import shard_frames, write_shard
from baselines.dataset.run import shard_name
from scenario_gen.errors import InputError

TINY = {"width": 48, "height": 32, "frames_per_shard": 2, "frame_every": 4}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "ds"
    assert generate(load_spec(None, TINY), out, seed=7, frames=4) == 4
    return out


def test_frames_hold_every_array_and_label(dataset: Path) -> None:
    ds = PerceptionDataset(dataset)
    assert len(ds) == 4
    s = ds[0]
    assert s["rgb"].shape == (32, 48, 3) and s["rgb"].dtype == np.uint8
    assert s["depth"].shape == (32, 48) and s["depth"].dtype == np.float32
    assert s["semantic"].shape == (32, 48) and s["instance"].dtype == np.int32
    lab = s["labels"]
    for key in ("pose", "gnss", "imu", "cameras", "lane", "rows", "plants", "scenario"):
        assert key in lab
    assert set(lab["cameras"]) == {"depth", "rgb"}
    shown = set(np.unique(s["instance"])) - {-1}
    labelled = {p["id"]: p for p in lab["plants"]}
    # every plant the instance image shows is labelled, with its pixel count
    assert shown <= set(labelled)
    for i in shown:
        assert labelled[i]["visible_pixels"] == int((s["instance"] == i).sum())


def test_lane_offset_agrees_with_the_envs_cross_track_error(dataset: Path) -> None:
    # FurrowFollow's route is the lane centreline: the label (from the row geometry) and the
    # env's own metric (nearest route segment) are independent computations of one distance.
    for s in PerceptionDataset(dataset):
        lab = s["labels"]
        assert abs(abs(lab["lane"]["lateral_offset"]) - lab["route_cte"]) < 0.01


def test_the_same_spec_and_seed_give_byte_identical_shards(dataset: Path, tmp_path: Path) -> None:
    again = tmp_path / shard_name(1)
    write_shard(shard_frames(load_spec(None, TINY), 7, 1), again)
    assert again.read_bytes() == (dataset / shard_name(1)).read_bytes()


def test_a_killed_run_resumes_and_a_finished_one_is_a_no_op(dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "copy"
    shutil.copytree(dataset, out)
    before = (out / shard_name(0)).read_bytes()
    (out / shard_name(0)).unlink()
    (out / f".{shard_name(0)}.tmp-123").write_bytes(b"partial")  # what a kill leaves
    spec = load_spec(None, TINY)
    assert generate(spec, out, seed=7, frames=4) == 2
    assert (out / shard_name(0)).read_bytes() == before
    assert not list(out.glob(".shard-*"))
    assert generate(spec, out, seed=7, frames=4) == 0


def test_a_folder_of_another_dataset_is_refused(dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "copy"
    shutil.copytree(dataset, out)
    with pytest.raises(InputError, match="holds another dataset"):
        generate(load_spec(None, {**TINY, "steer_noise": 0.1}), out, seed=7, frames=4)
    assert json.loads((out / "dataset.json").read_text())["seed"] == 7


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--set", "colour=1"], "spec.colour"),
        (["--set", "width=5"], "spec.width: got 5"),
        (["--set", "camera_pitch_deg=[30, 10]"], "spec.camera_pitch_deg"),
        (["--set", "frame_every=7"], "spec.frame_every"),
        (["--set", "policy=mpc"], "policy: got 'mpc'"),
        (["--set", "randomize={crop.stage: [1, 60]}"], "crop.stage"),
    ],
)
def test_bad_specs_exit_2_and_write_nothing(
    tmp_path: Path, args: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(["dataset", "perception", "--out", str(out), "--frames", "2", *args]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_trajectories_are_a_minari_dataset_that_recovers_its_env(tmp_path: Path) -> None:
    pytest.importorskip("jax", reason="Minari's recorder needs the dataset extra (jax)")
    minari = pytest.importorskip("minari", reason="the dataset extra is not installed")
    from baselines.dataset.trajectories import INFO_KEYS, _datasets_root, record

    path = record("AgriNav/FurrowFollow-v1", "rpp", 2, tmp_path / "m", seed=3)
    with _datasets_root(tmp_path / "m"):
        data = minari.load_dataset("agrinav/furrow_follow-v0")
        assert data.total_episodes == 2
        ep = next(iter(data.iterate_episodes()))
        assert set(ep.observations) == {"gps", "imu", "odom", "route"}
        assert set(INFO_KEYS) <= set(ep.infos) and "rewards" in ep.infos
        env = data.recover_environment()
        try:
            assert env.spec is not None and env.spec.id == "AgriNav/FurrowFollow-v1"
            env.reset(seed=0)
        finally:
            env.close()
    assert path.is_dir()


@pytest.mark.slow
def test_a_lane_offset_regressor_beats_the_mean_on_held_out_fields(tmp_path: Path) -> None:
    from baselines.dataset.validate import validate

    spec = load_spec(None, {"width": 64, "height": 48, "frames_per_shard": 48, "frame_every": 4})
    generate(spec, tmp_path / "ds", seed=1, frames=8 * 48, workers=2)
    v = validate(tmp_path / "ds")
    assert v.test_frames >= 48 and v.model_mae < v.mean_mae, str(v)
