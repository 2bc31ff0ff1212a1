"""``agrinav run`` and ``agrinav bench``: episodes, results.json, benchmark.md and figures."""

from __future__ import annotations

import json
import warnings
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tqdm import tqdm

from agrinav_gym.interface import OBSERVATION_KEYS
from policies import check_policy_spec
from policies.spec import PolicySpec
from scenario_gen.atomic import atomic_write_text, check_output_dir, output_dir
from scenario_gen.errors import InputError

from .episodes import (
    Episode,
    VideoWriter,
    run_episode,
    run_with_interventions,
    trajectory_figure,
)
from .report import METRICS, bar_chart, command_line, policy_labels, table
from .suites import EVAL_SEED, Case, suite

__all__ = ["METRICS", "bench", "command_line", "run"]

CASE_SEEDS = 10_000  # reset seeds per case: case i evaluates EVAL_SEED + 10⁴·i + k


def _record(ep: Episode, suite_name: str, scenario: str, env: Any = None) -> dict[str, Any]:
    return {
        "policy": ep.policy,
        "suite": suite_name,
        "scenario": scenario,
        "seed": ep.seed,
        **{k: ep.metrics.get(k) for k in METRICS},
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
    check_policy_spec(policy)
    if video:
        check_video()
    check_output_dir(out, force)
    # everything is checked before --out exists
    env = _make_env(env_id, scenario, render=video, max_steps=max_steps)
    records = []
    try:
        pi = _policy(policy, env, trust_checkpoint)
        name = scenario_label(env, scenario)
        with output_dir(out, force) as tmp:
            for k in tqdm(range(episodes), desc=f"{policy} on {env_id}", unit="ep"):
                if video and k == 0:
                    ep = _video_episode(env, pi, seed, policy, tmp / "episode_000.webm")
                else:
                    ep = run_episode(env, pi, seed + k, policy)
                records.append(_record(ep, "run", name))
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
) -> list[dict[str, Any]]:
    """Every policy on every case of a suite, the same held-out seeds for all."""
    if not 1 <= seeds <= CASE_SEEDS:
        raise InputError("--seeds", seeds, f"allowed: an integer in [1, {CASE_SEEDS}]")
    if not policies:
        raise InputError("--policies", "", "allowed: a comma list such as dwb,rpp,ppo:shipped")
    cases = suite(suite_name)
    labels = policy_labels(policies)
    for spec in policies:
        check_policy_spec(spec)
    check_output_dir(out, force)
    for case in cases:  # every policy must fit every case before any episode runs
        env = _make_env(case)
        try:
            for spec in policies:
                _policy(spec, env, trust_checkpoint)
        finally:
            env.close()
    records: list[dict[str, Any]] = []
    total = len(cases) * len(policies) * seeds
    with (
        output_dir(out, force) as tmp,
        tqdm(total=total, desc=f"bench {suite_name}", unit="ep") as bar,
    ):
        for ci, case in enumerate(cases):
            env = _make_env(case)
            try:
                for spec, name in zip(policies, labels, strict=True):
                    pi = _policy(spec, env, trust_checkpoint)
                    for k in range(seeds):
                        # each case its own sensor-noise draws: groups that differ only in
                        # what a policy cannot see are still independent samples
                        run = run_with_interventions if case.interventions else run_episode
                        ep = run(env, pi, EVAL_SEED + CASE_SEEDS * ci + k, name)
                        records.append(_record(ep, suite_name, case.group, env))
                        trajectory_figure(  # every episode: the second seed is a field too
                            ep,
                            tmp / trajectory_name(case.group, name, k),
                            f"{name} · {suite_name} · {case.group} · seed {ep.seed}",
                        )
                        bar.update(1)
                        bar.set_postfix(case=case.group, policy=name)
            finally:
                env.close()
            atomic_write_text(tmp / "results.json", json.dumps(records, indent=1))
        (tmp / "benchmark.md").write_text(table(records, suite_name, command))
        bar_chart(records, tmp / "benchmark.png", suite_name)
    return records


def trajectory_name(group: str, policy: str, k: int) -> str:
    """The trajectory figure of a suite's case, policy and k-th seed."""
    return f"traj_{_slug(group)}_{_slug(policy)}_{k:03d}.png"


def _slug(s: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in s).strip("-")
