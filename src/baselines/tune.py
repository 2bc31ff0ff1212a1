"""Every classical controller gets the same chance: its parameters searched on the training split.

RPP and Stanley search their arguments; DWB searches its critics' weights, the speed it samples
and its rollout horizon, written as a DWB config on top of the furrow changes (``best.yaml`` is
then a whole config: ``--policies dwb:best.yaml``).

``agrinav tune --policy rpp --trials 40 --episodes 8 --out runs/tune-rpp`` runs an Optuna TPE
search (seeded, so the same command gives the same trials) over the controller's ``SEARCH``
space. Each trial drives the same ``--episodes`` training fields of FieldRoute (scenario seeds
from the training range of ``hyperparams/envs.yml``, reset seeds ``seed … seed + episodes − 1``:
the same for every trial and every controller) under the benchmark's conditions (the EKF with
RTK, Nav2's progress checker). A trial's score is the mean over its episodes of the
path-weighted cross-track RMSE of a finished route, or ``FAIL_SCORE`` for a route not
finished, plus ``CROP_PENALTY`` per stalk touched. Nothing is decided on validation or test
fields. The folder gets ``best.yaml`` (the parameters: ``--policies rpp:best.yaml`` runs
them), ``trials.csv`` (every trial), ``search.png`` and ``command.txt``.
"""

from __future__ import annotations

import contextlib
import csv
from pathlib import Path
from typing import Any

import numpy as np

from agrinav_gym.interface import OBS_GPS, OBS_IMU, OBS_ODOM, OBS_ROUTE, OBSERVATION_KEYS
from scenario_gen.atomic import check_output_dir, output_dir
from scenario_gen.errors import InputError

#: Parameter ranges per controller: each around the published default, wide enough that the
#: default is not at an edge (RPP: Nav2's regulated pure pursuit; Stanley: Hoffmann et al.).
SEARCH: dict[str, dict[str, tuple[float, float]]] = {
    "rpp": {
        "desired_linear_vel": (0.3, 1.0),
        "lookahead_time": (0.5, 3.0),
        "min_lookahead": (0.15, 0.6),
        "max_lookahead": (0.4, 1.5),
    },
    "stanley": {
        "desired_linear_vel": (0.3, 1.0),
        "k": (0.5, 6.0),
        "k_heading": (0.5, 4.0),
        "integral_time": (2.0, 30.0),
    },
    # DWB (Nav2 Humble): the critics' weights around their defaults (32 / 24), the speed
    # sampled and the rollout horizon (1.7 s), on top of the furrow config's changes.
    "dwb": {
        "FollowPath.PathAlign.scale": (0.0, 64.0),
        "FollowPath.GoalAlign.scale": (0.0, 48.0),
        "FollowPath.PathDist.scale": (0.0, 64.0),
        "FollowPath.GoalDist.scale": (0.0, 48.0),
        "FollowPath.max_vel_x": (0.3, 1.0),
        "FollowPath.sim_time": (1.0, 3.0),
    },
}
#: Controllers whose parameters are a DWB config (dotted keys into its YAML), not arguments.
CONFIG_TUNED = ("dwb",)
FAIL_SCORE = 1.0  # m: an unfinished route scores like a metre of cross-track error
CROP_PENALTY = 0.05  # m per stalk touched
ENV_ID = "AgriNav/FieldRoute-v2"
#: The benchmark's conditions (suites.RTK_EKF); the path trackers ignore the depth camera, so
#: they run without it (DWB's costmap reads it).
OBSERVATIONS = [OBS_GPS, OBS_IMU, OBS_ODOM, OBS_ROUTE]


def observations(policy: str) -> list[str]:
    return list(OBSERVATION_KEYS) if policy in CONFIG_TUNED else OBSERVATIONS


def score(records: list[dict[str, Any]]) -> float:
    """Mean of (path RMSE if finished else FAIL_SCORE) + CROP_PENALTY × crops, over episodes."""
    parts = []
    for r in records:
        rmse = r["path_rmse"] if r["finished"] and r["path_rmse"] is not None else FAIL_SCORE
        parts.append(float(rmse) + CROP_PENALTY * int(r["crops_hit"]))
    return float(np.mean(parts))


def training_env(policy: str = "rpp") -> Any:
    """FieldRoute on the training split under the benchmark's conditions (built once a search:
    every trial drives the same fields)."""
    import gymnasium as gym

    import agrinav_gym  # noqa: F401  (registers the ids)

    from .hyperparams import load
    from .suites import RTK_EKF

    _, setup = load(ENV_ID)
    kw = dict(setup.env_kwargs)
    config = {**kw.pop("config", {}), **RTK_EKF}
    kw["observations"] = observations(policy)
    return gym.make(ENV_ID, **kw, config=config, scenario_seeds=list(setup.train_seeds))


def run_trial(
    env: Any, policy: str, params: dict[str, float], episodes: int, seed: int
) -> list[dict[str, Any]]:
    """``episodes`` episodes (reset seeds ``seed``, ``seed + 1``, ...) with ``params``."""
    from policies import make_policy

    from .episodes import run_episode

    pi = make_policy(policy, env, **policy_kwargs(policy, params))
    out = []
    for k in range(episodes):
        ep = run_episode(env, pi, seed + k, policy)
        out.append(
            {
                "finished": ep.termination == "success",
                "path_rmse": ep.metrics["path_rmse"],
                "completion": ep.metrics["completion"],
                "crops_hit": ep.metrics["crops_hit"],
            }
        )
    return out


def tune(
    policy: str,
    trials: int,
    episodes: int,
    seed: int,
    out: str | Path,
    command: str = "",
    force: bool = False,
) -> dict[str, Any]:
    """Search ``policy``'s parameters; returns the best trial (see the module docstring)."""
    try:
        import optuna
    except ImportError:
        raise InputError(
            "tune", "optuna", "is not installed: pip install 'agrinav-gym[tune]'"
        ) from None
    from tqdm import tqdm

    from scenario_gen.atomic import atomic_write_text

    if policy not in SEARCH:
        raise InputError("--policy", policy, f"allowed: one of {', '.join(SEARCH)}")
    check_output_dir(out, force, "--out")
    space = SEARCH[policy]
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    # The published defaults are trial 0: the search can only match or beat them.
    study.enqueue_trial(default_params(policy))
    rows: list[dict[str, Any]] = []
    with contextlib.closing(training_env(policy)) as env:
        for _ in tqdm(range(trials), desc=f"tune {policy}", unit="trial"):
            trial = study.ask()
            params = {name: trial.suggest_float(name, lo, hi) for name, (lo, hi) in space.items()}
            if policy == "rpp" and params["min_lookahead"] > params["max_lookahead"]:
                params["min_lookahead"], params["max_lookahead"] = (
                    params["max_lookahead"],
                    params["min_lookahead"],
                )
            records = run_trial(env, policy, params, episodes, seed)
            value = score(records)
            study.tell(trial, value)
            rows.append(
                {
                    "trial": trial.number,
                    **{k: round(v, 4) for k, v in params.items()},
                    "score": round(value, 5),
                    "finished": sum(r["finished"] for r in records),
                    "episodes": len(records),
                    "crops_hit": sum(int(r["crops_hit"]) for r in records),
                }
            )
    best = min(rows, key=lambda r: (r["score"], r["trial"]))
    with output_dir(out, force, "--out") as tmp:
        with open(tmp / "trials.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        import yaml

        chosen: dict[str, Any] = {k: best[k] for k in space}
        if policy in CONFIG_TUNED:  # a whole DWB config: `dwb:best.yaml` loads it
            chosen = dwb_changes(chosen)
        header = (
            f"# {policy} parameters chosen by `agrinav tune` (trial {best['trial']} of "
            f"{trials}, score {best['score']}: mean path RMSE of finished routes, 1 m per "
            f"unfinished one, +{CROP_PENALTY} m per stalk) on {episodes} training fields.\n"
        )
        atomic_write_text(tmp / "best.yaml", header + yaml.safe_dump(chosen, sort_keys=True))
        atomic_write_text(tmp / "command.txt", (command or "agrinav tune ...") + "\n")
        search_figure(rows, tmp / "search.png", policy)
    return best


def dwb_changes(params: dict[str, float]) -> dict[str, Any]:
    """The furrow config's changes to Nav2's DWB with ``params`` (dotted keys) set on top."""
    from policies.dwb.params import _shipped
    from scenario_gen.schema import merge

    nested: dict[str, Any] = {}
    for dotted, value in params.items():
        node = nested
        *parents, leaf = dotted.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = float(value)
    out: dict[str, Any] = merge(_shipped("furrow"), nested)
    return out


def policy_kwargs(policy: str, params: dict[str, float]) -> dict[str, Any]:
    """How a trial's parameters reach the controller: arguments, or a DWB config."""
    return {"params": dwb_changes(params)} if policy in CONFIG_TUNED else dict(params)


def default_params(policy: str) -> dict[str, float]:
    """The controller's own defaults for the searched parameters (trial 0)."""
    import inspect

    from policies import POLICIES

    if policy in CONFIG_TUNED:  # the furrow config, the robot's speed limit where it says none
        from agrinav_gym.config import RobotConfig
        from policies.dwb.params import DWBParams
        from scenario_gen.schema import to_mapping

        values = to_mapping(DWBParams.load("furrow"))
        out = {}
        for dotted in SEARCH[policy]:
            v: Any = values
            for part in dotted.split("."):
                v = v[part]
            out[dotted] = float(v) if v is not None else RobotConfig().v_max
        return out

    sig = inspect.signature(POLICIES[policy].__init__)
    return {name: float(sig.parameters[name].default) for name in SEARCH[policy]}


def search_figure(rows: list[dict[str, Any]], path: Path, policy: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    s = [r["score"] for r in rows]
    ax.plot([r["trial"] for r in rows], s, "o", ms=3, label="trial")
    ax.plot([r["trial"] for r in rows], np.minimum.accumulate(s), "-", label="best so far")
    ax.axhline(s[0], color="0.6", lw=0.8, ls="--", label="defaults (trial 0)")
    ax.set_xlabel("trial")
    ax.set_ylabel("score (m)")
    ax.set_yscale("log" if max(s) / max(min(s), 1e-9) > 20 else "linear")
    ax.set_title(f"{policy}: search on training fields", fontsize=9)
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=100)
