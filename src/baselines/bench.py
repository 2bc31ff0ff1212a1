"""``agrinav run`` and ``agrinav bench``: episodes, results.json, benchmark.md and figures."""

from __future__ import annotations

import json
import math
import shlex
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from scenario_gen import ScenarioError

from .episodes import Episode, VideoWriter, run_episode, trajectory_figure
from .suites import EVAL_SEED, Case, suite

METRICS = ("rmse", "mae", "max", "in_furrow_rmse", "headland_rmse", "completion", "crops_hit")


def _make(case_or_id: Case | str, scenario: str | None = None, render: bool = False) -> Any:
    import gymnasium as gym

    import agrinav_gym  # noqa: F401

    if isinstance(case_or_id, Case):
        kw = case_or_id.env_kwargs()
        if case_or_id.max_steps is not None:
            kw["max_episode_steps"] = case_or_id.max_steps
        env_id = case_or_id.env_id
    else:
        env_id = case_or_id
        kw = {"observations": ["gps", "imu", "odom", "route", "depth"]}
        if scenario is not None:
            kw["scenario"] = scenario
    if render:
        kw["render_mode"] = "rgb_array"
    return gym.make(env_id, **kw)


def _record(ep: Episode, suite_name: str, scenario: str) -> dict[str, Any]:
    return {
        "policy": ep.policy,
        "suite": suite_name,
        "scenario": scenario,
        "seed": ep.seed,
        **{k: ep.metrics.get(k) for k in METRICS},
        "steps": ep.steps,
        "termination": ep.termination,
        "seconds": round(ep.seconds, 3),
    }


def _write_json(path: Path, data: Any) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)


def run(
    env_id: str,
    policy: str,
    seed: int,
    episodes: int,
    out: str | Path,
    scenario: str | None = None,
    video: bool = False,
) -> list[dict[str, Any]]:
    from policies import make_policy

    if episodes < 1:
        raise ScenarioError("--episodes", episodes, "allowed: an integer >= 1")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = _make(env_id, scenario, render=video)
    records = []
    try:
        pi = make_policy(policy, env)
        for k in tqdm(range(episodes), desc=f"{policy} on {env_id}", unit="ep"):
            writer = VideoWriter(out / f"episode_{k:03d}.webm") if video and k == 0 else None
            ep = run_episode(env, pi, seed + k, policy, writer)
            if writer is not None:
                writer.close()
            records.append(_record(ep, "run", scenario or "default"))
            trajectory_figure(
                ep, out / f"trajectory_{k:03d}.png", f"{policy} · {env_id} · seed {seed + k}"
            )
    finally:
        env.close()
    _write_json(out / "metrics.json", records)
    return records


def bench(
    suite_name: str, policies: Sequence[str], seeds: int, out: str | Path, command: str = ""
) -> list[dict[str, Any]]:
    from policies import make_policy

    if seeds < 1:
        raise ScenarioError("--seeds", seeds, "allowed: an integer >= 1")
    cases = suite(suite_name)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    records: list[dict[str, Any]] = []
    total = len(cases) * len(policies) * seeds
    labels = policy_labels(policies)
    with tqdm(total=total, desc=f"bench {suite_name}", unit="ep") as bar:
        for case in cases:
            env = _make(case)
            try:
                for spec, name in zip(policies, labels, strict=True):
                    pi = make_policy(spec, env)
                    for k in range(seeds):
                        ep = run_episode(env, pi, EVAL_SEED + k, name)
                        records.append(_record(ep, suite_name, case.group))
                        if k == 0:
                            trajectory_figure(
                                ep,
                                out / f"traj_{_slug(case.group)}_{_slug(name)}.png",
                                f"{name} · {suite_name} · {case.group}",
                            )
                        bar.update(1)
                        bar.set_postfix(case=case.group, policy=name)
            finally:
                env.close()
            _write_json(out / "results.json", records)
    (out / "benchmark.md").write_text(table(records, suite_name, command))
    bar_chart(records, out / "benchmark.png", suite_name)
    return records


def policy_labels(specs: Sequence[str]) -> list[str]:
    """Row labels: the policy name, or ``ppo:FOLDER`` when several PPO checkpoints compete."""
    names = [spec.split(":")[0] for spec in specs]
    labels = []
    for spec, name in zip(specs, names, strict=True):
        path = spec.partition(":")[2]
        if names.count(name) > 1 and path:
            labels.append(f"{name}:{Path(path.rstrip('/')).name or path}")
        else:
            labels.append(name)
    if len(set(labels)) < len(labels):
        raise ScenarioError("--policies", ",".join(specs), "allowed: each policy once")
    return labels


def _slug(s: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in s).strip("-")


def _mean_std(values: list[Any]) -> str:
    v = [float(x) for x in values if x is not None and not math.isnan(float(x))]
    if not v:
        return "—"
    m = statistics.fmean(v)
    s = statistics.stdev(v) if len(v) > 1 else 0.0
    return f"{m:.3f} ± {s:.3f}"


def table(records: list[dict[str, Any]], suite_name: str, command: str) -> str:
    groups = list(dict.fromkeys(r["scenario"] for r in records))
    pols = list(dict.fromkeys(r["policy"] for r in records))
    seeds = len({r["seed"] for r in records})
    head = ["scenario", "policy", *METRICS, "episodes"]
    lines = [
        f"# Benchmark: `{suite_name}` suite",
        "",
        f"Mean ± std over {seeds} held-out seed(s) per policy and scenario group; "
        "cross-track errors in metres (true pose to nearest reference segment), "
        "completion in % of the route, crops hit per episode.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for g in groups:
        for p in pols:
            rows = [r for r in records if r["scenario"] == g and r["policy"] == p]
            if rows:
                cells = [_mean_std([r[m] for r in rows]) for m in METRICS]
                lines.append(f"| {g} | {p} | " + " | ".join(cells) + f" | {len(rows)} |")
    lines += ["", *failures(records, groups, pols)]
    lines += [
        "",
        "Source paper (Gazebo, Nav2 DWB, zigzag over two rows): RMSE 0.177, MAE 0.109,"
        " in-furrow 0.200, headland 0.170, max 0.472 m.",
        "",
        "Reproduce:",
        "",
        "```bash",
        command or "agrinav bench ...",
        "```",
        "",
    ]
    return "\n".join(lines)


FAILED_BELOW = 90.0  # mean completion (%) under which a policy counts as failing a group


def failures(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """One line per policy: the scenario groups where it does not finish the route."""
    lines = [f"Where each policy fails (mean completion below {FAILED_BELOW:.0f} %):", ""]
    for p in pols:
        bad = []
        for g in groups:
            rows = [r for r in records if r["scenario"] == g and r["policy"] == p]
            if rows:
                done = statistics.fmean(float(r["completion"]) for r in rows)
                if done < FAILED_BELOW:
                    hit = statistics.fmean(float(r["crops_hit"]) for r in rows)
                    bad.append(f"{g} ({done:.0f} % done, {hit:.1f} crops hit)")
        lines.append(f"- {p}: " + (", ".join(bad) if bad else "none"))
    return lines


def bar_chart(records: list[dict[str, Any]], path: Path, suite_name: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = list(dict.fromkeys(r["scenario"] for r in records))
    pols = list(dict.fromkeys(r["policy"] for r in records))
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    width = 0.8 / max(len(pols), 1)
    for i, p in enumerate(pols):
        for ax, metric in zip(axes, ("rmse", "completion"), strict=True):
            vals, errs = [], []
            for g in groups:
                v = [
                    float(r[metric])
                    for r in records
                    if r["scenario"] == g and r["policy"] == p and r[metric] is not None
                ]
                vals.append(np.mean(v) if v else np.nan)
                errs.append(np.std(v) if v else 0.0)
            ax.bar(np.arange(len(groups)) + i * width, vals, width, yerr=errs, label=p, capsize=3)
    for ax, label in zip(axes, ("cross-track RMSE (m)", "completion (%)"), strict=True):
        ax.set_xticks(np.arange(len(groups)) + 0.4 - width / 2, groups, fontsize=8)
        ax.set_ylabel(label)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{suite_name} suite")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def command_line(argv: Sequence[str]) -> str:
    return " ".join(shlex.quote(a) for a in argv)
