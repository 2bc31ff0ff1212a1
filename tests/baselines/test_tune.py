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
    assert min(float(r["score"]) for r in rows) == pytest.approx(
        float(next(r["score"] for r in rows if all(float(r[k]) == best[k] for k in best)))
    )
    assert (outs[0] / "search.png").is_file() and (outs[0] / "command.txt").is_file()
    env = gym.make("AgriNav/FurrowFollow-v2", observations=["route"])
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
    "content,needle", [("k: fast\n", "allowed: a finite number"), ("kk: 1\n", "unknown")]
)
def test_a_bad_parameter_file_is_one_clear_error(tmp_path: Path, content: str, needle: str) -> None:
    p = tmp_path / "p.yaml"
    p.write_text(content)
    env = gym.make("AgriNav/FurrowFollow-v2", observations=["route"])
    try:
        with pytest.raises(InputError, match=needle):
            make_policy(f"stanley:{p}", env)
    finally:
        env.close()
