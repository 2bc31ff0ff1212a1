import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from baselines.cli import main
from baselines.episodes import VIDEO_BITRATE
from baselines.report import METRICS


def _train(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "baselines.cli", "train", *args],
        capture_output=True,
        text=True,
        timeout=600,
    )


def _refused(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """A train command that must be refused before it trains, run in this process (a process
    start with torch costs ≈ 5 s): its status 2 checked, its stderr returned."""
    import torch

    threads = torch.get_num_threads()  # the command sets the process's; the suite's is kept
    try:
        capsys.readouterr()
        code = main(["train", *args])
    finally:
        torch.set_num_threads(threads)
    err = capsys.readouterr().err
    assert code == 2, err[-2000:]
    return err


@pytest.fixture(scope="module")
def tiny_scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    import scenario_gen as sg

    out = tmp_path_factory.mktemp("scn") / "tiny"
    spec = sg.preset(
        "default",
        field={"width": 6.0, "length": 12.0},
        layout={"headland": 1.5},
        terrain={"margin": 4.0},
    )
    sg.save(sg.generate(spec, 0), out, preview=False)
    return out


def test_training_saves_safe_checkpoints_logs_and_resumes(
    tmp_path: Path, tiny_scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "ppo"
    common = ["--env", "AgriNav/FurrowFollow-v3", "--seed", "3", "--scenario", str(tiny_scenario)]
    common += ["--n-envs", "1", "--eval-episodes", "1", "--eval-every", "128"]
    proc = _train(
        [
            *common,
            *("--timesteps", "256", "--out", str(out), "--checkpoint-every", "128"),
            *("--hyperparams", "n_steps=64", "batch_size=32", "learning_rate=lin_0.0003"),
        ]
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    for name in ("checkpoint.json", "policy.npz", "optimizer.npz", "config.yml", "command.txt"):
        assert (out / name).is_file(), name
    assert (out / "learning_curve.png").is_file() and (out / "logs" / "progress.csv").is_file()
    assert list((out / "logs").glob("events.out.tfevents.*")), "TensorBoard event file"
    evals = json.loads((out / "evaluations.json").read_text())
    # between rollouts, as the checkpoints: the final step is evaluated once
    assert [e["timesteps"] for e in evals] == [128, 256]
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == [
        "step_0000000128",
        "step_0000000256",
    ]
    # a checkpoint holds the weights of every step it counts: the last one is the final model
    import numpy as np

    with (
        np.load(out / "policy.npz") as final,
        np.load(out / "checkpoints" / "step_0000000256" / "policy.npz") as last,
    ):
        assert sorted(final.files) == sorted(last.files)
        assert all(np.array_equal(final[k], last[k]) for k in final.files)
    config = yaml.safe_load((out / "config.yml").read_text())
    assert config["hyperparams"]["n_steps"] == 64 and config["hyperparams"]["n_envs"] == 1
    assert config["env_kwargs"]["scenario"] == str(tiny_scenario.resolve())
    # the curve and checkpoint choice were made on validation fields, not the test range
    assert config["val_seeds"] == [500_000_000, 501_000_000] != config["eval_seeds"]
    # ... but a saved scenario has no held-out split: the record says validation drove it
    assert config["validation_fields"].startswith("the training fields")
    assert "has no held-out split" in proc.stderr
    assert "agrinav train --env AgriNav/FurrowFollow-v3" in (out / "command.txt").read_text()
    csv = (out / "logs" / "progress.csv").read_text().splitlines()[0]
    assert "eval/rmse" in csv and "train/value_loss" in csv
    assert "eval/mean_reward" in csv and "eval/mean_ep_length" in csv  # SB3 EvalCallback's tags
    # every evaluation reaches TensorBoard, the final one included; the device is recorded
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(out / "logs"))
    events.Reload()
    assert [e.step for e in events.Scalars("eval/mean_reward")] == [128, 256]
    assert config["device"] == "cpu" == json.loads((out / "checkpoint.json").read_text())["device"]
    assert not list(tmp_path.glob(".*tmp*")) and not list(out.glob(".*tmp*"))

    # resume from the first checkpoint: it continues at step 128, to 384 in all
    again = tmp_path / "resumed"
    proc = _train(
        [
            *common,
            *("--timesteps", "384", "--out", str(again), "--hyperparams", "n_steps=64"),
            *("batch_size=32", "--resume", str(out / "checkpoints" / "step_0000000128")),
        ]
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    meta = json.loads((again / "checkpoint.json").read_text())
    assert meta["num_timesteps"] == 384
    evals = json.loads((again / "evaluations.json").read_text())
    assert evals[0]["timesteps"] == 256  # the first evaluation after resuming at 128

    import gymnasium as gym

    import agrinav_gym  # noqa: F401
    from policies import make_policy

    env = gym.make("AgriNav/FurrowFollow-v3", scenario=str(tiny_scenario))
    try:
        pi = make_policy(f"ppo:{again}", env)
        obs, _ = env.reset(seed=0)
        assert env.action_space.contains(pi.act(obs))
    finally:
        env.close()

    # resuming goes on with the checkpoint's hyperparameters (n_steps 64, not ppo.yml's), and
    # refuses a change of what its weights were trained with
    quiet = tmp_path / "quiet"
    step128 = str(out / "checkpoints" / "step_0000000128")
    proc = _train([*common, "--timesteps", "192", "--out", str(quiet), "--resume", step128])
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert yaml.safe_load((quiet / "config.yml").read_text())["hyperparams"]["n_steps"] == 64
    assert json.loads((quiet / "checkpoint.json").read_text())["num_timesteps"] == 192
    for change, key in (("normalize=false", "normalize"), ("policy_kwargs={net_arch: [8]}", "")):
        bad = tmp_path / "changed"
        args = ["--timesteps", "384", "--out", str(bad), "--resume", step128]
        err = _refused([*common, *args, "--hyperparams", change], capsys)
        assert "the checkpoint was trained with" in err
        assert f"hyperparams.{key or 'policy_kwargs'}" in err and not bad.exists()

    # a truncated optimizer state is refused before the new run's folder exists
    import shutil

    broken = tmp_path / "broken"
    shutil.copytree(out / "checkpoints" / "step_0000000128", broken)
    (broken / "optimizer.npz").write_bytes((broken / "optimizer.npz").read_bytes()[:200])
    bad = tmp_path / "never"
    err = _refused(
        [*common, "--timesteps", "384", "--out", str(bad), "--resume", str(broken)], capsys
    )
    assert "--resume" in err and not bad.exists()

    # a resume into an env of other observations was a torch size-mismatch traceback
    obs3 = tmp_path / "obs3.yaml"
    obs3.write_text("observations: [gps, imu, odom]\n")
    args = ["--timesteps", "384", "--out", str(bad), "--resume", step128, "--env-kwargs", str(obs3)]
    err = _refused([*common, *args], capsys)
    assert "--resume" in err and "observation space is not the env's" in err and not bad.exists()


def test_a_run_starts_from_another_checkpoint_and_refuses_one_that_does_not_fit(
    tmp_path: Path, tiny_scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from policies import checkpoint, shipped_model

    start = shipped_model("AgriNav/FurrowFollow-v3")
    common = ["--env", "AgriNav/FurrowFollow-v3", "--seed", "1", "--scenario", str(tiny_scenario)]
    common += ["--n-envs", "1", "--eval-episodes", "1", "--eval-every", "64"]
    hp = ["--hyperparams", "n_steps=64", "batch_size=32"]
    out = tmp_path / "tuned"
    proc = _train([*common, "--timesteps", "64", "--out", str(out), *hp, "--init-from", str(start)])
    assert proc.returncode == 0, proc.stderr[-2000:]
    evals = json.loads((out / "evaluations.json").read_text())
    assert evals[0]["timesteps"] == 0  # the starting checkpoint, measured before any update
    assert json.loads((out / "checkpoint.json").read_text())["num_timesteps"] == 64
    config = yaml.safe_load((out / "config.yml").read_text())
    assert config["initialised_from"] == str(start) and config["warm_start"] is None
    before, after = checkpoint.load(start), checkpoint.load(out)
    assert before.meta["normalization"] is not None
    w0 = before.policy.state_dict()
    w1 = after.policy.state_dict()
    # 64 steps of fine-tuning moved the weights from the checkpoint's, not from a fresh draw
    k = next(k for k in w0 if k.endswith("weight"))
    delta = (w1[k] - w0[k]).abs().max().item()
    assert 0 < delta < 0.05 * w0[k].abs().max().item()

    # a checkpoint of an env that observes something else, or both ways in at once: refused
    other = shipped_model("AgriNav/FieldRoute-v3")
    # ... or one trained on normalised observations for a run that does not normalise them
    unnormalised = ["--init-from", str(start), "--hyperparams", "normalize=false"]
    for extra in (
        ["--init-from", str(other)],
        ["--init-from", str(start), "--resume", str(out)],
        unnormalised,
    ):
        bad = tmp_path / "never"
        err = _refused([*common, "--timesteps", "64", "--out", str(bad), *extra], capsys)
        assert "--init-from" in err and not bad.exists()


def test_ctrl_c_with_worker_processes_is_one_line_and_keeps_the_checkpoints(
    tmp_path: Path, tiny_scenario: Path
) -> None:
    """A terminal's Ctrl-C signals the whole process group, the SubprocVecEnv workers too:
    one line, status 130, the finished checkpoints kept with the command that made them."""
    import os
    import signal
    import time

    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "baselines.cli", "train", "--env", "AgriNav/FurrowFollow-v3"]
    cmd += ["--scenario", str(tiny_scenario), "--n-envs", "2", "--eval-episodes", "1"]
    cmd += ["--timesteps", "100000", "--checkpoint-every", "64", "--out", str(out)]
    cmd += ["--hyperparams", "n_steps=32", "batch_size=32", "n_epochs=1"]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # a job started in the background inherits SIGINT ignored; a terminal's is not
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("checkpoints/step_*")) and time.monotonic() < deadline:
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err and "agrinav: interrupted" in err, err[-2000:]
    assert list(out.glob("checkpoints/step_*")) and (out / "command.txt").is_file()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--hyperparams", "n_stepz=3"], "hyperparams.n_stepz"),
        (["--seed", str(2**32)], "--seed"),  # numpy's legacy seeding, which SB3 uses
        (["--hyperparams", "batch_size=99999"], "hyperparams.batch_size"),
        (["--hyperparams", "learning_rate=fast"], "hyperparams.learning_rate"),
        (["--hyperparams", "learning_rate=lin_-1"], "hyperparams.learning_rate"),
        (["--hyperparams", "clip_range=lin_-0.2"], "hyperparams.clip_range"),
        (["--hyperparams", "batch_size=1"], "hyperparams.batch_size"),
        (["--hyperparams", "max_grad_norm=0"], "hyperparams.max_grad_norm"),
        (["--n-envs", "2", "--hyperparams", "n_envs=3"], "--n-envs"),
        (["--timesteps", "5000", "--hyperparams", "n_timesteps=6000"], "--timesteps"),
        (["--hyperparams", "policy_kwargs={net_arch: [64], bogus: 1}"], "policy_kwargs"),
        (
            ["--hyperparams", "policy_kwargs={activation_fn: Foo}"],
            "hyperparams.policy_kwargs.activation_fn: got 'Foo'",
        ),
        (["--hyperparams", "n_steps"], "key=value, e.g. learning_rate="),
        (["--hyperparams", "policy_kwargs={net_arch: [0]}"], "net_arch"),
        (["--hyperparams", "policy_kwargs={log_std_init: high}"], "log_std_init"),
        # SB3 reads only pi and vf: {foo: [64]} trained a policy of no hidden layers
        (["--hyperparams", "policy_kwargs={net_arch: {foo: [64]}}"], "mapping of pi, vf"),
        # gSDE's noise matrix has no place in the checkpoint: the run would not load
        (["--hyperparams", "use_sde=true"], "hyperparams.use_sde"),
        (["--hyperparams", "normalize={norm_obs: true, bogus: 3}"], "hyperparams.normalize"),
        (["--hyperparams", "normalize={norm_reward: true}"], "normalize.norm_reward"),
        (["--device", "tpu"], "--device"),
        (["--scenario", "/no/such/place"], "--scenario"),
        (["--resume", "/no/such/checkpoint"], "checkpoint"),
    ],
)
def test_bad_training_arguments_exit_2_before_writing(
    tmp_path: Path, args: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    code = main(["train", "--env", "AgriNav/FurrowFollow-v3", "--out", str(out), *args])
    err = capsys.readouterr().err
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


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
        "obstacles_hit",
        "obstacles_hit_by_kind",
        "steps",
    }
    for r in records:
        assert fields <= set(r), fields - set(r)
        assert r["suite"] == "smoke" and r["steps"] > 0
    assert {r["policy"] for r in records} == {"dwb:furrow", "rpp", "depth"}
    assert len({r["seed"] for r in records}) == 2 and min(r["seed"] for r in records) >= 10**9
    md = (out / "benchmark.md").read_text()
    assert "| tiny | dwb:furrow |" in md and "95 % bootstrap interval" in md
    assert "agrinav bench --suite smoke" in md  # how to reproduce
    for m in METRICS:
        assert m in md
    assert (out / "benchmark.png").is_file()
    for policy in ("dwb-furrow", "rpp", "depth"):  # every episode drawn, the second seed too
        assert sorted(p.name for p in out.glob(f"traj_tiny_{policy}_*.png")) == [
            f"traj_tiny_{policy}_000.png",
            f"traj_tiny_{policy}_001.png",
        ]


def test_run_writes_metrics_plot_and_video(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert (
        main(
            [
                "run",
                "--env",
                "AgriNav/FurrowFollow-v3",
                "--policy",
                "rpp",
                "--episodes",
                "1",
                "--out",
                str(out),
                "--video",
                "--scenario",
                "early-corn",
                "--max-steps",
                "40",
            ]
        )
        == 0
    )
    records = json.loads((out / "metrics.json").read_text())
    assert len(records) == 1 and records[0]["policy"] == "rpp"
    assert records[0]["steps"] == 40 and records[0]["termination"] == "time_limit"
    # the frames' time is reported apart from the episode's own
    assert records[0]["frames"] == 41 and records[0]["render_seconds"] > 0
    assert (out / "trajectory_000.png").is_file()
    video = out / "episode_000.webm"
    assert video.read_bytes()[:4] == b"\x1a\x45\xdf\xa3"  # EBML: a Matroska/WebM file
    # VP8 at VIDEO_BITRATE: about 2 s of video, 0.3 MB (OpenCV's writer made 3 MB of it)
    assert video.stat().st_size < 1.5 * VIDEO_BITRATE / 8 * 41 / 20
    import cv2

    cap = cv2.VideoCapture(str(video))
    try:
        assert cap.get(cv2.CAP_PROP_FRAME_WIDTH) == 640
        assert cap.get(cv2.CAP_PROP_FRAME_HEIGHT) == 480
        assert int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little") == b"VP80"
        frames = 0
        while cap.read()[0]:
            frames += 1
        assert frames == 41  # the reset's state and each step's
    finally:
        cap.release()
    printed = capsys.readouterr()
    assert "41/41" in printed.err and "frame" in printed.err  # the video's progress
    # a table, not the records: the policy's row, then the folder written
    lines = printed.out.splitlines()
    assert lines[0].split()[:3] == ["policy", "episodes", "finished"] and "{" not in printed.out
    assert lines[1].split()[:3] == ["rpp", "1", "0/1"]  # truncated at 40 steps: not finished
    assert lines[-1].startswith(f"wrote {out.resolve()}")


def test_run_records_what_bench_records_on_drifted_rows(tmp_path: Path) -> None:
    """``run``'s metrics.json left out the planted-lane error (and the driven path) that a
    bench record of the same episode holds."""
    from scenario_gen import generate, preset, save

    spec = preset(
        "default",
        field={"width": 6.0, "length": 8.0},
        layout={"headland": 1.5, "drift_amplitude": 0.1},
        terrain={"margin": 3.0},
        route={"lead_in": 1.0},
    )
    save(generate(spec, 1), tmp_path / "drift", preview=False)
    out = tmp_path / "run"
    argv = ["run", "--policy", "rpp", "--scenario", str(tmp_path / "drift"), "--max-steps", "60"]
    assert main([*argv, "--out", str(out)]) == 0
    (record,) = json.loads((out / "metrics.json").read_text())
    assert record["planted_rmse"] is not None and record["planted_rmse"] >= 0.0
    assert 0.0 < record["driven_m"] < 60 * 0.05 * 2.0  # 60 steps of 0.05 s below 2 m/s
    assert record["geometry"]["scenario_seed"] == 1


def test_episode_seconds_leave_the_video_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """``seconds`` is the episode's own time: what its frames take is ``render_seconds``."""
    import baselines.episodes as episodes
    from policies import make_policy

    from ..agrinav_gym.helpers import make

    clock = [0.0]
    monkeypatch.setattr(episodes.time, "perf_counter", lambda: clock[0])

    class SlowVideo(episodes.VideoWriter):
        def __call__(self, env: object) -> float:
            clock[0] += 10.0  # ten seconds a frame
            self.frames += 1
            return 10.0

    env = make(max_episode_steps=5)
    try:
        pi = make_policy("blind", env)
        ep = episodes.run_episode(env, pi, 0, "blind", SlowVideo(Path("unused.webm")))
    finally:
        env.close()
    assert ep.frames == 6 and ep.render_seconds == 60.0
    assert ep.seconds == 0.0  # the clock moved only in the frames


@pytest.mark.parametrize(
    "args,needle",
    [
        (["bench", "--suite", "moon", "--policies", "dwb", "--out", "x"], "--suite: got 'moon'"),
        (["bench", "--suite", "smoke", "--policies", "mpc", "--out", "x"], "policy: got 'mpc'"),
        (["bench", "--suite", "smoke", "--policies", "rpp,,", "--out", "x"], "no empty entry"),
        (
            ["bench", "--suite", "smoke", "--policies", "rpp", "--cases", "a;", "--out", "x"],
            "no empty entry",
        ),
        # a doubled entry or key is a slip: refused, not silently merged or the last one kept
        (
            ["bench", "--suite", "smoke", "--policies", "rpp", "--cases", "a;a", "--out", "x"],
            "'a' given twice",
        ),
        (["bench", "--suite", "smoke", "--policies", "rpp,rpp", "--out", "x"], "given twice"),
        (
            [
                *("bench", "--suite", "smoke", "--policies", "rpp", "--out", "x"),
                *("--config", "soil.friction=0.4", "--config", "soil.friction=0.8"),
            ],
            "--config soil.friction",
        ),
        (["train", "--env", "AgriNav/Nope-v0", "--timesteps", "10", "--out", "x"], "--env"),
        # Optuna's sampler takes 32-bit seeds: a larger one was a traceback, exit 1
        (
            ["tune", "--policy", "rpp", "--trials", "1", "--seed", str(2**32), "--out", "x"],
            f"--seed: got {2**32}",
        ),
        (
            ["run", "--policy", "rpp", "--out", "x", "--trust-checkpoint"],
            "--trust-checkpoint: got 'rpp'; is given, but no policy",
        ),
        (
            [
                "bench",
                "--suite",
                "smoke",
                "--policies",
                "rpp,dwb",
                "--out",
                "x",
                "--trust-checkpoint",
            ],
            "no policy in --policies reads a checkpoint",
        ),
        # PPO collects whole rollouts: 100 steps would have trained 512 × 4
        (
            ["train", "--env", "AgriNav/FurrowFollow-v3", "--timesteps", "100", "--out", "x"],
            "less than one rollout (n_steps 512 × n_envs 4 = 2048 steps",
        ),
    ],
)
def test_bad_experiment_arguments_exit_2(
    tmp_path: Path, args: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [a if a != "x" else str(tmp_path / "x") for a in args]
    assert main(args) == 2
    assert needle in capsys.readouterr().err


def test_benchmark_names_where_a_policy_fails() -> None:
    from baselines.report import failures

    def rec(policy: str, group: str, completion: float, crops: int) -> dict[str, object]:
        end = "success" if completion > 95 else "corridor"
        return {
            "policy": policy,
            "scenario": group,
            "completion": completion,
            "crops_hit": crops,
            "termination": end,
        }

    records = [
        rec("dwb", "0.3 m", 99.0, 0),
        rec("dwb", "2.5 m", 98.0, 0),
        rec("depth", "0.3 m", 99.0, 0),
        rec("depth", "2.5 m", 10.0, 11),
        rec("depth", "2.5 m", 20.0, 9),
    ]
    lines = failures(records, ["0.3 m", "2.5 m"], ["dwb", "depth"])
    assert "- dwb: none" in lines
    assert "- depth: 2.5 m (0/2 finished, 15 % done, 10.0 crops hit)" in lines


def test_bench_labels_tell_ppo_checkpoints_apart() -> None:
    from baselines.bench import policy_labels
    from scenario_gen import ScenarioError

    assert policy_labels(["dwb", "ppo:shipped"]) == ["dwb:furrow", "ppo"]
    assert policy_labels(["dwb:nav2", "dwb:furrow", "dwb:runs/my.yaml"]) == [
        "dwb:nav2",
        "dwb:furrow",
        "dwb:my.yaml",
    ]
    # a user's file named as a shipped config is not that config
    assert policy_labels(["dwb:mine/tuned.yaml", "dwb:tuned"]) == ["dwb:tuned.yaml", "dwb:tuned"]
    assert policy_labels(["dwb:a/best.yaml", "dwb:b/best.yaml"]) == [
        "dwb:a/best.yaml",
        "dwb:b/best.yaml",
    ]
    assert policy_labels(["ppo:shipped", "ppo:runs/depth_ppo/"]) == ["ppo:shipped", "ppo:depth_ppo"]
    # the shipped tuned parameters say so, even alone: a default and a tuned row never share
    # a label
    assert policy_labels(["stanley:tuned", "dwb:tuned"]) == ["stanley:tuned", "dwb:tuned"]
    assert policy_labels(["rpp", "rpp:tuned"]) == ["rpp", "rpp:tuned"]
    with pytest.raises(ScenarioError, match="--policies"):
        policy_labels(["dwb", "dwb:furrow"])
    # two searches' results (each tune writes best.yaml): told apart by their folders
    assert policy_labels(["rpp:t1/best.yaml", "rpp:t2/best.yaml"]) == [
        "rpp:t1/best.yaml",
        "rpp:t2/best.yaml",
    ]
    with pytest.raises(ScenarioError, match="--policies"):
        policy_labels(["rpp:t1/best.yaml", "rpp:t1/best.yaml"])
    # a user's parameters or checkpoint alone is not the defaults or the shipped model
    assert policy_labels(["rpp:runs/mine.yaml", "dwb"]) == ["rpp:mine.yaml", "dwb:furrow"]
    assert policy_labels(["ppo:runs/depth_ppo"]) == ["ppo:depth_ppo"]
    assert policy_labels(["ppo:shipped"]) == ["ppo"]


@pytest.mark.parametrize(
    "args,field",
    [
        (["run", "--policy", "foo"], "policy: got 'foo'"),
        (["run", "--policy", "ppo:/no/such/model"], "ppo:/no/such/model"),
        (["run", "--policy", "rpp", "--env", "AgriNav/Nope-v0"], "--env"),
        (["run", "--policy", "rpp", "--scenario", "/no/such/dir"], "scenario"),
        (["run", "--policy", "rpp", "--seed", "-1"], "--seed"),
        (["bench", "--suite", "smoke", "--policies", ""], "--policies"),
        (["bench", "--suite", "smoke", "--policies", "dwb,dwb"], "--policies"),
        (["train", "--env", "AgriNav/FieldRoute-v3", "--eval-every", "0"], "--eval-every"),
    ],
)
def test_cli_refuses_before_creating_the_output(
    tmp_path: Path, args: list[str], field: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    code = main([*args, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert field in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "args",
    [
        ["train", "--env", "AgriNav/FurrowFollow-v3", "--timesteps", "64"],
        ["dataset", "perception", "--frames", "1"],
    ],
)
def test_an_out_under_a_file_is_one_line(
    tmp_path: Path, args: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """Not errno 17 from inside a mkdir, exit 1: the parent is named, exit 2."""
    (tmp_path / "afile").write_text("x")
    code = main([*args, "--out", str(tmp_path / "afile" / "x")])
    err = capsys.readouterr().err
    assert code == 2 and "is not a directory" in err and "Errno" not in err, err


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="Linux's /proc")
@pytest.mark.parametrize(
    "args",
    [
        ["train", "--env", "AgriNav/FurrowFollow-v3", "--timesteps", "4096"],
        ["bench", "--suite", "smoke", "--policies", "rpp"],
        ["scenario"],
    ],
)
def test_an_out_in_a_folder_that_takes_no_files_is_one_line(
    args: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """/proc looks writable to root but creates nothing: not a bare errno line (as another
    user, /proc is refused as not writable before any file is tried)."""
    code = main([*args, "--out", "/proc/agrinav-out"])
    err = capsys.readouterr().err
    assert code == 2 and "/proc/agrinav-out" in err, err
    assert "takes no files" in err or "is not writable" in err, err
    assert "Errno" not in err and len(err.strip().splitlines()) == 1, err


def test_env_kwargs_with_an_unknown_key_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kw = tmp_path / "k.yaml"
    kw.write_text("nosuch: 1\n")
    args = ["train", "--env", "AgriNav/FurrowFollow-v3", "--timesteps", "64"]
    code = main([*args, "--env-kwargs", str(kw), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "env kwargs: got ['nosuch']" in err and "Traceback" not in err, err
    assert not (tmp_path / "o").exists()


def test_run_refuses_to_overwrite_without_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["run", "--policy", "rpp", "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err and (out / "keep.txt").read_text() == "mine"


def test_run_refuses_reset_seeds_past_the_range(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--seed is bounded, but episode k resets with seed + k: the last must be in range too."""
    argv = ["run", "--policy", "rpp", "--seed", str(2**63 - 1), "--episodes", "2"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    assert "--seed/--episodes" in capsys.readouterr().err and not (tmp_path / "o").exists()


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGKILL"])
def test_a_killed_run_leaves_nothing_stale(tmp_path: Path, sig: str) -> None:
    import signal
    import time

    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "baselines.cli", "run", "--policy", "rpp", "--episodes", "20"]
    cmd += ["--env", "AgriNav/FurrowFollow-v3", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob(".run.tmp-*")) and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)  # mid-episode
        proc.send_signal(getattr(signal, sig))
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert not out.exists()
    left = list(tmp_path.glob(".run.*"))
    assert (left == []) if sig == "SIGTERM" else len(left) >= 1
    # the next run to the same --out cleans the dead run's temporaries and succeeds
    assert (
        main(
            [
                "run",
                "--policy",
                "rpp",
                "--env",
                "AgriNav/FurrowFollow-v3",
                "--out",
                str(out),
                "--scenario",
                "early-corn",
                "--episodes",
                "1",
            ]
        )
        == 0
    )
    assert out.is_dir() and list(tmp_path.glob(".run.*")) == []


@pytest.mark.parametrize(
    "args",
    [
        ["run", "--policy", "ppo:nope", "--out", "x"],
        ["run", "--policy", "mpc", "--out", "x"],
        ["bench", "--suite", "smoke", "--policies", "dwb,ppo:nope", "--out", "x"],
    ],
)
def test_a_bad_policy_is_one_line_before_any_simulator_starts(
    tmp_path: Path, args: list[str]
) -> None:
    # In a real process: pybullet prints a banner to stderr when it loads, so a policy typo
    # checked after the env is built would not be one line.
    args = [a if a != "x" else str(tmp_path / "x") for a in args]
    r = subprocess.run(
        [sys.executable, "-m", "baselines.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "policy: got" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_second_train_on_the_same_out_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two `agrinav train` on one --out used to both exit 0, the second overwriting the
    first's checkpoints: while one holds the folder, another is one clear error."""
    from scenario_gen.atomic import lock_output

    out = tmp_path / "ppo"
    with lock_output(out.absolute(), "--out"):  # what a running `agrinav train` holds
        argv = ["train", "--env", "AgriNav/FurrowFollow-v3", "--timesteps", "4096"]
        assert main([*argv, "--out", str(out)]) == 2
    assert "being written by another run" in capsys.readouterr().err
    assert not out.exists()


def test_scenario_and_an_env_kwargs_file_naming_one_are_refused_together(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--scenario replaced the file's scenario without a word: which field trained was a guess."""
    extra = tmp_path / "extra.yaml"
    extra.write_text("bank: /somewhere\n")
    out = tmp_path / "run"
    args = ["train", "--env", "AgriNav/FurrowFollow-v3", "--out", str(out)]
    code = main([*args, "--scenario", "ridged", "--env-kwargs", str(extra)])
    err = capsys.readouterr().err
    assert code == 2 and "--scenario" in err and "sets bank" in err, err
    assert not out.exists()


def test_a_run_that_diverges_is_one_line_naming_the_step_size(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An Adam step of 10^6 makes the policy's weights infinite in the first update: torch's
    distribution refuses them; the user gets the setting to lower, not torch's traceback."""
    out = tmp_path / "run"
    code = main(
        [
            *("train", "--env", "AgriNav/FurrowFollow-v3", "--out", str(out)),
            *("--timesteps", "256", "--n-envs", "1", "--no-warm-start", "--eval-episodes", "1"),
            *("--hyperparams", "learning_rate=1e6", "n_steps=64", "batch_size=32"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2, err[-2000:]
    line = [t for t in err.splitlines() if "error:" in t]
    assert len(line) == 1 and "Traceback" not in err
    assert "hyperparams.learning_rate" in line[0] and "diverged by step 64" in line[0]
    assert not out.exists()  # no checkpoint was finished


def test_a_checkpoint_that_cannot_be_written_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk while a checkpoint is written: the error reaches the user and the
    half-written ``.step_N.tmp-PID`` folder is gone (the last complete checkpoint stays)."""
    import errno

    from baselines import train

    def full_disk(folder: Path, *args: object, **kwargs: object) -> None:
        folder.mkdir(parents=True)
        (folder / "policy.npz").write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(train.checkpoint, "save", full_disk)
    saver = train._Saver.__new__(train._Saver)
    saver.out = tmp_path
    saver.hp = type("HP", (), {"policy": "MultiInputPolicy", "policy_kwargs": {}})()
    monkeypatch.setattr(saver, "_meta", lambda model: {}, raising=False)
    (tmp_path / "checkpoints" / "step_0000000100").mkdir(parents=True)
    model = type("Model", (), {"policy": None, "num_timesteps": 200})()
    with pytest.raises(OSError, match="No space left"):
        saver.periodic(model, None)
    assert sorted(p.name for p in (tmp_path / "checkpoints").iterdir()) == ["step_0000000100"]


def test_demo_saves_and_prints_the_fields_it_drives(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The demo's printed scenarios are the paper suite's fields, as its envs generate them."""
    import baselines.bench
    from baselines.bench import _make_env
    from baselines.demo import demo
    from baselines.suites import suite
    from scenario_gen import load

    ran: list[tuple[str, list[str], int]] = []

    def fake_bench(name: str, policies: list[str], seeds: int, out: Path, *a: object, **k: object):  # type: ignore[no-untyped-def]
        ran.append((name, list(policies), seeds))
        out.mkdir(parents=True)
        (out / "benchmark.md").write_text("# table\n")
        return []

    monkeypatch.setattr(baselines.bench, "bench", fake_bench)
    demo(tmp_path / "demo", seeds=1)
    printed = capsys.readouterr().out
    assert ran and ran[0][0] == "paper" and ran[0][2] == 1
    for case in suite("paper"):
        folder = tmp_path / "demo" / "scenarios" / case.group
        assert f"scenario {case.group}: {folder}" in printed
        env = _make_env(case)
        try:
            driven = env.unwrapped.scenario
        finally:
            env.close()
        saved = load(folder)  # the same spec and seed: the same field, to the files' precision
        assert (saved.spec, saved.seed) == (driven.spec, driven.seed)
        np.testing.assert_allclose(saved.plants.x, driven.plants.x, atol=1e-5)
        np.testing.assert_allclose(saved.route.xy, driven.route.xy, atol=1e-5)


def test_video_without_pyav_is_one_line_before_anything_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "av", None)  # import av raises ImportError
    out = tmp_path / "run"
    args = ["run", "--policy", "rpp", "--out", str(out), "--video"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--video" in err and "pip install av" in err, err
    assert not out.exists()


def test_run_on_one_field_notes_it_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import warnings

    args = ["run", "--env", "AgriNav/FurrowFollow-v3", "--policy", "blind", "--max-steps", "5"]
    with warnings.catch_warnings():
        warnings.simplefilter("default")  # as outside the tests
        assert main([*args, "--episodes", "2", "--out", str(tmp_path / "run")]) == 0
    notes = [
        line
        for line in capsys.readouterr().err.splitlines()
        if "every reset drives one field" in line
    ]
    assert len(notes) == 1 and notes[0].startswith("agrinav run: note: FurrowFollowEnv: "), notes


def test_bench_config_moves_one_value_on_the_suites_fields(tmp_path: Path) -> None:
    """``--config`` sets an env config value over every case's own: the same field and seed,
    the value named in each record, its conditions and the table; a key the config does not
    have is refused before anything is written."""
    argv = ["bench", "--suite", "smoke", "--policies", "blind", "--seeds", "1", "--out"]
    assert main([*argv, str(tmp_path / "a")]) == 0
    set_ = ["--config", "soil.contact_width=0.15", "--config", "soil.friction=0.4"]
    assert main([*argv, str(tmp_path / "b"), *set_]) == 0
    (a,), (b,) = (json.loads((tmp_path / d / "results.json").read_text()) for d in "ab")
    assert a["seed"] == b["seed"] and a["geometry"] == b["geometry"]
    assert "config_set" not in a
    assert b["config_set"] == {"soil.contact_width": 0.15, "soil.friction": 0.4}
    assert b["tyres"] == "0.15 m tread contact" and "tyres" not in a
    assert a["steps"] != b["steps"] or a["rmse"] != b["rmse"]  # the slippery soil drove it
    md = (tmp_path / "b" / "benchmark.md").read_text()
    assert "`soil.contact_width=0.15`, `soil.friction=0.4`" in md
    code = main([*argv, str(tmp_path / "c"), "--config", "soil.bogus=1"])
    assert code == 2 and not (tmp_path / "c").exists()


def test_an_env_kwargs_file_may_not_move_the_splits(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "seeds.yml"
    path.write_text("scenario_seeds: [0, 10]\n")
    for cmd in (["train", "--env", "AgriNav/FurrowFollow-v3"], ["tune", "--policy", "rpp"]):
        out = tmp_path / cmd[0]
        assert main([*cmd, "--env-kwargs", str(path), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "--env-kwargs scenario_seeds" in err and len(err.strip().splitlines()) == 1
        assert not out.exists()


def test_evaluations_are_strict_json_with_null_for_what_was_not_measured() -> None:
    import math

    from baselines.train import evaluations_json

    text = evaluations_json([{"rmse": 0.05, "in_furrow_rmse": math.nan, "timesteps": 64}])
    assert "NaN" not in text
    assert json.loads(text) == [{"rmse": 0.05, "in_furrow_rmse": None, "timesteps": 64}]


def test_extractor_keywords_the_policy_does_not_take_are_one_line_and_leave_no_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A TypeError traceback from inside SB3's policy, and the empty parents of --out left."""
    out = tmp_path / "np" / "a" / "b"
    argv = ["train", "--env", "AgriNav/FurrowFollow-v3", "--n-envs", "1", "--out", str(out)]
    argv += ["--timesteps", "64", "--no-warm-start"]
    argv += ["--hyperparams", "n_steps=64", "batch_size=64"]
    argv += ["policy_kwargs={features_extractor_kwargs: {foo: 1}}"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("agrinav train: error: hyperparams.policy_kwargs")
    assert "cannot build the policy" in err[-1] and not (tmp_path / "np").exists()


def test_timesteps_that_end_inside_a_rollout_are_noted(tmp_path: Path) -> None:
    from baselines.train import TrainRun, prepare
    from scenario_gen.errors import Notice

    run = TrainRun(
        "AgriNav/FurrowFollow-v3",
        tmp_path / "r",
        timesteps=100,
        n_envs=1,
        overrides={"n_steps": 64, "batch_size": 64},
    )
    with pytest.warns(Notice, match=r"--timesteps 100 trains 128 steps"):
        prepare(run)
    assert not (tmp_path / "r").exists()
