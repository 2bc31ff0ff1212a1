"""Benchmark reports: the results table (mean ± std, failures, reproduce command) and chart."""

from __future__ import annotations

import json
import math
import shlex
import statistics
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from policies.spec import PolicySpec
from scenario_gen.errors import InputError

#: Cross-track errors: path-weighted (the headline) and the paper's per-pose (time-weighted).
CTE_METRICS = (
    "path_rmse",
    "path_in_furrow_rmse",
    "path_headland_rmse",
    "rmse",
    "mae",
    "max",
    "in_furrow_rmse",
    "headland_rmse",
)
METRICS = (*CTE_METRICS, "completion", "crops_hit", "obstacles_hit")
#: On rows planted off their logged lines: the path's error from the lanes as planted
#: (``agrinav_gym.metrics.planted_lane_rmse``), beside the logged route's.
PLANTED_METRIC = "planted_rmse"
ERRORS = (*CTE_METRICS, PLANTED_METRIC)  # averaged over the finished episodes only
BOOTSTRAP = 2000  # resamples of the per-episode values for a 95 % percentile interval


def policy_labels(specs: Sequence[str]) -> list[str]:
    """Row labels: the policy name, ``dwb:CONFIG`` (nav2, furrow, tuned or the YAML file's
    name) for DWB, ``NAME:tuned`` for the shipped tuned parameters, ``NAME:FILE`` /
    ``ppo:FOLDER`` for a user's parameters or checkpoint (even alone: a row labelled plain
    ``rpp`` or ``ppo`` is the defaults or the shipped model), ``ppo:shipped`` beside others."""
    from policies import SHIPPED_ARG, TUNED_ARG
    from policies.dwb import config_label
    from policies.dwb.params import SHIPPED as DWB_SHIPPED

    parsed = [PolicySpec.parse(spec) for spec in specs]
    names = [p.name for p in parsed]
    labels = []
    for name, path in parsed:
        if name == "dwb":
            labels.append(f"dwb:{config_label(path or None)}")
        elif path == TUNED_ARG:
            labels.append(f"{name}:{TUNED_ARG}")
        elif path and path != SHIPPED_ARG:
            labels.append(f"{name}:{Path(path.rstrip('/')).name or path}")
        elif names.count(name) > 1 and path:
            labels.append(f"{name}:{path}")
        else:
            labels.append(name)
    # files of one name in different folders (every tune writes best.yaml): the folders
    # above them, as many as tell them apart
    for depth in range(2, 8):
        clash = {lab for lab in labels if labels.count(lab) > 1}
        if not clash:
            break
        for i, ((name, path), lab) in enumerate(zip(parsed, labels, strict=True)):
            if lab in clash and path and not (name == "dwb" and path in DWB_SHIPPED):
                parts = Path(path.rstrip("/")).parts[-depth:]
                labels[i] = f"{name}:{'/'.join(parts)}"
    if len(set(labels)) < len(labels):
        raise InputError("--policies", ",".join(specs), "allowed: each policy once")
    return labels


def mean_ci(values: Sequence[Any]) -> tuple[float, float, float] | None:
    """(mean, low, high): the mean of the finite values with a 95 % percentile bootstrap
    interval (a fixed seed: the same records give the same table)."""
    v = np.array([float(x) for x in values if x is not None and math.isfinite(float(x))])
    if v.size == 0:
        return None
    m = float(v.mean())
    if v.size == 1:
        return m, m, m
    rng = np.random.default_rng(0)
    means = v[rng.integers(0, v.size, (BOOTSTRAP, v.size))].mean(axis=1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return m, float(lo), float(hi)


def _cell(values: Sequence[Any]) -> str:
    """Mean [95 % interval]; one sample is its value alone (no interval to give)."""
    ci = mean_ci(values)
    if ci is None:
        return "—"
    if _finite(values) < 2:
        return f"{ci[0]:.3f}"
    return f"{ci[0]:.3f} [{ci[1]:.3f}, {ci[2]:.3f}]"


def _finite(values: Sequence[Any]) -> int:
    return sum(1 for x in values if x is not None and math.isfinite(float(x)))


def mean_pm(values: Sequence[Any], digits: int = 3) -> str:
    """The finite values' mean ± standard deviation; the mean alone for one value, "—" for
    none (a spread of one sample, "± 0.000", would claim a certainty there is not)."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    if not v:
        return "—"
    if len(v) < 2:
        return f"{v[0]:.{digits}f}"
    return f"{statistics.fmean(v):.{digits}f} ± {statistics.pstdev(v):.{digits}f}"


def mean_err(values: Sequence[float]) -> tuple[float, float | None]:
    """A bar's mean and its error bar (the standard deviation), None below two values."""
    v = [float(x) for x in values]
    if not v:
        return math.nan, None
    return statistics.fmean(v), (statistics.pstdev(v) if len(v) >= 2 else None)


def finished(record: dict[str, Any]) -> bool:
    """The route's end reached without a waypoint given up on the way (the waypoint
    follower's ``stop_on_failure: false`` reaches the end past missed ones)."""
    return record.get("termination") == "success" and not record.get("missed_waypoints")


def _config_set(records: list[dict[str, Any]]) -> list[str]:
    """The env config ``agrinav bench --config`` set over every case's own, said once."""
    sets = {json.dumps(r.get("config_set", {}), sort_keys=True) for r in records}
    if sets == {"{}"}:
        return []
    said = " / ".join(
        ", ".join(f"`{k}={v}`" for k, v in json.loads(c).items()) or "none" for c in sorted(sets)
    )
    return ["", f"Env config set on every case over the suite's own (`--config`): {said}."]


def table(records: list[dict[str, Any]], suite_name: str, command: str) -> str:
    groups = list(dict.fromkeys(r["scenario"] for r in records))
    pols = list(dict.fromkeys(r["policy"] for r in records))
    # each case draws its own reset seeds: count episodes per (case, policy), not seeds overall
    episodes = max(Counter((r["scenario"], r["policy"]) for r in records).values())
    planted = any(PLANTED_METRIC in r for r in records)
    optional = (PLANTED_METRIC,) * planted + ("missed_waypoints",) * any(
        "missed_waypoints" in r for r in records
    )
    metrics = METRICS + optional
    head = ["scenario", "policy", "finished", *metrics, "poses", "episodes"]
    lines = [
        f"# Benchmark: `{suite_name}` suite",
        "",
        f"Mean [95 % bootstrap interval] over {episodes} held-out episode(s) per policy and "
        "scenario group. Cross-track errors in metres (true pose to nearest reference segment) "
        "over the episodes that **finished** the route only: a failed episode is a failure, not a "
        "short RMSE (`—`: none finished). `path_*` weigh each pose by the path driven around it "
        "(the headline); the paper's `rmse`, `mae`, `in_furrow_rmse`, `headland_rmse` weigh every "
        "20 Hz pose, standing still included (`poses`: their number, over the same finished "
        "episodes). Completion in % of the route, crops hit and "
        "obstacles hit (stones, litter, fallen stalks the footprint touched) per episode over "
        "every episode"
        + (
            "; `missed_waypoints`: waypoints the navigator gave up on and went past (a run with "
            "one is not finished)."
            if "missed_waypoints" in optional
            else "."
        )
        + (
            " The rows were planted off the lines the route follows: `planted_rmse` is the path's "
            "error from the lanes as planted (midway between each lane's two drifted rows, the "
            "poses inside a lane, path-weighted), where the route's columns measure it from the "
            "logged line."
            if planted
            else ""
        ),
        *_config_set(records),
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for g in groups:
        for p in pols:
            rows = [r for r in records if r["scenario"] == g and r["policy"] == p]
            if rows:
                done = [r for r in rows if finished(r)]
                cells = [
                    _cell([r.get(m) for r in (done if m in ERRORS else rows)]) for m in metrics
                ]
                counts = [int(r["poses"]) for r in done if r.get("poses") is not None]
                poses = f"{statistics.fmean(counts):.0f}" if counts else "—"
                lines.append(
                    f"| {g} | {p} | {len(done)}/{len(rows)} | "
                    + " | ".join(cells)
                    + f" | {poses} | {len(rows)} |"
                )
    lines += ["", *conditions(records, groups, pols)]
    lines += paired(records, groups, pols)
    lines += case_pairs(records, groups, pols)
    lines += held_out(records)
    lines += ["", *failures(records, groups, pols)]
    lines += interventions(records, groups, pols)
    lines += [
        "",
        "Source paper (Gazebo, Nav2 DWB, four GPS waypoints over two lanes): RMSE 0.177, MAE 0.109,"
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


#: What the paired comparison reports (on the same fields and reset seeds).
PAIRED = (("completion", 1.0), ("path_rmse", -1.0))  # (metric, sign of "better")


def paired_differences(
    records: list[dict[str, Any]], group: str, a: str, b: str, metric: str
) -> tuple[tuple[float, float, float] | None, int]:
    """Mean of ``a − b`` over the episodes both policies drove on the same field and reset
    seed (for cross-track metrics: both finished), with its 95 % bootstrap interval, and the
    number of pairs. Pairing removes the field-to-field spread both policies share, so a
    difference smaller than either policy's own interval can still be resolved."""
    by = {(r["policy"], r.get("seed")): r for r in records if r["scenario"] == group}
    pairs = [
        (ra, by[(b, seed)])
        for (pol, seed), ra in by.items()
        if pol == a and seed is not None and (b, seed) in by
    ]
    return _pair_diffs(pairs, metric)


def _pair_diffs(
    pairs: list[tuple[dict[str, Any], dict[str, Any]]], metric: str
) -> tuple[tuple[float, float, float] | None, int]:
    """Mean of ``a − b`` over ``(a, b)`` record pairs (cross-track metrics: both finished)."""
    diffs = []
    for ra, rb in pairs:
        if metric in ERRORS and not (finished(ra) and finished(rb)):
            continue
        va, vb = ra.get(metric), rb.get(metric)
        if va is not None and vb is not None:
            diffs.append(float(va) - float(vb))
    return mean_ci(diffs), len(diffs)


def _delta_cell(ci: tuple[float, float, float] | None, n: int, digits: int = 3) -> str:
    """A paired difference's cell: signed mean [interval] (pairs), the mean alone for one pair
    (an interval of one pair would "exclude 0" with nothing resolved), or — without pairs. An
    interval that excludes 0 keeps as many digits as show it (``[-0.008, -0.00008]``, not a
    bound printed as ``-0.000``)."""
    if ci is None:
        return "—"
    if n < 2:
        return f"{ci[0]:+.{digits}f} ({n})"
    lo, hi = ci[1], ci[2]
    if lo > 0 or hi < 0:
        near = min(abs(lo), abs(hi))
        while digits < 9 and round(near, digits) == 0:
            digits += 1
    m, a, b = (f"{v:+.{digits}f}" for v in ci)
    return f"{m} [{a}, {b}] ({n})"


#: What the paired comparison of two scenario groups reports: the paper's per-pose in-furrow
#: and headland errors beside the headline, since a case often moves one and not the other.
PAIRED_CASES = ("completion", "crops_hit", "path_rmse", "in_furrow_rmse", "headland_rmse")


def case_pairs(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """Each scenario group against the first earlier group whose episodes (per policy) drove
    the same reset seeds: a case that reuses another's fields and seeds (``Case.seeds_of``)
    differs from it only in what it sets, so the difference is that setting's effect."""
    by: dict[tuple[str, str], dict[Any, dict[str, Any]]] = {}
    for r in records:
        by.setdefault((r["scenario"], r["policy"]), {})[r.get("seed")] = r
    metrics = [*PAIRED_CASES, *[PLANTED_METRIC] * any(PLANTED_METRIC in r for r in records)]
    lines: list[str] = []
    for p in pols:
        for i, g in enumerate(groups):
            own = by.get((g, p), {})
            if not own or None in own:
                continue
            ref = next((h for h in groups[:i] if by.get((h, p), {}).keys() == own.keys()), None)
            if ref is None:
                continue
            pairs = [(r, by[(ref, p)][seed]) for seed, r in own.items()]
            cells = []
            for metric in metrics:
                ci, n = _pair_diffs(pairs, metric)
                cells.append(_delta_cell(ci, n))
            lines.append(f"| {g} | {ref} | {p} | " + " | ".join(cells) + " |")
    if not lines:
        return []
    head = ["scenario", "against", "policy", *(f"Δ {m}" for m in metrics)]
    return [
        "",
        "Paired differences between scenario groups that drove the same fields and reset seeds "
        "(this group − the one it is set against, per policy; cross-track over episodes both "
        "finished): mean [95 % bootstrap interval] (pairs).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
        *lines,
    ]


def paired(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """Every policy against the first one listed, per scenario group, on shared seeds."""
    if len(pols) < 2:
        return []
    ref = pols[0]
    planted = any(PLANTED_METRIC in r for r in records)
    metrics = [m for m, _ in PAIRED] + [PLANTED_METRIC] * planted
    head = ["scenario", "policy", *(f"Δ {m}" for m in metrics)]
    lines = [
        "",
        f"Paired differences against `{ref}` (this policy − {ref}, same fields and reset seeds; "
        "cross-track over episodes both finished): mean [95 % bootstrap interval] (pairs). An "
        "interval that excludes 0 is a difference these episodes resolve.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    rows = 0
    for g in groups:
        for p in pols[1:]:
            cells = []
            for metric in metrics:
                ci, n = paired_differences(records, g, p, ref, metric)
                cells.append(_delta_cell(ci, n))
            if any(c != "—" for c in cells):
                lines.append(f"| {g} | {p} | " + " | ".join(cells) + " |")
                rows += 1
    return lines if rows else []


#: ``run_table``'s cross-track columns: the headline, then the paper's
RUN_CTE = ("path_rmse", "rmse", "mae", "max")


def run_table(records: list[dict[str, Any]]) -> str:
    """``agrinav run``'s summary, a plain-text table: one row per policy with its episodes,
    how many finished, the mean cross-track errors of those (m), mean completion, crops hit and
    obstacles hit of all, and the episodes' own seconds summed (with a video, its frames' seconds
    apart)."""
    head = [
        "policy",
        "episodes",
        "finished",
        *RUN_CTE,
        "completion %",
        "crops hit",
        "obstacles hit",
        "seconds",
    ]
    video = any("render_seconds" in r for r in records)
    if video:
        head.append("video seconds")
    rows = [head]
    for p in dict.fromkeys(r["policy"] for r in records):
        mine = [r for r in records if r["policy"] == p]
        done = [r for r in mine if finished(r)]

        def mean(key: str, over: list[dict[str, Any]], fmt: str = ".3f") -> str:
            v = [float(r[key]) for r in over if r.get(key) is not None]
            return format(statistics.fmean(v), fmt) if v else "—"

        row = [p, str(len(mine)), f"{len(done)}/{len(mine)}", *(mean(m, done) for m in RUN_CTE)]
        row += [mean("completion", mine, ".1f"), mean("crops_hit", mine, ".3g")]
        row.append(mean("obstacles_hit", mine, ".3g"))
        row.append(f"{sum(float(r.get('seconds', 0.0)) for r in mine):.1f}")
        if video:
            row.append(f"{sum(float(r.get('render_seconds', 0.0)) for r in mine):.1f}")
        rows.append(row)
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.append(
        "cross-track errors (m): means over the finished episodes (— none finished); "
        "completion, crops hit, obstacles hit: over all"
    )
    return "\n".join(lines)


CONDITIONS = ("localisation", "camera", "speed_limit", "controller")
#: a record with no "tyres" condition: the registered envs' wheels (sim.tyres)
POINT_CONTACT = "point contact"
GEOMETRY = (
    "row_direction_deg",
    "row_length_m",
    "turn_offset_m",
    "max_slope_deg",
    "field_slope_deg",
    "site",
    "crop_stage",
)


def held_out(records: list[dict[str, Any]]) -> list[str]:
    """The fields the episodes drove, one row per evaluation seed, when they differ."""
    fields: dict[tuple[str, Any], dict[str, Any]] = {}
    for r in records:
        if "geometry" in r:
            fields.setdefault((r["scenario"], r["seed"]), r["geometry"])
    if len({g.get("scenario_seed") for g in fields.values()}) < 2:
        return []  # one field per case: the suite's own table says what it is
    head = ["scenario", "reset seed", "scenario seed", *GEOMETRY]
    lines = [
        "",
        "Fields driven (held out: drawn from the evaluation seeds, disjoint from every training "
        "seed range; the same field for every policy at a seed):",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for (group, seed), g in fields.items():
        cells = [str(g.get(k, "—")) for k in GEOMETRY]
        lines.append(f"| {group} | {seed} | {g.get('scenario_seed')} | " + " | ".join(cells) + " |")
    return lines


def conditions(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """What produced each row: no number without its localisation, camera, speed limit and
    controller configuration (and the tyres' contact, where some row is not a point)."""
    cols = list(CONDITIONS)
    if any("tyres" in r for r in records):
        cols.insert(3, "tyres")
    head = [c.replace("_", " ") for c in cols]
    lines = [
        "Conditions of each row:",
        "",
        "| scenario | policy | " + " | ".join(head) + " |",
        "|" + "---|" * (len(head) + 2),
    ]
    for g in groups:
        for p in pols:
            rows = [r for r in records if r["scenario"] == g and r["policy"] == p]
            if rows:
                cells = [
                    " / ".join(
                        dict.fromkeys(
                            str(r.get(c, POINT_CONTACT if c == "tyres" else "—")) for r in rows
                        )
                    )
                    for c in cols
                ]
                lines.append(f"| {g} | {p} | " + " | ".join(cells) + " |")
    return lines


def interventions(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """Long runs with interventions: how far each policy drives by itself between them."""
    if not any("interventions" in r for r in records):
        return []
    lines = [
        "",
        "Interventions (every stall, corridor exit or stalk contact; the run resumes from the "
        "route). Mean distance between interventions is the route distance driven by the robot "
        "itself over all episodes of the cell, divided by their interventions; the rate per "
        "100 m has a 95 % bootstrap interval over episodes. Field reports for comparison (LiDAR "
        "+ IMU row following on a compact robot): 386.9 m in fields without gaps, 56.1 m in "
        "production fields, 47.5 m with 1 m gaps.",
        "",
        "| scenario | policy | driven (m) | interventions | mean distance between (m) | "
        "per 100 m | kinds |",
        "|---|---|---|---|---|---|---|",
    ]
    for g in groups:
        for p in pols:
            rows = [r for r in records if r["scenario"] == g and r["policy"] == p]
            if not rows or "interventions" not in rows[0]:
                continue
            metres = sum(float(r["autonomous_m"]) for r in rows)
            n = sum(int(r["interventions"]) for r in rows)
            mdbi = f"{metres / n:.1f}" if n else f"> {metres:.0f} (none)"
            rate = _cell([_rate(r) for r in rows])
            kinds: Counter[str] = Counter()
            for r in rows:
                kinds.update(r.get("intervention_kinds", {}))
            kind_text = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())) or "—"
            lines.append(f"| {g} | {p} | {metres:.0f} | {n} | {mdbi} | {rate} | {kind_text} |")
    return lines + _paired_rates(records, groups, pols)


def _rate(record: dict[str, Any]) -> float:
    """Interventions per 100 m the robot drove by itself."""
    return 100.0 * record["interventions"] / max(record["autonomous_m"], 1e-9)


def _paired_rates(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """Each policy's rate per 100 m against every policy listed before it, on shared seeds:
    pairing resolves differences the cells' own intervals leave open."""
    rated = [dict(r, rate=_rate(r)) for r in records if "interventions" in r]
    lines = []
    for g in groups:
        for i, p in enumerate(pols):
            for q in pols[:i]:
                ci, n = paired_differences(rated, g, p, q, "rate")
                if ci is not None and n >= 2:
                    lines.append(f"| {g} | {p} − {q} | {_delta_cell(ci, n, 2)} |")
    if not lines:
        return []
    head = [
        "",
        "Paired differences of the rate per 100 m (same fields and reset seeds): mean [95 % "
        "bootstrap interval] (pairs); an interval that excludes 0 is resolved.",
        "",
        "| scenario | policies | Δ per 100 m |",
        "|---|---|---|",
    ]
    return head + lines


FAILED_BELOW = 90.0  # mean completion (%) under which a policy counts as failing a group
#: the share of episodes (%) a policy must finish in a group not to count as failing it (the
#: benchmark's target for the tuned controllers and the learned route policy)
FINISHED_AT_LEAST = 95.0


def failures(records: list[dict[str, Any]], groups: list[str], pols: list[str]) -> list[str]:
    """One line per policy: the scenario groups where it does not finish the route."""
    lines = [
        f"Where each policy fails (fewer than {FINISHED_AT_LEAST:.0f} % of the episodes finished, "
        f"or a mean completion below {FAILED_BELOW:.0f} %):",
        "",
    ]
    for p in pols:
        bad = []
        for g in groups:
            rows = [r for r in records if r["scenario"] == g and r["policy"] == p]
            if rows:
                ends = sum(finished(r) for r in rows)
                done = statistics.fmean(float(r["completion"]) for r in rows)
                if 100.0 * ends < FINISHED_AT_LEAST * len(rows) or not done >= FAILED_BELOW:
                    hit = statistics.fmean(float(r["crops_hit"]) for r in rows)
                    bad.append(
                        f"{g} ({ends}/{len(rows)} finished, {done:.0f} % done, {hit:.1f} crops hit)"
                    )
        lines.append(f"- {p}: " + (", ".join(bad) if bad else "none"))
    return lines


def bar_chart_values(
    records: list[dict[str, Any]], group: str, policy: str, metric: str
) -> list[float]:
    """What one bar of ``bar_chart`` averages: as the table, cross-track errors over the
    finished episodes only (a failed episode's short RMSE would read better than a finish)."""
    return [
        float(r[metric])
        for r in records
        if r["scenario"] == group
        and r["policy"] == policy
        and r.get(metric) is not None
        and (metric not in ERRORS or finished(r))
    ]


def bar_chart(records: list[dict[str, Any]], path: Path, suite_name: str) -> None:
    """Mean ± std per scenario group and policy (error bars where a bar has two values or
    more): in-furrow and headland cross-track error (the paper's split) and max deviation over
    the finished episodes (no bar where none finished), completion and crops hit over all."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    groups = list(dict.fromkeys(r["scenario"] for r in records))
    pols = list(dict.fromkeys(r["policy"] for r in records))
    panels: tuple[tuple[str, str], ...] = (
        ("in_furrow_rmse", "in-furrow RMSE (m)"),
        ("headland_rmse", "headland RMSE (m)"),
        ("max", "max deviation (m)"),
        ("completion", "completion (%)"),
        ("crops_hit", "crops hit"),
    )
    panels = tuple(
        pn for pn in panels if any(r[pn[0]] is not None for r in records)
    )  # no headland panel for single-lane suites
    fig = Figure(figsize=(3.2 * len(panels) + 1.5, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(panels))
    width = 0.8 / max(len(pols), 1)
    x = np.arange(len(groups))
    for ax, (metric, label) in zip(np.atleast_1d(axes), panels, strict=True):
        for i, p in enumerate(pols):
            vals, errs = [], []
            for g in groups:
                m, e = mean_err(bar_chart_values(records, g, p, metric))
                vals.append(m)
                errs.append(np.nan if e is None else e)  # no bar drawn for one value
            yerr = errs if np.isfinite(errs).any() else None
            ax.bar(
                x + (i - (len(pols) - 1) / 2) * width, vals, width, yerr=yerr, label=p, capsize=3
            )
        ax.set_xticks(
            x,
            groups,
            fontsize=8,
            rotation=30 if len(groups) > 3 else 0,
            ha="right" if len(groups) > 3 else "center",
        )
        ax.set_title(label, fontsize=9)
        ax.set_ylim(0, max(1.0 if metric == "crops_hit" else 0.0, ax.get_ylim()[1]))
    fig.legend(
        *np.atleast_1d(axes)[0].get_legend_handles_labels(),
        loc="outside lower center",
        ncols=len(pols),
        fontsize=8,
    )
    many = max(Counter((r["scenario"], r["policy"]) for r in records).values(), default=0) > 1
    fig.suptitle(
        f"{suite_name} suite ("
        + ("mean ± std over seeds" if many else "one seed")
        + "; cross-track over the finished episodes)"
    )
    fig.savefig(path, dpi=100)


def command_line(argv: Sequence[str]) -> str:
    return " ".join(shlex.quote(a) for a in argv)
