import json
import subprocess
import sys
from pathlib import Path

import pytest

from baselines.bench import METRICS
from baselines.cli import main


def test_training_smoke_run_saves_a_loadable_model(tmp_path: Path) -> None:
    out = tmp_path / "ppo"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "baselines.cli",
            "train",
            "--env",
            "AgriNav/FurrowFollow-v0",
            "--timesteps",
            "256",
            "--seed",
            "3",
            "--out",
            str(out),
            "--eval-every",
            "1000000",
            "--eval-episodes",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    for name in (
        "model.zip",
        "vecnormalize.pkl",
        "config.yml",
        "command.txt",
        "evaluations.json",
        "learning_curve.png",
    ):
        assert (out / name).is_file(), name
    assert "agrinav train --env AgriNav/FurrowFollow-v0" in (out / "command.txt").read_text()
    import gymnasium as gym

    import agrinav_gym  # noqa: F401
    from policies import make_policy

    env = gym.make(
        "AgriNav/FurrowFollow-v0",
        scenario_overrides={
            "field": {"width": 6.0, "length": 14.0},
            "layout": {"headland": 2.0},
            "terrain": {"margin": 4.0},
        },
    )
    try:
        pi = make_policy(f"ppo:{out}", env)
        obs, _ = env.reset(seed=0)
        assert env.action_space.contains(pi.act(obs))
    finally:
        env.close()


def test_smoke_bench_writes_results_and_table(tmp_path: Path) -> None:
    out = tmp_path / "bench"
    assert (
        main(
            [
                "bench",
                "--suite",
                "smoke",
                "--policies",
                "dwb,rpp,depth",
                "--seeds",
                "2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    records = json.loads((out / "results.json").read_text())
    assert len(records) == 3 * 2
    fields = {
        "policy",
        "suite",
        "scenario",
        "seed",
        "rmse",
        "mae",
        "max",
        "in_furrow_rmse",
        "headland_rmse",
        "completion",
        "crops_hit",
        "steps",
    }
    for r in records:
        assert fields <= set(r), fields - set(r)
        assert r["suite"] == "smoke" and r["steps"] > 0
    assert {r["policy"] for r in records} == {"dwb", "rpp", "depth"}
    assert len({r["seed"] for r in records}) == 2 and min(r["seed"] for r in records) >= 10**9
    md = (out / "benchmark.md").read_text()
    assert "| tiny | dwb |" in md and " ± " in md
    assert "agrinav bench --suite smoke" in md  # how to reproduce
    for m in METRICS:
        assert m in md
    assert (out / "benchmark.png").is_file() and (out / "traj_tiny_dwb.png").is_file()


def test_run_writes_metrics_plot_and_video(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert (
        main(
            [
                "run",
                "--env",
                "AgriNav/FurrowFollow-v0",
                "--policy",
                "rpp",
                "--episodes",
                "1",
                "--out",
                str(out),
                "--video",
                "--scenario",
                "early-corn",
            ]
        )
        == 0
    )
    records = json.loads((out / "metrics.json").read_text())
    assert len(records) == 1 and records[0]["policy"] == "rpp"
    assert (out / "trajectory_000.png").is_file()
    video = out / "episode_000.webm"
    assert video.read_bytes()[:4] == b"\x1a\x45\xdf\xa3"  # EBML: a Matroska/WebM file
    import cv2

    cap = cv2.VideoCapture(str(video))
    try:
        assert cap.get(cv2.CAP_PROP_FRAME_WIDTH) == 640
        assert int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little") == b"VP80"
        assert cap.read()[0]
    finally:
        cap.release()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["bench", "--suite", "moon", "--policies", "dwb", "--out", "x"], "--suite: got 'moon'"),
        (["bench", "--suite", "smoke", "--policies", "mpc", "--out", "x"], "policy: got 'mpc'"),
        (["train", "--env", "AgriNav/Nope-v0", "--timesteps", "10", "--out", "x"], "--env"),
    ],
)
def test_bad_experiment_arguments_exit_2(
    tmp_path: Path, args: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [a if a != "x" else str(tmp_path / "x") for a in args]
    assert main(args) == 2
    assert needle in capsys.readouterr().err


def test_benchmark_names_where_a_policy_fails() -> None:
    from baselines.bench import failures

    def rec(policy: str, group: str, completion: float, crops: int) -> dict[str, object]:
        return {"policy": policy, "scenario": group, "completion": completion, "crops_hit": crops}

    records = [
        rec("dwb", "0.3 m", 99.0, 0),
        rec("dwb", "2.5 m", 98.0, 0),
        rec("depth", "0.3 m", 99.0, 0),
        rec("depth", "2.5 m", 10.0, 11),
        rec("depth", "2.5 m", 20.0, 9),
    ]
    lines = failures(records, ["0.3 m", "2.5 m"], ["dwb", "depth"])
    assert "- dwb: none" in lines
    assert "- depth: 2.5 m (15 % done, 10.0 crops hit)" in lines


def test_bench_labels_tell_ppo_checkpoints_apart() -> None:
    from baselines.bench import policy_labels
    from scenario_gen import ScenarioError

    assert policy_labels(["dwb", "ppo:shipped"]) == ["dwb", "ppo"]
    assert policy_labels(["ppo:shipped", "ppo:runs/depth_ppo/"]) == ["ppo:shipped", "ppo:depth_ppo"]
    with pytest.raises(ScenarioError, match="--policies"):
        policy_labels(["dwb", "dwb"])
