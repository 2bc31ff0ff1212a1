"""``agrinav train --device``: an unavailable device is one line before anything is made (no
silent CPU fallback), the device trained on is recorded, evaluations log under SB3's tags."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
import yaml

from baselines import hyperparams
from baselines.cli import main
from baselines.train import (
    EVAL_TAGS,
    TrainRun,
    _Saver,
    device_record,
    log_evaluation,
    resolve_device,
)
from policies import checkpoint, shipped_model
from scenario_gen import InputError

FF = "AgriNav/FurrowFollow-v3"
no_cuda = pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")


@no_cuda
@pytest.mark.parametrize("device", ["cuda", "cuda:0", "cuda:3"])
def test_cuda_is_refused_in_one_line_where_there_is_none(
    tmp_path: Path, device: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert main(["train", "--env", FF, "--out", str(out), "--device", device]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "--device" in err and "CUDA is not available here" in err and "allowed here" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("device", ["tpu", "gpu", "cuda:x", "cuda:-1", "CPU", ""])
def test_unknown_devices_list_what_is_allowed(device: str) -> None:
    with pytest.raises(InputError, match="allowed: cpu, cuda, cuda:N, mps, auto"):
        resolve_device(device)


def test_mps_is_refused_where_there_is_none() -> None:
    if torch.backends.mps.is_available():
        pytest.skip("this machine has MPS")
    with pytest.raises(InputError, match="MPS is not available here"):
        resolve_device("mps")


def test_auto_picks_what_exists() -> None:
    expected = f"cuda:{torch.cuda.current_device()}" if torch.cuda.is_available() else "cpu"
    assert resolve_device("auto") == expected
    assert resolve_device("cpu") == "cpu"


@pytest.mark.parametrize("requested", ["cpu", "auto"])
def test_the_device_used_is_recorded_in_checkpoint_and_config(
    tmp_path: Path, requested: str
) -> None:
    """What a run writes at its end (``_Saver.final``), given the shipped network as the
    trained model: the checkpoint and config.yml name the device actually used."""
    device = resolve_device(requested)
    loaded = checkpoint.load(shipped_model(FF))
    model = SimpleNamespace(policy=loaded.policy, num_timesteps=1234)
    hp, setup = hyperparams.load(FF)
    run = TrainRun(env_id=FF, out=tmp_path, device=requested)
    saver = _Saver(tmp_path, run, hp, setup, {}, device_record(device))
    saver.final(model, None, [])
    meta = json.loads((tmp_path / "checkpoint.json").read_text())
    config = yaml.safe_load((tmp_path / "config.yml").read_text())
    for record in (meta, config):
        assert record["device"] == device and record["device_name"]
    assert checkpoint.load(tmp_path).meta["device"] == device  # and it still loads


def test_evaluations_log_under_sb3_eval_callback_tags(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    from stable_baselines3.common.logger import configure
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    logger = configure(str(tmp_path), ["csv", "tensorboard"])
    res = {k: float(i) for i, k in enumerate(EVAL_TAGS)}
    log_evaluation(logger, res, 4096)
    logger.close()
    header = (tmp_path / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"eval/mean_reward", "eval/mean_ep_length", "eval/success_rate"} <= set(header)
    events = EventAccumulator(str(tmp_path))
    events.Reload()
    scalars = events.Tags()["scalars"]
    assert set(EVAL_TAGS.values()) <= set(scalars)
    (point,) = events.Scalars("eval/mean_reward")
    assert point.step == 4096 and point.value == res["return"]
