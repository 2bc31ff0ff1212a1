"""The classical controllers' parameter search: seeded, defaults first, its choice runnable."""

from __future__ import annotations

import csv
from pathlib import Path

import gymnasium as gym
import pytest
import yaml

import agrinav_gym  # noqa: F401
from baselines.cli import main
from baselines.tune import SEARCH, default_params, score
from policies import make_policy
from scenario_gen.errors import InputError

pytest.importorskip("optuna")


def test_a_search_is_reproducible_starts_from_the_defaults_and_its_choice_runs(
    tmp_path: Path,
) -> None:
    outs = [tmp_path / "a", tmp_path / "b"]
    for out in outs:
        argv = ["tune", "--policy", "stanley", "--trials", "2", "--episodes", "1"]
        assert main([*argv, "--out", str(out)]) == 0
    a, b = ((o / "trials.csv").read_text() for o in outs)
    assert a == b  # the same command, the same trials
    rows = list(csv.DictReader(a.splitlines()))
    assert {k: float(rows[0][k]) for k in SEARCH["stanley"]} == default_params("stanley")
    best = yaml.safe_load((outs[0] / "best.yaml").read_text())
    assert set(best) == set(SEARCH["stanley"])
    # the log holds the values each trial ran, not rounded (best.yaml is a row of it): the
    # sampler replayed with the search's seed draws trial 1's parameters to the bit
    import optuna

    study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=0))
    study.enqueue_trial(default_params("stanley"))
    for row in rows:
        trial = study.ask()
        drawn = {n: trial.suggest_float(n, lo, hi) for n, (lo, hi) in SEARCH["stanley"].items()}
        assert {k: float(row[k]) for k in drawn} == drawn
        study.tell(trial, float(row["score"]))
    assert min(float(r["score"]) for r in rows) == pytest.approx(
        float(next(r["score"] for r in rows if all(float(r[k]) == best[k] for k in best)))
    )
    assert (outs[0] / "search.png").is_file() and (outs[0] / "command.txt").is_file()
    env = gym.make("AgriNav/FurrowFollow-v3", observations=["route"])
    try:
        pi = make_policy(f"stanley:{outs[0] / 'best.yaml'}", env)
        assert pi.k == pytest.approx(best["k"])  # type: ignore[attr-defined]
    finally:
        env.close()


def test_a_failed_route_scores_worse_than_any_finished_one() -> None:
    ok = {"finished": True, "path_rmse": 0.3, "crops_hit": 0}
    stalled = {"finished": False, "path_rmse": 0.01, "crops_hit": 0}
    assert score([stalled]) > score([ok]) and score([{**ok, "crops_hit": 2}]) > score([ok])


@pytest.mark.parametrize(
    "content,needle", [("k: fast\n", "k: got .fast.; allowed: a number"), ("kk: 1\n", "unknown")]
)
def test_a_bad_parameter_file_is_one_clear_error(tmp_path: Path, content: str, needle: str) -> None:
    p = tmp_path / "p.yaml"
    p.write_text(content)
    env = gym.make("AgriNav/FurrowFollow-v3", observations=["route"])
    try:
        with pytest.raises(InputError, match=needle):
            make_policy(f"stanley:{p}", env)
    finally:
        env.close()


def test_dwbs_trial_0_takes_the_robots_own_speed_limit() -> None:
    """The furrow config leaves max_vel_x to the robot: a file that sets the robot's v_max
    gave trial 0 the default robot's 1 m/s instead."""
    assert default_params("dwb")["FollowPath.max_vel_x"] == 1.0
    assert default_params("dwb", 0.6)["FollowPath.max_vel_x"] == 0.6


def test_dwb_gets_a_search_too_starting_from_its_furrow_config(tmp_path: Path) -> None:
    """DWB's trial 0 is the shipped furrow config (Nav2's critic weights, the robot's speed
    limit); a trial's parameters become a DWB config the controller loads, and ``best.yaml`` is
    a whole config `dwb:best.yaml` runs."""
    from baselines.tune import dwb_changes, policy_kwargs
    from policies.dwb.params import DWBParams

    d = default_params("dwb")
    assert d["FollowPath.PathAlign.scale"] == 32.0 and d["FollowPath.GoalDist.scale"] == 24.0
    assert d["FollowPath.max_vel_x"] == 1.0 and d["FollowPath.sim_time"] == 1.7
    for name, (lo, hi) in SEARCH["dwb"].items():
        assert lo <= d[name] <= hi  # the default is inside the searched range
    trial = {**d, "FollowPath.PathAlign.scale": 5.0, "FollowPath.max_vel_x": 0.4}
    p = DWBParams.load(dwb_changes(trial))
    assert p.FollowPath.PathAlign.scale == 5.0 and p.FollowPath.max_vel_x == 0.4
    furrow = DWBParams.load("furrow")
    assert p.FollowPath.prune_distance == furrow.FollowPath.prune_distance  # furrow kept
    path = tmp_path / "best.yaml"
    path.write_text(yaml.safe_dump(dwb_changes(trial)))
    env = gym.make("AgriNav/FurrowFollow-v3", observations=["route", "odom", "depth"])
    try:
        for pi in (
            make_policy(f"dwb:{path}", env),
            make_policy("dwb", env, **policy_kwargs("dwb", trial)),
        ):
            assert pi.p.FollowPath.PathAlign.scale == 5.0  # type: ignore[attr-defined]
            obs, _ = env.reset(seed=0)
            pi.reset()
            env.step(pi.act(obs))
    finally:
        env.close()


def test_env_kwargs_put_more_geometry_in_the_searched_training_fields(tmp_path: Path) -> None:
    """``--env-kwargs`` merges a file over envs.yml's env_kwargs, as ``agrinav train`` does:
    the trials drive the training split with those ranges, the header says which file, and a
    bad file is refused before anything is written."""
    import dataclasses
    import json

    from baselines.tune import TrialEpisode, release_training_env, training_env, trial_episode

    extra = {"scenario_overrides": {"layout": {"row_geometry": "curved"}}}
    env = training_env("stanley", json.dumps(extra))
    try:
        env.reset(seed=3)
        assert env.unwrapped.scenario.rows.curve is not None
    finally:
        env.close()
    from baselines.tune import _TRAINING_ENV

    job = TrialEpisode(0, 0, "stanley", tuple(default_params("stanley").items()), 3)
    _, plain = trial_episode(job)
    assert _TRAINING_ENV[0][1].unwrapped.scenario.rows.curve is None
    _, curved = trial_episode(dataclasses.replace(job, env_kwargs=json.dumps(extra)))
    # the worker built the env again for the other ranges, not kept the one it had
    assert _TRAINING_ENV[0][1].unwrapped.scenario.rows.curve is not None
    release_training_env()
    assert plain != curved

    file = tmp_path / "curved.yaml"
    file.write_text(yaml.safe_dump(extra))
    out = tmp_path / "t"
    argv = ["tune", "--policy", "stanley", "--trials", "1", "--episodes", "1", "--out", str(out)]
    assert main([*argv, "--env-kwargs", str(file)]) == 0
    assert "env_kwargs merged from curved.yaml" in (out / "best.yaml").read_text()
    # the file kept inside the search's own folder is its input: --force must not delete it
    inside = out / "curved.yaml"
    inside.write_text(yaml.safe_dump(extra))
    assert main([*argv, "--env-kwargs", str(inside), "--force"]) == 2
    assert inside.is_file()
    file.write_text("randomize: {layout.row_geometry: {choices: [straight, spiral]}}\n")
    assert main([*argv[:-1], str(tmp_path / "u"), "--env-kwargs", str(file)]) == 2
    assert not (tmp_path / "u").exists()


def test_env_kwargs_can_set_the_estimator_the_searches_run() -> None:
    """A config in ``--env-kwargs`` goes over the searches' conditions (the oracle EKF, RTK
    fixed, the benchmark's progress checker) key by key: the shipped robot_localization ranges
    (the navigation suites' estimator, nothing else) change the estimator and keep the rest;
    without them the searches run the oracle."""
    import json

    from baselines.suites import RTK_NAV2
    from baselines.tune import training_env

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "fieldroute_robot_localization.yaml"
    ranges = yaml.safe_load(path.read_text())
    assert ranges == {"config": {"localisation": RTK_NAV2["localisation"]}}
    extra = json.dumps(ranges)
    for kwargs, kind in (("", "ekf"), (extra, "robot_localization")):
        env = training_env("rpp", kwargs)
        try:
            cfg = env.unwrapped.cfg
            assert cfg.localisation.kind == kind
            assert cfg.task.progress_time == 10.0 and cfg.gnss.mode == RTK_NAV2["gnss"]["mode"]
            assert cfg.reward["progress"].cte_scale == 0.1  # envs.yml's config, kept
            if kind == "robot_localization":
                want = RTK_NAV2["localisation"]["robot_localization"]["history_length_s"]
                assert cfg.localisation.robot_localization.history_length_s == want
        finally:
            env.close()


def test_the_route_clock_times_the_trials_as_the_test_suites_are(tmp_path: Path) -> None:
    """``--route-clock``: a trial's episodes end after 20 s per metre of route (the test
    suites' clock), not the registered 4,000 steps; the choice says so."""
    from baselines.suites import ROUTE_CLOCK, ROUTE_CLOCK_BACKSTOP
    from baselines.tune import training_env

    for clock in (False, True):
        env = training_env("stanley", route_clock=clock)
        try:
            task = env.unwrapped.cfg.task
            assert task.seconds_per_metre == (ROUTE_CLOCK["seconds_per_metre"] if clock else None)
            assert env.spec.max_episode_steps == (ROUTE_CLOCK_BACKSTOP if clock else 4000)
            assert task.progress_time == 10.0  # the benchmark's progress checker either way
        finally:
            env.close()
    out = tmp_path / "t"
    argv = ["tune", "--policy", "stanley", "--trials", "1", "--episodes", "1", "--out", str(out)]
    assert main([*argv, "--route-clock"]) == 0
    assert "route clock" in (out / "best.yaml").read_text()


def test_a_search_that_fails_before_any_episode_keeps_no_journal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An unreachable cluster (here: the first episode failing) used to leave the journal's
    run.json, which then refused another search on the same --out as an unfinished one."""
    import baselines.tune as tune_module

    def unreachable(job: object) -> object:
        raise ConnectionError("no cluster")

    monkeypatch.setattr(tune_module, "trial_episode", unreachable)
    out = tmp_path / "t"
    argv = ["tune", "--policy", "rpp", "--trials", "1", "--episodes", "1", "--out", str(out)]
    assert main(argv) == 1  # the machine's error, in one line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "content,needle",
    [
        ("observations: [gps, foo]\n", "--env-kwargs: observations"),  # ignored before
        ("max_episode_steps: -5\n", "max_episode_steps: got -5"),  # Gymnasium's traceback
    ],
)
def test_env_kwargs_a_search_cannot_take_are_refused(
    tmp_path: Path, content: str, needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "kw.yaml"
    f.write_text(content)
    argv = ["tune", "--policy", "rpp", "--trials", "1", "--episodes", "1"]
    assert main([*argv, "--env-kwargs", str(f), "--out", str(tmp_path / "t")]) == 2
    assert needle in capsys.readouterr().err and not (tmp_path / "t").exists()
