"""``agrinav run`` and ``agrinav bench``: episodes, results.json, benchmark.md and figures."""

from __future__ import annotations

import dataclasses
import json
import sys
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from agrinav_gym.interface import OBSERVATION_KEYS
from policies import check_policy_spec
from policies.spec import PolicySpec, policy_files
from scenario_gen.atomic import atomic_write_text, check_output_dir, output_dir
from scenario_gen.errors import InputError

from .cli.args import MAX_SEED
from .episodes import (
    Episode,
    VideoWriter,
    run_episode,
    run_with_interventions,
    trajectory_figure,
)
from .journal import Journal, input_digest
from .parallel import Tasks, check_spread
from .report import METRICS, bar_chart, command_line, policy_labels, table
from .suites import EVAL_SEED, Case, suite

__all__ = ["METRICS", "bench", "command_line", "run"]

CASE_SEEDS = 10_000  # reset seeds per case: case i evaluates EVAL_SEED + 10⁴·i + k


def _record(
    ep: Episode, suite_name: str, scenario: str, env: Any = None, planted: bool = False
) -> dict[str, Any]:
    """One episode's row of results.json; ``planted``: with ``planted_rmse`` (``_planted``) even
    where the rows were not drifted (a drift case's reference)."""
    return {
        "policy": ep.policy,
        "suite": suite_name,
        "scenario": scenario,
        "seed": ep.seed,
        **{k: ep.metrics.get(k) for k in METRICS},
        "driven_m": ep.metrics.get("driven_m"),  # the path the distance-weighted errors weigh
        "obstacles_hit_by_kind": ep.metrics.get("obstacles_hit_by_kind"),
        **(
            {"missed_waypoints": ep.metrics["missed_waypoints"]}
            if "missed_waypoints" in ep.metrics
            else {}
        ),
        "poses": len(ep.poses),
        "steps": ep.steps,
        "termination": ep.termination,
        "seconds": round(ep.seconds, 3),
        **(
            {"frames": ep.frames, "render_seconds": round(ep.render_seconds, 3)}
            if ep.frames
            else {}
        ),
        **ep.conditions,
        **({"geometry": geometry(env.unwrapped.scenario)} if env is not None else {}),
        **_planted(ep, env, planted),
        **(
            {
                "interventions": len(ep.interventions),
                "intervention_kinds": dict(Counter(i["kind"] for i in ep.interventions)),
                "autonomous_m": round(float(ep.autonomous_m or 0.0), 2),
            }
            if ep.interventions is not None
            else {}
        ),
    }


def _planted(ep: Episode, env: Any, planted: bool) -> dict[str, Any]:
    """On rows planted off their logged lines (or with ``planted``), the path's error from the
    lanes as planted (``planted_rmse``); a run with interventions jumps, so its path is not one
    line: left out."""
    scn = None if env is None else env.unwrapped.scenario
    if scn is None or ep.interventions is not None:
        return {}
    if not planted and scn.spec.layout.drift_amplitude <= 0.0:
        return {}
    from agrinav_gym.metrics import planted_lane_rmse

    return {"planted_rmse": planted_lane_rmse(ep.poses, scn)}


def geometry(scn: Any) -> dict[str, Any]:
    """What makes one field's route differ from another's: the held-out table's columns."""
    s = scn.spec
    return {
        "scenario_seed": scn.seed,
        "row_direction_deg": round(
            s.layout.row_angle_deg if s.layout.row_angle_deg is not None else s.field.angle_deg, 1
        ),
        "row_length_m": round(s.field.length, 1),
        "turn_offset_m": round(s.route.turn_offset, 2),
        "max_slope_deg": round(s.terrain.max_slope_deg, 1),
        # the ground's own median slope under the field (a DEM window's cap is not it)
        "field_slope_deg": (scn.info.get("slope_deg") or {}).get("median"),
        "site": s.terrain.site,
        "crop_stage": s.crop.stage,
    }


def _make_env(
    case_or_id: Case | str,
    scenario: str | None = None,
    render: bool = False,
    max_steps: int | None = None,
) -> Any:
    import gymnasium as gym

    import agrinav_gym
    from agrinav_gym.scenarios import FixedFieldWarning

    if isinstance(case_or_id, Case):
        kw = case_or_id.env_kwargs()
        if case_or_id.max_steps is not None:
            kw["max_episode_steps"] = case_or_id.max_steps
        env_id = case_or_id.env_id
    else:
        env_id = case_or_id
        kw = {"observations": list(OBSERVATION_KEYS)}
        if scenario is not None:
            kw["scenario"] = scenario
        if max_steps is not None:
            kw["max_episode_steps"] = max_steps
    agrinav_gym.check_env_id(env_id, "--env")
    if render:
        kw["render_mode"] = "rgb_array"
    if not isinstance(case_or_id, Case):
        return gym.make(env_id, **kw)
    with warnings.catch_warnings():  # a suite's fields are its own, fixed on purpose
        warnings.simplefilter("ignore", FixedFieldWarning)
        return gym.make(env_id, **kw)


def _check_trust(specs: Sequence[str], trust: bool, flag: str) -> None:
    """--trust-checkpoint loads PPO's pickled SB3 files: with no PPO it changed nothing."""
    if trust and not any(PolicySpec.parse(spec).name == "ppo" for spec in specs):
        raise InputError(
            "--trust-checkpoint",
            ",".join(specs),
            f"is given, but no policy in {flag} reads a checkpoint; allowed with a ppo policy",
        )


def _policy(spec: str, env: Any, trust: bool) -> Any:
    from policies import make_policy

    extra = {"trust_checkpoint": True} if trust and PolicySpec.parse(spec).name == "ppo" else {}
    return make_policy(spec, env, **extra)


def run(
    env_id: str,
    policy: str,
    seed: int,
    episodes: int,
    out: str | Path,
    scenario: str | None = None,
    video: bool = False,
    force: bool = False,
    trust_checkpoint: bool = False,
    max_steps: int | None = None,
) -> list[dict[str, Any]]:
    """Episodes of one policy: metrics.json, a trajectory figure per episode, with ``video``
    a WebM of the first (a progress bar per frame; its time is the record's
    ``render_seconds``, not part of ``seconds``)."""
    if episodes < 1:
        raise InputError("--episodes", episodes, "allowed: an integer >= 1")
    if seed + episodes - 1 > MAX_SEED:  # episode k resets with seed + k
        raise InputError(
            "--seed/--episodes",
            (seed, episodes),
            f"allowed: reset seeds up to {MAX_SEED} (seed + episodes - 1)",
        )
    check_policy_spec(policy)
    _check_trust([policy], trust_checkpoint, "--policy")
    if video:
        check_video()
    reads = policy_files([policy])
    if scenario is not None and Path(scenario).exists():  # a folder or file, not a preset name
        reads.append(Path(scenario))
    check_output_dir(out, force, "--out", kind="run", inputs=reads)
    # everything is checked before --out exists
    env = _make_env(env_id, scenario, render=video, max_steps=max_steps)
    records = []
    try:
        pi = _policy(policy, env, trust_checkpoint)
        name = scenario_label(env, scenario)
        with output_dir(out, force, "--out", kind="run", inputs=reads) as tmp:
            for k in tqdm(range(episodes), desc=f"{policy} on {env_id}", unit="ep"):
                if video and k == 0:
                    ep = _video_episode(env, pi, seed, policy, tmp / "episode_000.webm")
                else:
                    ep = run_episode(env, pi, seed + k, policy)
                records.append(_record(ep, "run", name, env))
                trajectory_figure(
                    ep, tmp / f"trajectory_{k:03d}.png", f"{policy} · {env_id} · seed {seed + k}"
                )
            atomic_write_text(tmp / "metrics.json", json.dumps(records, indent=1))
    finally:
        env.close()
    return records


def check_video() -> None:
    """``--video`` writes with PyAV (libvpx): a clear error before anything starts."""
    try:
        import av  # noqa: F401
    except ImportError as exc:
        raise InputError(
            "--video", True, "needs PyAV (pip install av), which writes the WebM"
        ) from exc


def _video_episode(env: Any, pi: Any, seed: int, policy: str, path: Path) -> Episode:
    limit = getattr(env.spec, "max_episode_steps", None)
    with tqdm(
        total=None if limit is None else limit + 1,
        desc="video",
        unit="frame",
        leave=False,
        position=1,
    ) as bar:
        writer = VideoWriter(path, progress=bar)
        try:
            ep = run_episode(env, pi, seed, policy, writer)
        finally:
            writer.close()
        bar.total = bar.n  # the episode ended before its step limit
        bar.refresh()
    return ep


def scenario_label(env: Any, scenario: str | None) -> str:
    """What a record calls the field: the scenario's name (its preset or folder)."""
    if scenario is not None:
        return scenario
    return str(env.unwrapped.scenario.spec.name)


def bench(
    suite_name: str,
    policies: Sequence[str],
    seeds: int,
    out: str | Path,
    command: str = "",
    force: bool = False,
    trust_checkpoint: bool = False,
    workers: int = 1,
    ray: str | None = None,
    groups: Sequence[str] | None = None,
    config: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Every policy on every case of a suite (or on its cases named in ``groups``), the same
    held-out seeds for all: a case keeps its seeds whichever others run with it. ``config``
    (dotted keys) is merged over every case's env config: the same fields and seeds with those
    values moved; each record keeps it as ``config_set``.

    Each episode is a task (``baselines.parallel``: this process, ``workers`` processes or Ray
    tasks at ``ray``); an episode is a function of its case, policy and seed alone, so the
    records are the same however they were spread (but ``seconds``, each episode's wall
    time). Finished episodes are kept in ``.<out>.partial/`` as they come back
    (``baselines.journal``): the same command after a kill runs only the missing ones."""
    if not 1 <= seeds <= CASE_SEEDS:
        raise InputError("--seeds", seeds, f"allowed: an integer in [1, {CASE_SEEDS}]")
    if not policies:
        raise InputError("--policies", "", "allowed: a comma list such as dwb,rpp,ppo:shipped")
    extra = json.dumps(config, sort_keys=True, default=str) if config else ""
    cases = suite_cases(suite_name, extra)
    chosen = _chosen_cases(cases, groups, suite_name)
    labels = policy_labels(policies)
    for spec in policies:
        check_policy_spec(spec)
    _check_trust(policies, trust_checkpoint, "--policies")
    check_spread(workers, ray)
    reads = policy_files(policies)
    check_output_dir(out, force, "--out", kind="bench", inputs=reads)
    for ci in chosen:  # every policy must fit every case before any episode runs
        env = _make_env(cases[ci])
        try:
            for spec in policies:
                _policy(spec, env, trust_checkpoint)
        finally:
            env.close()
    jobs = [
        EpisodeJob(suite_name, ci, pi, spec, name, k, trust_checkpoint, extra)
        for ci in chosen
        for pi, (spec, name) in enumerate(zip(policies, labels, strict=True))
        for k in range(seeds)
    ]
    identity = {
        "command": "bench",
        "suite": suite_name,
        "policies": list(policies),
        "seeds": seeds,
        **({"cases": [cases[ci].group for ci in chosen]} if groups else {}),
        **({"config": config} if config else {}),
        "trust_checkpoint": trust_checkpoint,
        "version": _version(),
    }
    if reads:  # absent otherwise: a journal from before the field still resumes
        # the files' bytes: an edited parameter file or a retrained checkpoint under the same
        # name must not be averaged with the episodes run before the edit
        identity["inputs"] = [input_digest(p) for p in reads]
    journal = Journal(out, identity)
    with output_dir(out, force, "--out", kind="bench", inputs=reads) as tmp:
        done = journal.open(force)  # refused before a progress bar is drawn
        with (
            tqdm(total=len(jobs), desc=f"bench {suite_name}", unit="ep") as bar,
            Tasks(workers, ray) as tasks,
        ):
            bar.update(sum(j.key in done for j in jobs))
            try:
                for key, record, png in tasks.map(
                    episode_task, [j for j in jobs if j.key not in done]
                ):
                    journal.save(key, record, {"png": png})
                    done[key] = json.loads(json.dumps(record))  # as a resumed run reads it
                    bar.update(1)
                    bar.set_postfix(case=record["scenario"], policy=record["policy"])
            except (KeyboardInterrupt, SystemExit):  # Ctrl-C, SIGTERM: say what stays
                bar.close()
                if done:
                    print(
                        f"bench: stopped; {len(done)} of {len(jobs)} episodes are kept in "
                        f"{journal.path}: rerun the same command to resume",
                        file=sys.stderr,
                    )
                else:  # nothing to resume: no journal to block another command's --out
                    journal.remove()
                    print("bench: stopped; no episode had finished", file=sys.stderr)
                raise
            finally:
                release_episode_envs()
        records = [done[j.key] for j in jobs]
        slugs = policy_slugs(list(dict.fromkeys(j.label for j in jobs)))
        for j in jobs:  # every episode's figure: the second seed is a field too
            name = trajectory_name(cases[j.case].group, slugs[j.label], j.seed)
            (tmp / name).write_bytes(journal.blob(j.key, "png"))
        atomic_write_text(tmp / "results.json", json.dumps(records, indent=1))
        (tmp / "benchmark.md").write_text(table(records, suite_name, command))
        bar_chart(records, tmp / "benchmark.png", suite_name)
    journal.remove()
    return records


def suite_cases(suite_name: str, config: str = "") -> list[Case]:
    """A suite's cases with ``config`` (JSON of dotted env config keys) merged over each one's
    env config."""
    from scenario_gen.schema import merge

    cases = suite(suite_name)
    if not config:
        return cases
    over = json.loads(config)
    return [dataclasses.replace(c, config=merge(c.config, over)) for c in cases]


def _chosen_cases(cases: Sequence[Any], groups: Sequence[str] | None, suite_name: str) -> list[int]:
    """Indices of the suite's cases named in ``groups`` (all when None), in suite order."""
    if not groups:
        return list(range(len(cases)))
    names = [c.group for c in cases]
    unknown = [g for g in groups if g not in names]
    if unknown:
        raise InputError(
            "--cases",
            ",".join(unknown),
            f"allowed: cases of the {suite_name} suite: {'; '.join(names)}",
        )
    return [i for i, n in enumerate(names) if n in groups]


def episode_seed(index: int, case: Case, k: int) -> int:
    """Episode ``k``'s reset seed for the suite's case number ``index``: each case its own
    sensor-noise draws, so groups that differ only in what a policy cannot see are still
    independent samples — unless the case reuses another's seeds to be compared with it pair by
    pair (``Case.seeds_of``)."""
    paired = index if case.seeds_of is None else case.seeds_of
    return EVAL_SEED + CASE_SEEDS * paired + k


def trajectory_name(group: str, policy: str, k: int) -> str:
    """The trajectory figure of a suite's case, policy (its slug, ``policy_slugs``) and k-th
    seed."""
    return f"traj_{_slug(group)}_{_slug(policy)}_{k:03d}.png"


def policy_slugs(labels: list[str]) -> dict[str, str]:
    """Each row label's file-name slug; labels that slug alike (``rpp:p_1.yaml`` and
    ``rpp:p-1.yaml``) get their place in the list appended, so no figure overwrites another."""
    slugs = [_slug(lab) for lab in labels]
    return {
        lab: f"{sl}-{i + 1}" if slugs.count(sl) > 1 else sl
        for i, (lab, sl) in enumerate(zip(labels, slugs, strict=True))
    }


@dataclass(frozen=True)
class EpisodeJob:
    """One episode of ``agrinav bench``: case ``case`` of suite ``suite``, policy ``policy``
    (``spec``, shown as ``label``), the case's ``seed``-th evaluation seed."""

    suite: str
    case: int
    policy: int
    spec: str
    label: str
    seed: int
    trust: bool
    config: str = ""  # JSON of the dotted env config set on every case (``bench``'s config)

    @property
    def key(self) -> str:
        return f"c{self.case:03d}-p{self.policy:02d}-s{self.seed:05d}"


#: a worker's env and policies, kept while its episodes stay on one case
_EPISODE_ENV: dict[str, Any] = {}


def episode_task(job: EpisodeJob) -> tuple[str, dict[str, Any], bytes]:
    """(key, record, trajectory figure PNG) of one bench episode (in any process)."""
    import io

    cached = _EPISODE_ENV
    case = suite_cases(job.suite, job.config)[job.case]
    if cached.get("case") != (job.suite, job.case, job.config):
        release_episode_envs()
        cached.update(case=(job.suite, job.case, job.config), env=_make_env(case), policies={})
    env, pols = cached["env"], cached["policies"]
    if job.policy not in pols:
        pols[job.policy] = _policy(job.spec, env, job.trust)
    run = run_with_interventions if case.interventions else run_episode
    ep = run(env, pols[job.policy], episode_seed(job.case, case, job.seed), job.label)
    record = _record(ep, job.suite, case.group, env, case.planted)
    if job.config:
        record["config_set"] = json.loads(job.config)
    buf = io.BytesIO()
    title = f"{job.label} · {job.suite} · {case.group} · seed {ep.seed}"
    trajectory_figure(ep, buf, title)  # type: ignore[arg-type]
    return job.key, record, buf.getvalue()


def release_episode_envs() -> None:
    """Close the env ``episode_task`` keeps (this process's)."""
    env = _EPISODE_ENV.pop("env", None)
    _EPISODE_ENV.clear()
    if env is not None:
        env.close()


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("agrinav-gym")
    except PackageNotFoundError:
        return "unknown"


def _slug(s: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in s).strip("-")
