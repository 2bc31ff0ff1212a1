"""The guidance ridges give in the simulator, as a curve over ridge height: none on level
ground, growing with height, a rail at the 0.12 m of ridge-till maize."""

from __future__ import annotations

import itertools

import pytest

from agrinav_gym.sim.ridge_guidance import ridged_plane, turn_ratios


def test_ridged_plane_puts_rows_on_crests_and_lanes_in_troughs() -> None:
    t = ridged_plane(0.1, row_spacing=1.0)
    assert float(t.height_at(0.0, 0.0)) == pytest.approx(0.05, abs=1e-9)
    assert float(t.height_at(0.0, 0.5)) == pytest.approx(-0.05, abs=1e-9)


def test_turn_ratio_falls_monotonically_with_ridge_height() -> None:
    ratios = turn_ratios([0.0, 0.02, 0.05, 0.12])
    assert ratios[0] == 1.0  # the same ground twice: the same rate
    # Each step up in height takes away turn: a strictly falling curve, not noise around 1.
    assert all(b < a - 0.05 for a, b in itertools.pairwise(ratios)), ratios
    assert ratios[-1] < 0.2  # 12 cm ridges hold a 0.2 rad/s command at 1 m/s
