"""``agrinav train --env-kwargs FILE``: a YAML mapping merged over envs.yml's env kwargs, checked
like them before anything is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from baselines.cli import main
from baselines.train import merge_env_kwargs


def test_nested_mappings_merge_key_by_key_and_the_rest_is_replaced(tmp_path: Path) -> None:
    f = tmp_path / "extra.yaml"
    f.write_text(
        "randomize:\n  layout.row_geometry: {choices: [straight, curved]}\n"
        "  crop.stage: [2, 2]\nobservations: [imu, route]\n"
    )
    base = {
        "scenario": "paper-p1",
        "randomize": {"crop.stage": [1, 3], "field.length": [20.0, 40.0]},
        "observations": ["imu", "odom", "route"],
    }
    out = merge_env_kwargs(base, f)
    assert out == {
        "scenario": "paper-p1",
        "randomize": {
            "crop.stage": [2, 2],
            "field.length": [20.0, 40.0],
            "layout.row_geometry": {"choices": ["straight", "curved"]},
        },
        "observations": ["imu", "route"],
    }
    assert base["randomize"] == {"crop.stage": [1, 3], "field.length": [20.0, 40.0]}


def test_the_shipped_geometry_file_names_only_valid_ranges() -> None:
    import gymnasium as gym

    import agrinav_gym
    from baselines.hyperparams import load

    _, setup = load("AgriNav/FieldRoute-v3")
    root = Path(__file__).resolve().parents[2]
    kw = merge_env_kwargs(dict(setup.env_kwargs), root / "benchmarks" / "fieldroute_geometry.yaml")
    assert kw["randomize"]["layout.row_geometry"] == {"choices": ["straight", "curved", "contour"]}
    env = gym.make(agrinav_gym.check_env_id("AgriNav/FieldRoute-v3"), **kw)
    env.close()


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (None, "--env-kwargs"),
        ("- a list\n", "--env-kwargs"),
        ("randomize:\n  layout.no_such_key: [0, 1]\n", "layout.no_such_key"),
        # gym.make's own keywords: a traceback from Gymnasium, or taken silently
        ("max_episode_steps: -5\n", "max_episode_steps: got -5"),
        ("disable_env_checker: 5\n", "disable_env_checker: got 5"),
    ],
)
def test_a_bad_env_kwargs_file_exits_2_before_writing(
    tmp_path: Path, text: str | None, needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "extra.yaml"
    if text is not None:
        f.write_text(text)
    out = tmp_path / "run"
    code = main(
        ["train", "--env", "AgriNav/FurrowFollow-v3", "--out", str(out), "--env-kwargs", str(f)]
    )
    err = capsys.readouterr().err
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_the_receiver_randomized_file_draws_the_receiver_over_fieldroutes_own_ranges() -> None:
    import gymnasium as gym

    import agrinav_gym
    from baselines.hyperparams import load

    _, setup = load("AgriNav/FieldRoute-v3")
    root = Path(__file__).resolve().parents[2]
    extra = root / "benchmarks" / "fieldroute_receiver_randomized.yaml"
    kw = merge_env_kwargs(dict(setup.env_kwargs), extra)
    assert set(setup.env_kwargs["randomize"]) < set(kw["randomize"])  # the fields' ranges stay
    env = gym.make(agrinav_gym.check_env_id("AgriNav/FieldRoute-v3"), **kw)
    try:
        drawn = set()
        for seed in range(6):
            env.reset(seed=seed)
            fix = env.unwrapped.sensors.gnss.cfg.fix
            assert fix.multipath_mtbf_s in (40.0, 120.0, 600.0)
            assert 0.4 <= fix.foliage_db_per_m <= 2.0 and 0.0 <= fix.false_fix_prob <= 0.3
            drawn.add(fix.multipath_mtbf_s)
        assert len(drawn) > 1
        assert env.unwrapped.estimator.name == "robot_localization"
    finally:
        env.close()
