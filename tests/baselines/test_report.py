"""The benchmark table: intervals, and a failed episode failing every cross-track column."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from baselines.report import METRICS, mean_ci, mean_err, mean_pm, run_table, table


def _rec(policy: str, rmse: float, termination: str, completion: float) -> dict[str, Any]:
    r: dict[str, Any] = {m: rmse for m in METRICS}
    r.update(
        policy=policy,
        scenario="field",
        seed=0,
        termination=termination,
        completion=completion,
        crops_hit=0,
        poses=100,
    )
    return r


def test_bootstrap_interval_brackets_the_mean_and_narrows_with_more_episodes() -> None:
    rng = np.random.default_rng(1)
    few = mean_ci(rng.normal(0.1, 0.02, 5))
    many = mean_ci(rng.normal(0.1, 0.02, 500))
    assert few is not None and many is not None
    for m, lo, hi in (few, many):
        assert lo < m < hi
    # the interval of a mean shrinks as 1/√n: 100× the episodes, about a tenth of the width
    ratio = (many[2] - many[1]) / (few[2] - few[1])
    assert 0.04 < ratio < 0.25, ratio
    assert mean_ci([None, float("nan")]) is None and mean_ci([0.2]) == (0.2, 0.2, 0.2)


def test_a_failed_episode_is_a_failure_in_every_cross_track_column() -> None:
    """A run that stalls after 10 % has a tiny RMSE over the bit it drove; it must not make
    its policy's row read better than a policy that finished."""
    recs = [
        _rec("stalls", 0.01, "success", 100.0),
        _rec("stalls", 0.001, "progress", 10.0),
        _rec("never", 0.001, "crops_hit", 30.0),
    ]
    md = table(recs, "t", "agrinav bench")
    row = next(line for line in md.splitlines() if line.startswith("| field | stalls |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == "1/2"
    assert cells[3] == "0.010"  # path_rmse of the finished episode alone: no interval of one
    assert cells[3 + METRICS.index("completion")].startswith("55.000")  # over both episodes
    never = next(line for line in md.splitlines() if line.startswith("| field | never |"))
    assert never.split("|")[3].strip() == "0/1" and never.split("|")[4].strip() == "—"


@pytest.mark.parametrize("metric", METRICS)
def test_every_metric_is_a_column(metric: str) -> None:
    assert f" {metric} |" in table([_rec("p", 0.1, "success", 100.0)], "t", "")


def test_pairing_resolves_a_difference_the_field_spread_hides() -> None:
    """Two policies on 20 shared fields: B is 5 mm better on every field, the fields spread by
    5 cm. Each policy's own interval overlaps the other's; the paired interval excludes 0."""
    from baselines.report import paired_differences

    rng = np.random.default_rng(3)
    field = rng.normal(0.10, 0.05, 20).clip(0.01)
    records = []
    for seed, base in enumerate(field):
        for policy, rmse in (("a", base + 0.005), ("b", base)):
            r = _rec(policy, float(rmse), "success", 100.0)
            r["seed"] = seed
            records.append(r)
    a = mean_ci([r["path_rmse"] for r in records if r["policy"] == "a"])
    b = mean_ci([r["path_rmse"] for r in records if r["policy"] == "b"])
    assert a is not None and b is not None and a[1] < b[2]  # overlapping intervals
    ci, n = paired_differences(records, "field", "a", "b", "path_rmse")
    assert n == 20 and ci is not None
    assert ci[0] == pytest.approx(0.005) and ci[1] > 0  # resolved
    # an episode one of them did not finish drops out of the cross-track pairs only
    records[0]["termination"] = "corridor"
    assert paired_differences(records, "field", "a", "b", "path_rmse")[1] == 19
    assert paired_differences(records, "field", "a", "b", "completion")[1] == 20
    assert "Paired differences against `a`" in table(records, "t", "agrinav bench")


def test_run_prints_a_short_table_not_records() -> None:
    """``agrinav run``'s summary: a row per policy, finished episodes counted, cross-track
    errors of the finished ones only, and the episodes' own seconds apart from the video's."""
    recs = [
        {**_rec("rpp", 0.02, "success", 100.0), "seconds": 1.5, "render_seconds": 30.0},
        {**_rec("rpp", 0.5, "corridor", 20.0), "seconds": 0.5},
    ]
    lines = run_table(recs).splitlines()
    head = lines[0].split()
    assert head[:7] == ["policy", "episodes", "finished", "path_rmse", "rmse", "mae", "max"]
    assert lines[0].rstrip().endswith("seconds  video seconds")
    assert "crops hit  obstacles hit" in lines[0]
    row = lines[1].split()
    assert row[:4] == ["rpp", "2", "1/2", "0.020"]  # the corridor exit's 0.5 is not averaged in
    assert row[7] == "60.0" and row[-2:] == ["2.0", "30.0"]  # completion over both; seconds
    assert "{" not in run_table(recs)
    plain = run_table([{**_rec("dwb", 0.1, "progress", 5.0), "seconds": 2.0}])
    assert "video" not in plain and plain.splitlines()[1].split()[3] == "—"


def test_a_spread_is_shown_only_where_there_are_two_samples() -> None:
    """One seed has no spread to show: "± 0.000" and "[x, x]" would claim a certainty."""
    assert mean_pm([0.2]) == "0.200" and mean_pm([None, 0.2, float("nan")]) == "0.200"
    assert mean_pm([0.1, 0.3]) == "0.200 ± 0.100" and mean_pm([]) == "—"
    assert mean_err([0.5]) == (0.5, None) and mean_err([0.1, 0.3])[1] == pytest.approx(0.1)
    one = table([_rec("p", 0.1, "success", 100.0)], "t", "")
    row = next(line for line in one.splitlines() if line.startswith("| field | p |"))
    assert "[" not in row and "±" not in row
    two = table([_rec("p", 0.1, "success", 100.0), _rec("p", 0.2, "success", 100.0)], "t", "")
    row = next(line for line in two.splitlines() if line.startswith("| field | p |"))
    assert "0.150 [" in row


def test_a_run_past_a_missed_waypoint_is_not_finished() -> None:
    """With the follower's stop_on_failure false a run can reach the route's end past a
    waypoint it gave up on: counted, shown, and not a finish."""
    clean, skipped = _rec("p", 0.02, "success", 100.0), _rec("p", 0.5, "success", 99.0)
    clean["missed_waypoints"], skipped["missed_waypoints"] = 0, 1
    skipped["seed"] = 1
    md = table([clean, skipped], "t", "")
    head = next(line for line in md.splitlines() if line.startswith("| scenario |"))
    row = next(line for line in md.splitlines() if line.startswith("| field | p |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    cols = [c.strip() for c in head.strip("|").split("|")]
    assert cells[2] == "1/2" and cells[3] == "0.020"  # the clean run's error alone
    assert cells[cols.index("missed_waypoints")].startswith("0.500")
    assert "missed_waypoints" not in table([_rec("p", 0.1, "success", 100.0)], "t", "")


def test_the_planted_lane_column_appears_on_drifted_rows_for_finished_runs() -> None:
    """Rows planted off the logged lines: `planted_rmse` beside the route's columns, over the
    finished runs only as every error; absent where no record carries it."""
    done, failed = _rec("p", 0.02, "success", 100.0), _rec("p", 0.02, "corridor", 40.0)
    done["planted_rmse"], failed["planted_rmse"], failed["seed"] = 0.07, 0.01, 1
    md = table([done, failed], "t", "")
    head = next(line for line in md.splitlines() if line.startswith("| scenario |"))
    row = next(line for line in md.splitlines() if line.startswith("| field | p |"))
    cols = [c.strip() for c in head.strip("|").split("|")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[cols.index("planted_rmse")] == "0.070"
    assert "lanes as planted" in md
    # paired on the runs both finished, beside the route's columns
    other = [dict(r, policy="q", planted_rmse=r["planted_rmse"] - 0.03) for r in (done, failed)]
    md = table([done, failed, *other], "t", "")
    pair = [line for line in md.splitlines() if line.startswith("| field | q |")][-1]
    assert pair.endswith("| -0.030 (1) |")  # one pair: its value, no interval
    assert "planted_rmse" not in table([_rec("p", 0.1, "success", 100.0)], "t", "")


def test_the_tyres_column_appears_where_a_row_has_a_tread() -> None:
    from baselines.report import conditions

    base = {"policy": "blind", "localisation": "ideal", "camera": "none", "speed_limit": "1 m/s"}
    point = {**base, "scenario": "a", "controller": "constant"}
    tread = {**point, "scenario": "b", "tyres": "0.15 m tread contact"}
    assert "tyres" not in "\n".join(conditions([point], ["a"], ["blind"]))
    lines = conditions([point, tread], ["a", "b"], ["blind"])
    assert lines[2].split(" | ")[5] == "tyres"
    assert "| a | blind | ideal | none | 1 m/s | point contact | constant |" in lines
    assert "| b | blind | ideal | none | 1 m/s | 0.15 m tread contact | constant |" in lines


def test_an_env_on_treads_says_so_in_its_conditions() -> None:
    import gymnasium as gym

    import agrinav_gym  # noqa: F401

    yielding = {"cohesion_kpa": 1.72, "friction_angle_deg": 29.0}
    for soil, expect in (
        ({"contact_width": 0.0}, None),
        ({"contact_width": 0.15}, "0.15 m tread contact"),
        (
            {"contact_width": 0.15, **yielding},
            "0.15 m tread contact on a yielding ground (c 1.72 kPa, φ 29°, 1.3 t/m³)",
        ),
    ):
        env = gym.make("AgriNav/FurrowFollow-v3", config={"soil": soil})
        try:
            assert env.unwrapped.conditions().get("tyres") == expect
        finally:
            env.close()


def test_groups_that_drove_the_same_seeds_are_paired_and_others_are_not() -> None:
    """A case on another's fields and seeds (``Case.seeds_of``) is set against it per policy;
    a case on seeds of its own is not (its fields are other fields)."""
    from baselines.report import case_pairs

    rng = np.random.default_rng(5)
    field = rng.normal(0.10, 0.05, 20).clip(0.01)
    records = []
    for group, offset, first in (("flat", 0.0, 0), ("ridged", 0.011, 0), ("other", 0.0, 100)):
        for k, base in enumerate(field):
            r = _rec("dwb", float(base + offset), "success", 100.0)
            r.update(scenario=group, seed=first + k)
            records.append(r)
    lines = case_pairs(records, ["flat", "ridged", "other"], ["dwb"])
    rows = [ln for ln in lines if ln.startswith("| ridged") or ln.startswith("| other")]
    assert len(rows) == 1 and rows[0].startswith("| ridged | flat | dwb | +0.000 [+0.000, +0.000]")
    assert "+0.011 [+0.011, +0.011] (20)" in rows[0]  # every cross-track column moved 11 mm
    assert "Paired differences between scenario groups" in table(records, "t", "agrinav bench")
    # one unfinished run drops out of the cross-track pairs, not out of completion's
    records[25]["termination"] = "corridor"
    row = next(ln for ln in case_pairs(records, ["flat", "ridged"], ["dwb"]) if "| ridged" in ln)
    assert "(19)" in row and "(20)" in row
    assert case_pairs(records, ["flat", "other"], ["dwb"]) == []


def test_the_chart_draws_cross_track_bars_of_finished_episodes_only() -> None:
    """benchmark.png averaged every episode's error: a policy that never finished got an
    in-furrow bar (its short runs' RMSE) where the table says —."""
    from baselines.report import bar_chart_values

    recs = [
        _rec("p", 0.01, "success", 100.0),
        {**_rec("p", 0.001, "progress", 10.0), "seed": 1},
        _rec("never", 0.001, "crops_hit", 30.0),
    ]
    assert bar_chart_values(recs, "field", "p", "in_furrow_rmse") == [0.01]
    assert bar_chart_values(recs, "field", "never", "max") == []
    assert bar_chart_values(recs, "field", "p", "completion") == [100.0, 10.0]


def test_one_pair_is_a_value_and_a_resolved_interval_keeps_its_sign() -> None:
    from baselines.report import _delta_cell

    # one pair: no interval that could "exclude 0"
    assert _delta_cell((0.061, 0.061, 0.061), 1) == "+0.061 (1)"
    # an upper bound of -8e-5 printed as -0.000 hid that the interval excludes 0
    assert _delta_cell((-0.003, -0.008, -0.00008), 20) == "-0.0030 [-0.0080, -0.0001] (20)"
    assert _delta_cell((0.01, -0.002, 0.02), 20) == "+0.010 [-0.002, +0.020] (20)"


def test_a_group_a_policy_does_not_finish_is_a_failure_whatever_its_completion() -> None:
    """A run past a missed waypoint reaches ≈ 100 % completion without finishing: it was
    listed under "fails" as none."""
    from baselines.report import failures

    recs = []
    for seed in range(4):
        r = _rec("p", 0.1, "success", 99.0)
        r.update(seed=seed, missed_waypoints=1)
        recs.append(r)
    lines = failures(recs, ["field"], ["p"])
    assert lines[-1].startswith("- p: field (0/4 finished")
    ok = [{**_rec("q", 0.1, "success", 100.0), "seed": s} for s in range(4)]
    assert failures(ok, ["field"], ["q"])[-1] == "- q: none"


def test_labels_that_slug_alike_get_figures_of_their_own() -> None:
    from baselines.bench import policy_slugs, trajectory_name

    slugs = policy_slugs(["rpp:p_1.yaml", "rpp:p-1.yaml", "dwb:furrow"])
    names = {trajectory_name("g", s, 0) for s in slugs.values()}
    assert len(names) == 3 and slugs["dwb:furrow"] == "dwb-furrow"
