"""The benchmark table: intervals, and a failed episode failing every cross-track column."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from baselines.report import METRICS, mean_ci, table


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
    assert cells[3] == "0.010 [0.010, 0.010]"  # path_rmse of the finished episode alone
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
