"""Planting drift (scenario_gen/drift.py): planted rows off their logged lines, bounded by the
amplitude, seeded, shared by a planter pass, and nothing at all by default."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import scenario_gen as sg
from scenario_gen.drift import lane_error, planted_offset
from scenario_gen.errors import InputError
from scenario_gen.generate import STREAMS, planting_drift, streams
from scenario_gen.io import save
from scenario_gen.reading import load

SMALL = {"width": 12.0, "length": 40.0}


def scenario(seed: int = 0, **layout: object) -> sg.Scenario:
    return sg.generate(sg.preset("default", field=SMALL, layout=layout), seed)


def residual(scn: sg.Scenario) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row, along-row t, lateral offset from the logged line) of every crop plant."""
    p = scn.plants
    crop = p.row >= 0
    t, s = scn.rows.to_rows(p.x[crop], p.y[crop])
    row = p.row[crop]
    return row, t, s - scn.rows.offsets[row]


@pytest.mark.parametrize("amplitude", [0.03, 0.2])
def test_drift_is_bounded_by_its_amplitude(amplitude: float) -> None:
    scn = scenario(1, drift_amplitude=amplitude, drift_wavelength=20.0, jitter_lateral=0.0)
    _, _, d = residual(scn)
    assert np.abs(d).max() <= amplitude + 1e-9
    assert np.abs(d).max() > 0.5 * amplitude  # and it does use the room it has
    assert np.std(d) > 0.2 * amplitude


def test_drift_is_smooth_along_the_row() -> None:
    scn = scenario(2, drift_amplitude=0.1, drift_wavelength=20.0, jitter_lateral=0.0)
    row, t, d = residual(scn)
    r0 = row == row.min()
    order = np.argsort(t[r0])
    tt, dd = t[r0][order], d[r0][order]
    # the slope is bounded by the shortest harmonic: |d'| <= 2π A / λ · Σ k w_k / Σ w_k
    slope = np.abs(np.diff(dd) / np.diff(tt))
    assert slope.max() <= 2 * np.pi * 0.1 / 20.0 * 3 / (1 + 1 / 2 + 1 / 3) + 1e-9


def test_drift_is_seeded_from_the_scenario() -> None:
    kw = {"drift_amplitude": 0.05, "jitter_lateral": 0.0}
    a, b, c = scenario(3, **kw), scenario(3, **kw), scenario(4, **kw)
    assert np.array_equal(a.plants.x, b.plants.x) and np.array_equal(a.plants.y, b.plants.y)
    da, dc = residual(a)[2], residual(c)[2]
    assert not np.array_equal(da[: len(dc)], dc[: len(da)])


def test_zero_drift_changes_nothing() -> None:
    base = scenario(5)
    same = scenario(5, drift_wavelength=123.0, drift_pass_rows=6)  # amplitude 0: no draws
    for name in ("x", "y", "z", "height", "yaw", "row"):
        assert np.array_equal(getattr(base.plants, name), getattr(same.plants, name))
    assert np.array_equal(base.route.xyz, same.route.xyz)
    # the drift stream was appended: the other streams are the seeds they always were
    old = np.random.SeedSequence(5).spawn(len(STREAMS) - 1)
    new = streams(5)
    for name, seq in zip(STREAMS[:-1], old, strict=True):
        assert new[name].random() == np.random.default_rng(seq).random()


def test_route_and_rows_stay_the_logged_lines() -> None:
    base = scenario(6)
    drifted = scenario(6, drift_amplitude=0.1)
    assert np.array_equal(base.rows.offsets, drifted.rows.offsets)
    assert np.array_equal(base.route.xyz, drifted.route.xyz)
    assert np.array_equal(base.lanes, drifted.lanes)
    # the plants are where the drift put them, the weeds and the rest where they were
    assert not np.array_equal(base.plants.y, drifted.plants.y)


def test_a_planter_pass_drifts_together() -> None:
    scn = scenario(
        7, drift_amplitude=0.1, drift_pass_rows=4, jitter_lateral=0.0, jitter_longitudinal=0.0
    )
    row, t, d = residual(scn)
    # plants at the same along-row position: equal drift within a pass, not across passes
    same_t = np.round(t, 6)
    common = set(same_t[row == 0]) & set(same_t[row == 3]) & set(same_t[row == 4])
    probe = sorted(common)[len(common) // 2]
    at = {r: float(d[(row == r) & (same_t == probe)][0]) for r in (0, 1, 2, 3, 4)}
    assert at[0] == pytest.approx(at[1]) == pytest.approx(at[2]) == pytest.approx(at[3])
    assert abs(at[4] - at[3]) > 1e-6


def test_drift_beyond_half_a_row_is_refused() -> None:
    with pytest.raises(InputError, match="layout.drift_amplitude"):
        sg.generate(sg.preset("default", layout={"row_spacing": 0.76, "drift_amplitude": 0.36}), 0)
    with pytest.raises(InputError, match="layout.drift_amplitude"):
        scenario(0, drift_amplitude=0.48, jitter_lateral=0.01)


def test_a_drifted_scenario_saves_and_loads_with_its_drift(tmp_path: Path) -> None:
    scn = scenario(8, drift_amplitude=0.08, drift_pass_rows=2)
    save(scn, tmp_path / "out")
    back = load(tmp_path / "out")
    assert back.spec.layout.drift_amplitude == 0.08 and back.spec.layout.drift_pass_rows == 2
    # the plant file keeps micrometres
    assert np.allclose(back.plants.x, scn.plants.x, rtol=0, atol=1e-6)
    assert np.allclose(back.plants.y, scn.plants.y, rtol=0, atol=1e-6)
    assert np.array_equal(back.plants.row, scn.plants.row)
    assert np.array_equal(back.rows.offsets, scn.rows.offsets)


@pytest.mark.parametrize("geometry", ["straight", "curved"])
def test_the_planted_rows_are_recovered_from_the_scenario(geometry: str, tmp_path: Path) -> None:
    kw = {"drift_amplitude": 0.15, "drift_pass_rows": 2, "jitter_lateral": 0.0}
    if geometry == "curved":
        kw |= {"row_geometry": "curved", "curve_radius": [20.0, 30.0]}
    scn = scenario(9, **kw)
    row, t, _ = residual(scn)
    _, s = scn.rows.to_rows(scn.plants.x[scn.plants.row >= 0], scn.plants.y[scn.plants.row >= 0])
    # every crop plant stands where the drift put its row (no lateral jitter here), and a
    # saved and loaded scenario gives the same phases
    phases = planting_drift(scn)
    assert np.allclose(planted_offset(scn.rows, phases, scn.spec.layout, row, t), s, atol=1e-9)
    save(scn, tmp_path / "out")
    assert np.array_equal(planting_drift(load(tmp_path / "out")), phases)


def test_lane_error_is_measured_from_the_planted_lane_centre() -> None:
    scn = scenario(10, drift_amplitude=0.2, drift_pass_rows=1, jitter_lateral=0.0)
    rows, spec, phases = scn.rows, scn.spec.layout, planting_drift(scn)
    k = np.array([1, 1, 1])
    t = np.full(3, 0.5 * (rows.starts[1] + rows.ends[1]))
    left, right = (planted_offset(rows, phases, spec, k + j, t) for j in (0, 1))
    centre = 0.5 * (left + right)
    # rows 1 and 2 are two passes: their drifts differ, and the lane centre moves with both
    assert abs(centre[0] - 0.5 * (rows.offsets[1] + rows.offsets[2])) > 1e-3
    x, y = rows.to_enu(t, centre + np.array([0.0, 0.1, -0.05]))
    err, inside = lane_error(rows, phases, spec, x, y)
    assert inside.all()
    assert err == pytest.approx([0.0, 0.1, -0.05], abs=1e-9)
    # beyond the outer rows and past the rows' ends there is no lane: NaN, not a number
    out_x, out_y = rows.to_enu(
        np.array([t[0], t[0], rows.ends[1] + 3.0]),
        np.array([rows.offsets[0] - 0.3, rows.offsets[-1] + 0.3, centre[0]]),
    )
    err, inside = lane_error(rows, phases, spec, out_x, out_y)
    assert not inside.any() and np.isnan(err).all()


def test_without_drift_the_lane_centre_is_the_logged_centreline() -> None:
    scn = scenario(11)
    rows = scn.rows
    t = np.linspace(rows.starts[2] + 0.1, rows.ends[2] - 0.1, 7)
    mid = 0.5 * (rows.offsets[2] + rows.offsets[3])
    x, y = rows.to_enu(t, np.full(7, mid + 0.07))
    err, inside = lane_error(rows, planting_drift(scn), scn.spec.layout, x, y)
    assert inside.all() and err == pytest.approx(np.full(7, 0.07), abs=1e-9)
