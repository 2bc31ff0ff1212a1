"""agrinav dataset perception: labels, determinism, resumption, bad input, the loader."""

from __future__ import annotations

import itertools
import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

from agrinav_gym.render.classes import CROP, WEED
from baselines.cli import main
from baselines.dataset import PerceptionDataset, generate, load_spec
from baselines.dataset.perception import check, shard_frames, write_shard
from baselines.dataset.run import shard_name
from scenario_gen.errors import InputError

TINY = {"width": 48, "height": 32, "frames_per_shard": 2, "frame_every": 4}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "ds"
    assert generate(load_spec(None, TINY), out, seed=7, frames=4) == 4
    return out


def test_frames_hold_every_array_and_label(dataset: Path) -> None:
    ds = PerceptionDataset(dataset, parse_labels=True)
    assert len(ds) == 4
    s = ds[0]
    assert s["rgb"].shape == (32, 48, 3) and s["rgb"].dtype == np.uint8
    assert s["depth"].shape == (32, 48) and s["depth"].dtype == np.float32
    assert s["semantic"].shape == (32, 48) and s["instance"].dtype == np.int32
    lab = s["labels"]
    for key in ("pose", "gnss", "imu", "cameras", "lane", "rows", "plants", "scenario"):
        assert key in lab
    assert set(lab["cameras"]) == {"depth", "rgb"}
    plant = np.isin(s["semantic"], (CROP, WEED))  # an obstacle's pixels name an obstacle
    shown = set(np.unique(s["instance"][plant])) - {-1}
    labelled = {p["id"]: p for p in lab["plants"]}
    # every plant the instance image shows is labelled, with its pixel count
    assert shown <= set(labelled)
    for i in shown:
        assert labelled[i]["visible_pixels"] == int(((s["instance"] == i) & plant).sum())
    assert lab["obstacles"] == []  # the default fields have none


def test_lane_offset_agrees_with_the_envs_cross_track_error(dataset: Path) -> None:
    # FurrowFollow's route is the lane centreline: the label (from the row geometry) and the
    # env's own metric (nearest route segment) are independent computations of one distance.
    for s in PerceptionDataset(dataset, parse_labels=True):
        lab = s["labels"]
        assert abs(abs(lab["lane"]["lateral_offset"]) - lab["route_cte"]) < 0.01
        assert s["lateral_offset"] == lab["lane"]["lateral_offset"]


def test_splits_are_disjoint_field_ranges_listed_in_the_manifest_and_card(
    dataset: Path, tmp_path: Path
) -> None:
    """Shards 0, 1, 2 are train, validation, test; each split's fields come from its own
    scenario seed range; the card's front matter lists the shards per split for the Hub."""
    import yaml

    from baselines.dataset.perception import SPLIT_SEEDS

    man = json.loads((dataset / "dataset.json").read_text())
    assert man["splits"]["train"]["shards"] == ["shard-000000.tar"]
    assert man["splits"]["validation"]["shards"] == ["shard-000001.tar"]
    assert man["splits"]["test"]["shards"] == []  # 4 frames, 2 per shard: two shards
    for name in ("train", "validation"):
        part = PerceptionDataset(dataset, split=name, parse_labels=True)
        assert len(part) == 2
        lo, hi = SPLIT_SEEDS[name]
        for s in part:
            assert s["split"] == name and lo <= s["labels"]["scenario"]["seed"] < hi
    ranges = sorted(SPLIT_SEEDS.values())
    assert all(a[1] <= b[0] for a, b in itertools.pairwise(ranges))
    with pytest.raises(InputError, match="split"):
        PerceptionDataset(dataset, split="dev")
    from baselines.dataset.card import write_card

    shutil.copytree(dataset, tmp_path / "ds")
    write_card(tmp_path / "ds")
    text = (tmp_path / "ds" / "README.md").read_text()
    assert text.startswith("---\n")
    meta = yaml.safe_load(text.split("---\n")[1])
    assert meta["license"] == "mit" and meta["size_categories"] == ["n<1K"]
    files = {d["split"]: d["path"] for d in meta["configs"][0]["data_files"]}
    assert files == {"train": ["shard-000000.tar"], "validation": ["shard-000001.tar"]}


def test_pytorchs_default_collation_batches_frames(dataset: Path) -> None:
    torch = pytest.importorskip("torch")
    loader = torch.utils.data.DataLoader(PerceptionDataset(dataset), batch_size=3)
    batch = next(iter(loader))
    assert tuple(batch["depth"].shape) == (3, 32, 48) and batch["rgb"].dtype == torch.uint8
    assert batch["lateral_offset"].shape == (3,) and len(batch["labels"]) == 3
    assert json.loads(batch["labels"][0])["key"] == batch["key"][0]


def test_lane_offset_on_curved_rows_is_measured_from_the_curve() -> None:
    import math

    from baselines.dataset.labels import lane_offset
    from scenario_gen import generate as generate_scenario
    from scenario_gen import preset

    spec = preset(
        "default",
        field={"width": 10.0, "length": 14.0},
        layout={"headland": 2.0, "row_geometry": "curved", "curve_radius": [15.0, 15.0]},
        terrain={"margin": 4.0},
    )
    scn = generate_scenario(spec, 1)
    rows = scn.rows
    mid = 0.5 * (rows.offsets[1] + rows.offsets[2])
    for t in (rows.starts[1] + 1.0, 0.5 * (rows.starts[1] + rows.ends[1]), rows.ends[1] - 1.0):
        (x,), (y,) = rows.to_enu(np.array([t]), np.array([mid + 0.1]))
        (h,) = rows.heading(np.array([t]))
        lab = lane_offset(scn, np.array([x, y]), float(h) + 0.05)
        assert lab["lane"] == 1
        assert lab["lateral_offset"] == pytest.approx(0.1, abs=1e-4)
        assert lab["heading_offset"] == pytest.approx(0.05, abs=1e-4)
        back = lane_offset(scn, np.array([x, y]), float(h) + math.pi)  # driving the other way
        assert back["lateral_offset"] == pytest.approx(-0.1, abs=1e-4)


@pytest.mark.parametrize("overlap", [False, True])
def test_the_same_spec_and_seed_give_byte_identical_shards(
    dataset: Path, tmp_path: Path, overlap: bool
) -> None:
    """Encoding a frame while the next one renders (``overlap``) changes no byte."""
    again = tmp_path / shard_name(1)
    write_shard(shard_frames(load_spec(None, TINY), 7, 1), again, overlap)
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


@pytest.mark.parametrize("stop", [KeyboardInterrupt(), SystemExit(143)])
def test_a_stopped_run_says_how_many_shards_it_kept(
    dataset: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    stop: BaseException,
) -> None:
    """Ctrl-C or SIGTERM (the CLI turns it into SystemExit) while shard 1 is written: the
    whole shard 0 stays, and the run says so and how to resume (it used to say nothing)."""
    from baselines.dataset import run

    out = tmp_path / "copy"
    shutil.copytree(dataset, out)
    for i in (0, 1):
        (out / shard_name(i)).unlink()
    work = run._work

    def stopped_at_shard_1(args: tuple) -> tuple[int, int, float]:
        if args[2] == 1:
            (out / f".{shard_name(1)}.tmp-123").write_bytes(b"partial")
            raise stop
        return work(args)

    monkeypatch.setattr(run, "_work", stopped_at_shard_1)
    with pytest.raises(type(stop)):
        generate(load_spec(None, TINY), out, seed=7, frames=4)
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err == (
        f"dataset: stopped; 1 of 2 shards are complete and kept in {out}: rerun the same "
        "command to resume"
    )
    assert sorted(p.name for p in out.iterdir()) == [
        ".agrinav-output",
        "dataset.json",
        shard_name(0),
    ]


def test_a_killed_card_write_leaves_no_file_and_a_finished_rerun_writes_nothing(
    dataset: Path, tmp_path: Path
) -> None:
    out = tmp_path / "copy"
    shutil.copytree(dataset, out)
    assert (out / ".agrinav-output").is_file()  # an output folder as every command's
    (out / ".mosaic.png.tmp-123").write_bytes(b"partial")  # a kill while the card was written
    (out / shard_name(1)).unlink()
    from baselines.dataset.card import write_card

    spec = load_spec(None, TINY)
    assert generate(spec, out, seed=7, frames=4, card=write_card) == 2
    assert not list(out.glob(".*.tmp*"))
    stamps = {f: (out / f).stat().st_mtime_ns for f in ("README.md", "mosaic.png")}
    assert generate(spec, out, seed=7, frames=4, card=write_card) == 0
    assert stamps == {f: (out / f).stat().st_mtime_ns for f in stamps}


def test_frames_rounded_up_to_whole_shards_are_noted(tmp_path: Path) -> None:
    from scenario_gen.errors import Notice

    with pytest.warns(Notice, match=r"--frames 3 is written as 2 whole shard\(s\).*: 4 frames"):
        assert generate(load_spec(None, TINY), tmp_path / "ds", seed=7, frames=3) == 4


def test_the_loader_says_when_shards_are_missing(dataset: Path, tmp_path: Path) -> None:
    from scenario_gen.errors import Notice

    out = tmp_path / "copy"
    shutil.copytree(dataset, out)
    (out / shard_name(1)).unlink()
    with pytest.warns(Notice, match=r"1 of the 2 shards dataset\.json lists are here"):
        assert len(PerceptionDataset(out)) == 2


def test_a_symbolic_link_as_out_is_refused(dataset: Path, tmp_path: Path) -> None:
    link = tmp_path / "link"
    link.symlink_to(dataset)
    with pytest.raises(InputError, match="is a symbolic link"):
        generate(load_spec(None, TINY), link, seed=7, frames=4)


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
        (["--ray", "not an address"], "--ray: got 'not an address'"),
        (["--ray", "local", "--workers", "2"], "--workers: got 2"),
        (["--frames", str(10**20)], "--frames: got 100000000000000000000"),
        # a field too short for its headlands: the rule's field and the spec's
        (["--set", "field_length=8"], "8 m long (spec.field_length)"),
        # no scenario key: one field in every split, which the card calls disjoint
        (["--set", "randomize={lighting.sun_azimuth_deg: [0, 90]}"], "holds no scenario key"),
        # the env's draw would override spec.field_length, which the card states
        (["--set", "randomize={field.length: [30, 40]}"], "set by spec.field_length"),
    ],
)
def test_bad_specs_exit_2_and_write_nothing(
    tmp_path: Path, args: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new" / "parent" / "out"  # nor the parent folders it would have made
    assert main(["dataset", "perception", "--out", str(out), "--frames", "2", *args]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "new").exists()


def test_a_run_that_fails_in_an_empty_folder_leaves_it_empty(tmp_path: Path) -> None:
    """A depth policy trained on 64 × 48 frames refuses these 48 × 32 ones, in the up-front
    check (the policy is built against the spec's first field before the manifest is
    written): the user's empty folder stays empty, not blocked as "another dataset"."""
    from policies import shipped_model

    out = tmp_path / "mine"
    out.mkdir()
    spec = load_spec(
        None, {**TINY, "policy": f"ppo:{shipped_model('AgriNav/FurrowFollowDepth-v3')}"}
    )
    with pytest.raises(InputError):
        check(spec)
    with pytest.raises(InputError):
        generate(spec, out, seed=7, frames=2)
    assert out.is_dir() and list(out.iterdir()) == []
    assert generate(load_spec(None, TINY), out, seed=7, frames=2) == 2  # the corrected command


def test_trajectories_are_a_minari_dataset_that_recovers_its_env(tmp_path: Path) -> None:
    pytest.importorskip("jax", reason="Minari's recorder needs the dataset extra (jax)")
    minari = pytest.importorskip("minari", reason="the dataset extra is not installed")
    from baselines.dataset.trajectories import INFO_KEYS, _datasets_root, load, record

    path = record("AgriNav/FurrowFollow-v3", "rpp", 2, tmp_path / "m", seed=3)
    meta = load(tmp_path / "m").storage.metadata
    assert meta["requirements"][0].startswith("agrinav-gym==")
    assert meta["ref_min_score"] < meta["ref_max_score"]  # random actions score below RPP
    with _datasets_root(tmp_path / "m"):
        data = minari.load_dataset("agrinav/furrow_follow-v0")
        assert data.total_episodes == 2
        ep = next(iter(data.iterate_episodes()))
        assert set(ep.observations) == {"gps", "imu", "odom", "route"}
        assert set(INFO_KEYS) <= set(ep.infos) and "rewards" in ep.infos
        env = data.recover_environment()
        try:
            assert env.spec is not None and env.spec.id == "AgriNav/FurrowFollow-v3"
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


def _tmpfs_shell() -> list[str] | None:
    """A shell in its own mount namespace that may mount a tmpfs (root, or unprivileged user
    namespaces); None where the machine allows neither."""
    import shutil
    import subprocess

    if shutil.which("unshare") is None:
        return None
    for cmd in (["unshare", "-m", "sh", "-c"], ["unshare", "-rm", "sh", "-c"]):
        ok = subprocess.run([*cmd, "mount -t tmpfs -o size=4k none /mnt"], capture_output=True)
        if ok.returncode == 0:
            return cmd
    return None


@pytest.mark.parametrize(
    ("size_kb", "kept"),
    [(24, 0), (260, 1)],
    ids=["first-shard", "after-one-shard"],
)
def test_a_full_disk_is_one_error_and_leaves_no_partial_file(
    tmp_path: Path, size_kb: int, kept: int
) -> None:
    import os
    import subprocess
    import sys

    shell = _tmpfs_shell()
    if shell is None:
        if os.environ.get("CI"):
            pytest.fail("CI must be able to mount a small tmpfs (unshare -m / -rm)")
        pytest.skip("cannot mount a tmpfs here (no root, no user namespaces)")
    disk = tmp_path / "disk"
    disk.mkdir()
    # 48x32 frames: a 2-frame shard is 150-190 KB (labels, mostly); the manifest ≈ 1.4 KB
    sets = " ".join(f"--set {k}={v}" for k, v in TINY.items())
    script = (
        f"mount -t tmpfs -o size={size_kb}k none {disk} && "
        f"{sys.executable} -m baselines.cli dataset perception --out {disk}/ds --frames 40 "
        f"{sets} 2>{tmp_path}/err; echo rc=$?; cd {disk} && find . -mindepth 1 | sort"
    )
    r = subprocess.run([*shell, script], capture_output=True, text=True, timeout=300)
    lines = r.stdout.split()
    assert "rc=1" in lines, r.stdout + (tmp_path / "err").read_text()
    left = [x for x in lines if x.startswith("./")]
    err = (tmp_path / "err").read_text()
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("agrinav dataset: error: ") and "No space left" in last, last
    # whole shards only: no hidden temporary shard or card file
    assert not [x for x in left if Path(x).name.startswith(".") and x != "./ds/.agrinav-output"]
    shards = [x for x in left if x.endswith(".tar")]
    assert len(shards) == kept, left
    if kept:
        assert f"{kept} of 20 shards are complete" in last and "./ds/dataset.json" in left
    else:
        assert left == [] and "nothing was kept" in last


def test_ray_tasks_write_the_same_shards_as_local_workers(dataset: Path, tmp_path: Path) -> None:
    ray = pytest.importorskip("ray", reason="the ray extra is not installed")
    out = tmp_path / "ray"
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level=logging.ERROR)
    try:  # generate uses the cluster this process is connected to
        assert generate(load_spec(None, TINY), out, seed=7, frames=4, ray="auto") == 4
        for i in range(2):
            assert (out / shard_name(i)).read_bytes() == (dataset / shard_name(i)).read_bytes()
        # resumable and a no-op when finished, as for local runs
        (out / shard_name(1)).unlink()
        assert generate(load_spec(None, TINY), out, seed=7, frames=4, ray="auto") == 2
        assert generate(load_spec(None, TINY), out, seed=7, frames=4, ray="auto") == 0
    finally:
        ray.shutdown()


def test_driving_check_scores_a_policy_by_the_labels_of_its_frames(tmp_path: Path) -> None:
    from baselines.dataset.validate import driving_check

    r = driving_check("rpp", tmp_path / "d", frames=8, overrides={"frames_per_shard": 4})
    lab = [s["labels"]["lane"] for s in PerceptionDataset(tmp_path / "d", parse_labels=True)]
    off = np.abs([x["lateral_offset"] for x in lab])
    assert r.frames == r.labelled == 8 and r.mae == pytest.approx(off.mean())
    assert r.p95 <= off.max() + 1e-12 and r.rmse >= r.mae
    # RPP on an RTK fix keeps to the lane: 0.62 m across the wheels clears rows 0.9 m apart
    # (the narrowest the spec draws) only within ±0.14 m of the centre
    assert r.mae < 0.14


def test_a_second_dataset_run_on_the_same_out_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from scenario_gen.atomic import lock_output

    out = tmp_path / "ds"
    with lock_output(out.absolute(), "--out"):  # what a running `agrinav dataset` holds
        assert main(["dataset", "perception", "--out", str(out), "--frames", "1"]) == 2
    assert "being written by another run" in capsys.readouterr().err
    assert not out.exists()


def test_a_killed_trajectory_recording_leaves_nothing_outside_its_output(tmp_path: Path) -> None:
    """Minari's buffer lives in the output's temporary folder (a kill -9 left it in
    ~/.minari/datasets for ever); the next run on the same --out removes it."""
    import os
    import signal
    import subprocess
    import sys
    import time

    pytest.importorskip("minari")
    root = Path(__file__).resolve().parents[2]
    minari_home = tmp_path / "minari"
    minari_home.mkdir()
    env = {**os.environ, "PYTHONPATH": str(root / "src"), "MINARI_DATASETS_PATH": str(minari_home)}
    out = tmp_path / "work" / "traj"
    out.parent.mkdir()
    argv = [sys.executable, "-m", "baselines.cli", "dataset", "trajectories", "--policy", "rpp"]
    proc = subprocess.Popen([*argv, "--episodes", "50", "--out", str(out)], env=env)
    deadline = time.monotonic() + 60
    while not list(out.parent.glob(".traj.tmp-*/tmp*")) and time.monotonic() < deadline:
        time.sleep(0.2)  # until the collector's buffer exists
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert list(out.parent.glob(".traj.tmp-*/tmp*")), "the buffer was not inside the output"
    assert list(minari_home.iterdir()) == []
    done = subprocess.run(
        [*argv, "--episodes", "1", "--out", str(out)], env=env, capture_output=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-500:]
    assert sorted(p.name for p in out.parent.iterdir()) == ["traj"]


def test_a_stopped_trajectory_recording_says_nothing_was_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C mid-recording: a Minari dataset is written whole, so the user is told that none
    of it stayed (and how far it got), not left to look."""
    pytest.importorskip("minari")
    import policies

    real = policies.make_policy

    def stops_on_step_50(spec: str, env: object) -> object:
        pi = real(spec, env)
        act, steps = pi.act, [0]

        def counted(obs: object) -> object:
            steps[0] += 1
            if steps[0] == 50:
                raise KeyboardInterrupt
            return act(obs)

        pi.act = counted  # type: ignore[method-assign]
        return pi

    monkeypatch.setattr(policies, "make_policy", stops_on_step_50)
    out = tmp_path / "traj"
    argv = ["dataset", "trajectories", "--policy", "rpp", "--episodes", "3", "--out", str(out)]
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "dataset: stopped after 0 of 3 episodes; nothing was kept" in err, err[-2000:]
    assert "Traceback" not in err and not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_a_trajectory_recording_says_each_note_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The command makes three envs (recording, random reference, Minari's spec check): the
    one-field note came three times, with two Minari warnings about links it has no use for."""
    import warnings

    pytest.importorskip("minari")
    argv = ["dataset", "trajectories", "--policy", "blind", "--episodes", "1"]
    with warnings.catch_warnings():
        warnings.simplefilter("default")  # as outside the tests
        assert main([*argv, "--out", str(tmp_path / "t")]) == 0
    err = capsys.readouterr().err
    assert err.count("every reset drives one field") == 1, err[-3000:]
    assert "code_permalink" not in err and "author_email" not in err


def test_a_plants_top_keypoint_lies_on_its_axis_and_labels_reach_as_far_as_a_camera_sees() -> None:
    """On a 10° slope the plants stand on the ground's normal (plants.csv roll and pitch, as
    the cameras draw them): the top keypoint is base + R·(0, 0, height), not straight above
    the base (21 cm apart for 1.2 m maize). By default the labels reach the cameras' corner
    rays at their range, past the 8 m that left plants the image shows unlabelled."""
    import math

    from agrinav_gym.config import EnvConfig
    from agrinav_gym.render.plant_meshes import rotation_rpy
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from agrinav_gym.sensors.d455 import color_model
    from baselines.dataset.labels import camera_reach, plants, to_camera
    from scenario_gen import generate as generate_scenario

    from ..scenario_gen.helpers import plane

    scn = generate_scenario(plane(10.0, crop={"stage": 3}), 0)
    depth = robot_interface(EnvConfig(), RobotGeometry.from_urdf()).camera
    cams = {"depth": depth, "rgb": color_model(depth)}
    p = scn.plants
    i = int(np.argmin(np.hypot(p.x, p.y)))
    pos = np.array([p.x[i] - 2.0, p.y[i], p.z[i]])  # 2 m short of the plant, looking at it
    (r,) = [r for r in plants(scn, pos, np.eye(3), cams, None, 8.0) if r["id"] == i]
    axis = rotation_rpy(p.roll[i], p.pitch[i], p.yaw[i])[:, 2]
    assert math.degrees(math.acos(axis[2])) == pytest.approx(10.0, abs=0.5)  # the slope's tilt
    base = np.array([p.x[i], p.y[i], p.z[i]])
    want = to_camera((base + p.height[i] * axis)[None, :], pos, np.eye(3), depth)[0]
    assert np.allclose(r["top_3d"], want, atol=1e-3)
    upright = to_camera((base + np.array([0.0, 0.0, p.height[i]]))[None, :], pos, np.eye(3), depth)[
        0
    ]
    assert np.linalg.norm(want - upright) > 0.15  # what the label was: 0.2 m off
    reach = camera_reach(cams)
    hx, hy = 0.5 * depth.width / depth.fx, 0.5 * depth.height / depth.fy
    assert reach >= depth.max_range * math.sqrt(1 + hx * hx + hy * hy) > 8.5
