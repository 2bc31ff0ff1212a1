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

import csv
import json
import sys
from dataclasses import dataclass
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
ENV_ID = "AgriNav/FieldRoute-v3"
#: The searches' conditions: RTK through the oracle EKF (suites.RTK_EKF), the same for every
#: controller and the ones the shipped parameters were chosen under (the test suites run
#: robot_localization, suites.RTK_NAV2); the path trackers ignore the depth camera, so they run
#: without it (DWB's costmap reads it).
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


def training_env(policy: str = "rpp", extra: str = "", route_clock: bool = False) -> Any:
    """FieldRoute on the training split under the searches' conditions (built once a search:
    every trial drives the same fields); ``extra`` a JSON mapping merged over envs.yml's
    env_kwargs as ``agrinav train --env-kwargs`` merges its file (more ranges, other turns);
    ``route_clock``: truncated as the test suites are (suites.ROUTE_CLOCK), not after the
    registered step limit. A ``config`` in ``extra`` goes over the searches' conditions key by
    key, so a file can set the estimator (``benchmarks/fieldroute_robot_localization.yaml``)."""
    import gymnasium as gym

    import agrinav_gym  # noqa: F401  (registers the ids)

    from .hyperparams import load, merge_env_kwargs
    from .suites import ROUTE_CLOCK, ROUTE_CLOCK_BACKSTOP, RTK_EKF

    _, setup = load(ENV_ID)
    kw = merge_env_kwargs(dict(setup.env_kwargs), json.loads(extra) if extra else {})
    given = kw.pop("config", None)
    if given is not None and not isinstance(given, dict):
        raise InputError("--env-kwargs: config", given, "allowed: a mapping of config sections")
    config = merge_env_kwargs(RTK_EKF, given or {})
    if route_clock:
        config["task"] = {**config["task"], **ROUTE_CLOCK}
        kw["max_episode_steps"] = ROUTE_CLOCK_BACKSTOP
    kw["observations"] = observations(policy)
    return gym.make(ENV_ID, **kw, config=config, scenario_seeds=list(setup.train_seeds))


def _episode(env: Any, pi: Any, policy: str, seed: int) -> dict[str, Any]:
    from .episodes import run_episode

    ep = run_episode(env, pi, seed, policy)
    return {
        "finished": ep.termination == "success",
        "path_rmse": ep.metrics["path_rmse"],
        "completion": ep.metrics["completion"],
        "crops_hit": ep.metrics["crops_hit"],
    }


@dataclass(frozen=True)
class TrialEpisode:
    """Episode ``episode`` of trial ``trial``: ``policy`` with ``params`` from reset ``seed``."""

    trial: int
    episode: int
    policy: str
    params: tuple[tuple[str, float], ...]
    seed: int
    env_kwargs: str = ""  # JSON merged over envs.yml's env_kwargs (``training_env``)
    route_clock: bool = False  # the test suites' clock (``training_env``)

    @property
    def key(self) -> str:
        return f"t{self.trial:05d}-e{self.episode:04d}"


#: a worker's training env and what it was built for, (policy, env_kwargs, route_clock): every
#: trial drives the same fields
_TRAINING_ENV: list[tuple[tuple[str, str, bool], Any]] = []


def trial_episode(job: TrialEpisode) -> tuple[str, dict[str, Any]]:
    """(key, result) of one episode of a trial (in any process; the env is built once)."""
    from policies import make_policy

    built_for = (job.policy, job.env_kwargs, job.route_clock)
    if _TRAINING_ENV and _TRAINING_ENV[0][0] != built_for:
        release_training_env()  # another controller observes other keys (DWB: depth)
    if not _TRAINING_ENV:
        _TRAINING_ENV.append((built_for, training_env(*built_for)))
    env = _TRAINING_ENV[0][1]
    pi = make_policy(job.policy, env, **policy_kwargs(job.policy, dict(job.params)))
    return job.key, _episode(env, pi, job.policy, job.seed)


def release_training_env() -> None:
    """Close the env ``trial_episode`` keeps (this process's)."""
    while _TRAINING_ENV:
        _TRAINING_ENV.pop()[1].close()


def tune(
    policy: str,
    trials: int,
    episodes: int,
    seed: int,
    out: str | Path,
    command: str = "",
    force: bool = False,
    workers: int = 1,
    ray: str | None = None,
    env_kwargs: Path | None = None,
    route_clock: bool = False,
) -> dict[str, Any]:
    """Search ``policy``'s parameters; returns the best trial (see the module docstring).
    ``env_kwargs``: a YAML mapping merged over envs.yml's env_kwargs, as ``agrinav train
    --env-kwargs`` takes it (the training fields with more geometry in their ranges).
    ``route_clock``: the episodes run on the test suites' clock (20 s per metre of route)
    instead of the registered 4,000 steps, so a slow controller is not cut short in training
    where it would finish in the tests.

    A trial's episodes are tasks (``baselines.parallel``: ``workers`` processes or Ray tasks at
    ``ray``); trials follow one another, each asked of the sampler after the one before was
    scored, so the search is the same however its episodes were spread. Finished episodes
    are kept in ``.<out>.partial/`` (``baselines.journal``): the same command after a kill
    replays the trials it finished into the sampler without running them again."""
    try:
        import optuna
    except ImportError:
        raise InputError(
            "tune", "optuna", "is not installed: pip install 'agrinav-gym[tune]'"
        ) from None
    from tqdm import tqdm

    from scenario_gen.atomic import atomic_write_text

    from .bench import _version
    from .journal import Journal
    from .parallel import Tasks, check_spread

    if policy not in SEARCH:
        raise InputError("--policy", policy, f"allowed: one of {', '.join(SEARCH)}")
    check_spread(workers, ray)
    check_output_dir(out, force, "--out", "tune")
    extra = ""
    reads: list[Path] = []  # what the search reads: an --out replaced with --force must not hold it
    v_max = None  # the robot's speed limit where the file sets one (DWB's trial 0 takes it)
    if env_kwargs is not None:
        from scenario_gen.schema import load_yaml

        from .hyperparams import refuse_split_keys
        from .train import check_make_keywords

        given = load_yaml(env_kwargs, "--env-kwargs")
        reads = [Path(env_kwargs)] + [
            Path(v) for k in ("bank", "scenario") if isinstance(v := given.get(k), str)
        ]
        check_output_dir(out, force, "--out", "tune", inputs=reads)
        refuse_split_keys(given)
        check_make_keywords(given)
        if "observations" in given:  # each controller's own (training_env): not the file's
            raise InputError(
                "--env-kwargs: observations",
                given["observations"],
                f"are the controller's own in a search ({', '.join(observations(policy))} for "
                f"{policy}); allowed: leave it out",
            )
        extra = json.dumps(given, sort_keys=True)
        probe = training_env(policy, extra)  # a bad file is refused before anything runs
        v_max = probe.unwrapped.interface.v_max
        probe.close()
    space = SEARCH[policy]
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    # The published defaults are trial 0: the search can only match or beat them.
    study.enqueue_trial(default_params(policy, v_max))
    rows: list[dict[str, Any]] = []
    identity = {
        "command": "tune",
        "policy": policy,
        "trials": trials,
        "episodes": episodes,
        "seed": seed,
        "env_kwargs": json.loads(extra) if extra else None,
        "version": _version(),
    }
    if route_clock:  # absent otherwise: a journal from before the option still resumes
        identity["route_clock"] = True
    journal = Journal(out, identity)
    with output_dir(out, force, "--out", "tune", inputs=reads) as tmp:
        done = journal.open(force, "--out")
        with Tasks(workers, ray) as tasks:
            bar = tqdm(range(trials), desc=f"tune {policy}", unit="trial")
            try:
                for _ in bar:
                    trial = study.ask()
                    params = {n: trial.suggest_float(n, lo, hi) for n, (lo, hi) in space.items()}
                    if policy == "rpp" and params["min_lookahead"] > params["max_lookahead"]:
                        params["min_lookahead"], params["max_lookahead"] = (
                            params["max_lookahead"],
                            params["min_lookahead"],
                        )
                    jobs = [
                        TrialEpisode(
                            trial.number,
                            k,
                            policy,
                            tuple(params.items()),
                            seed + k,
                            extra,
                            route_clock,
                        )
                        for k in range(episodes)
                    ]
                    for key, result in tasks.map(
                        trial_episode, [j for j in jobs if j.key not in done]
                    ):
                        journal.save(key, result)
                        done[key] = result
                    records = [done[j.key] for j in jobs]
                    value = score(records)
                    study.tell(trial, value)
                    rows.append(
                        {
                            "trial": trial.number,
                            # as the trial ran: best.yaml reproduces its score exactly
                            **params,
                            "score": value,
                            "finished": sum(r["finished"] for r in records),
                            "episodes": len(records),
                            "crops_hit": sum(int(r["crops_hit"]) for r in records),
                        }
                    )
            except BaseException as exc:
                bar.close()
                if not done:  # nothing to resume: no journal to block another search's --out
                    journal.remove()
                if isinstance(exc, (KeyboardInterrupt, SystemExit)):  # Ctrl-C, SIGTERM
                    print(
                        f"tune: stopped; {len(done)} trial episodes are kept in {journal.path}: "
                        "rerun the same command to resume"
                        if done
                        else "tune: stopped; no trial episode had finished",
                        file=sys.stderr,
                    )
                raise
            finally:
                release_training_env()
        best = min(rows, key=lambda r: (r["score"], r["trial"]))
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
            f"{trials}, score {best['score']:.5f}: mean path RMSE of finished routes, 1 m per "
            f"unfinished one, +{CROP_PENALTY} m per stalk) on {episodes} training fields"
            + (f" (env_kwargs merged from {Path(env_kwargs).name})" if env_kwargs else "")
            + (", on the test suites' route clock (20 s per metre)" if route_clock else "")
            + ".\n"
        )
        atomic_write_text(tmp / "best.yaml", header + yaml.safe_dump(chosen, sort_keys=True))
        atomic_write_text(tmp / "command.txt", (command or "agrinav tune ...") + "\n")
        search_figure(rows, tmp / "search.png", policy)
    journal.remove()
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


def default_params(policy: str, v_max: float | None = None) -> dict[str, float]:
    """The controller's own defaults for the searched parameters (trial 0); DWB's furrow
    config leaves its speed limits to the robot: ``v_max`` (None: the robot config's
    default)."""
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
            robot = RobotConfig().v_max if v_max is None else v_max
            out[dotted] = float(v) if v is not None else robot
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
