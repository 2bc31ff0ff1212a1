"""Curved and contour rows: spacing along the normal, radius, level rows, lanes, files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely

from scenario_gen import InputError, generate, load, preset, save
from scenario_gen.routes import centreline

from .helpers import plane, small


def _menger(xy: np.ndarray) -> np.ndarray:
    """Curvature of the circle through each three consecutive points (1/m)."""
    a, b, c = xy[:-2], xy[1:-1], xy[2:]
    ab, bc, ca = (np.hypot(*(q - p).T) for p, q in ((a, b), (b, c), (c, a)))
    cross = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    return 2 * np.abs(cross) / np.maximum(ab * bc * ca, 1e-300)


@pytest.fixture(scope="module")
def curved():
    spec = small(
        field={"width": 12.0, "length": 16.0},
        layout={"row_geometry": "curved", "curve_radius": [15.0, 15.0]},
        route={"lanes": 3},
    )
    return generate(spec, seed=4)


@pytest.fixture(scope="module")
def contour():
    spec = preset(
        "hillside",
        field={"width": 40.0, "length": 40.0},
        layout={"row_geometry": "contour"},
        furrows={"roughness": 0.0},
    )
    return generate(spec, seed=1)


@pytest.mark.parametrize("which", ["curved", "contour"])
def test_neighbouring_rows_are_one_row_spacing_apart_along_the_normal(which, request) -> None:
    scn = request.getfixturevalue(which)
    rows, lay = scn.rows, scn.spec.layout
    crop = ~scn.plants.is_weed
    px, py, prow = scn.plants.x[crop], scn.plants.y[crop], scn.plants.row[crop]
    tol = 3 * lay.jitter_lateral + 1e-3  # jitter is clipped at 3 std; 1 mm for the polyline
    checked = 0
    for k in range(len(rows.offsets) - 1):
        t0, t1 = float(rows.starts[k + 1]), float(rows.ends[k + 1])
        if t1 - t0 < 3.0:
            continue
        line = shapely.LineString(centreline(rows, t0, t1, float(rows.offsets[k + 1]), 0.05))
        mine = prow == k
        t, _ = rows.to_rows(px[mine], py[mine])
        inner = (t > t0 + 1.0) & (t < t1 - 1.0)  # the normal foot lies inside the next row
        d = shapely.distance(line, shapely.points(px[mine][inner], py[mine][inner]))
        assert np.abs(d - lay.row_spacing).max() <= tol, (k, np.abs(d - lay.row_spacing).max())
        checked += int(inner.sum())
    assert checked > 0.5 * crop.sum()


def test_curved_rows_are_arcs_no_tighter_than_the_radius(curved) -> None:
    rows = curved.rows
    assert rows.geometry == "curved"
    radii = []
    for k, s in enumerate(rows.offsets):
        pts = centreline(rows, float(rows.starts[k]), float(rows.ends[k]), float(s), 0.5)
        kappa = _menger(pts)
        # an arc: one radius along the row
        assert kappa.max() - kappa.min() < 1e-3 * kappa.max()
        radii.append(1.0 / kappa.mean())
    radii = np.array(radii)
    assert radii.min() >= 15.0 - 1e-3
    # concentric: neighbouring radii differ by the row spacing
    np.testing.assert_allclose(np.abs(np.diff(radii)), curved.spec.layout.row_spacing, atol=1e-3)


def test_plants_keep_the_plant_spacing_along_each_curved_row() -> None:
    spec = small(
        layout={
            "row_geometry": "curved",
            "curve_radius": [15.0, 15.0],
            "jitter_longitudinal": 0.0,
            "jitter_lateral": 0.0,
            "gap_prob": 0.0,
        }
    )
    scn = generate(spec, seed=2)
    p = scn.plants
    for k in range(len(scn.rows.offsets)):
        xy = np.column_stack([p.x, p.y])[p.row == k]
        step = np.hypot(*np.diff(xy, axis=0).T)
        # the chord of 0.18 m of a >= 15 m arc is shorter by < 1e-5 m
        np.testing.assert_allclose(step, spec.layout.plant_spacing, atol=1e-4)


def test_curved_radius_and_bend_are_drawn_per_seed_and_reproduced() -> None:
    spec = small(layout={"row_geometry": "curved", "curve_radius": [20.0, 200.0]})
    a, b = generate(spec, 3), generate(spec, 3)
    np.testing.assert_array_equal(a.plants.x, b.plants.x)
    np.testing.assert_array_equal(a.route.xyz, b.route.xyz)
    kappas = {float(np.round(generate(spec, s).rows.curve.kappa.mean(), 6)) for s in range(6)}
    assert len(kappas) == 6 and min(kappas) < 0 < max(kappas)  # radii differ, both bends


def test_contour_rows_stay_in_their_height_band(contour) -> None:
    """Within 20 m of the key line (the contour through the field centre) a contour row climbs
    less than the height step to its neighbour (row spacing × the slope across the rows): it
    stays in its own band. Straight rows along the field climb over twenty times more."""
    straight = generate(contour.spec.replace({"layout.row_geometry": "straight"}), 1)

    def climbs(scn, near: float) -> np.ndarray:
        rows, out = scn.rows, []
        for k, s in enumerate(rows.offsets):
            t0, t1 = float(rows.starts[k]), float(rows.ends[k])
            if t1 - t0 < 2.0 or abs(s) > near:
                continue
            pts = centreline(rows, t0, t1, float(s), 0.25)
            z = scn.terrain.height_at(pts[:, 0], pts[:, 1])
            t = np.linspace(t0, t1, 20)
            here = scn.terrain.height_at(*rows.to_enu(t, np.full(20, s)))
            nxt = scn.terrain.height_at(*rows.to_enu(t, np.full(20, s + rows.spacing)))
            out.append((np.ptp(z), np.abs(nxt - here).min()))
        return np.array(out)

    c = climbs(contour, 20.0)
    assert len(c) >= 30
    assert (c[:, 0] < c[:, 1]).all(), (c[:, 0] / c[:, 1]).max()
    s = climbs(straight, np.inf)
    assert np.median(s[:, 0]) > 20 * np.median(c[:, 0])


def test_contour_rows_are_refused_on_flat_ground() -> None:
    with pytest.raises(InputError, match="layout.row_geometry.*flat"):
        generate(plane(0.0, layout={"row_geometry": "contour"}), 0)
    scn = generate(plane(8.0, 60.0, layout={"row_geometry": "contour"}), 0)
    # on a plane the contours are straight lines across the slope (downhill 30° from east)
    assert np.abs(np.cos(scn.rows.curve.theta - np.radians(30.0))).max() < 1e-6
    assert np.ptp(scn.rows.curve.theta) < 1e-6


def test_curve_radius_low_above_high_is_refused() -> None:
    with pytest.raises(InputError, match="layout.curve_radius"):
        generate(small(layout={"row_geometry": "curved", "curve_radius": [50.0, 20.0]}), 0)
    with pytest.raises(InputError, match="layout.curve_radius"):
        small(layout={"curve_radius": [10.0, 20.0]})  # below 15 m


def test_the_route_follows_the_lanes_between_curved_rows(curved) -> None:
    rows, r = curved.rows, curved.route
    furrow = r.segment == "furrow"
    _, s = rows.to_rows(r.xy[furrow, 0], r.xy[furrow, 1])
    mid = 0.5 * (rows.offsets[r.lane[furrow]] + rows.offsets[r.lane[furrow] + 1])
    np.testing.assert_allclose(s, mid, atol=1e-6)
    # independently: a furrow waypoint is half a row spacing from both rows' lines
    crop = ~curved.plants.is_weed
    p = np.column_stack([curved.plants.x, curved.plants.y])[crop]
    d = np.min(np.hypot(*(r.xy[furrow][:, None, :] - p[None, ::5, :]).transpose(2, 0, 1)), 1)
    assert d.min() > 0.5 * curved.spec.layout.row_spacing - 3 * curved.spec.layout.jitter_lateral
    step = np.hypot(*np.diff(r.xy, axis=0).T)
    assert step.max() <= curved.spec.route.spacing + 1e-9


def test_curved_and_contour_scenarios_round_trip(curved, tmp_path: Path) -> None:
    save(curved, tmp_path / "c", preview=True)
    back = load(tmp_path / "c")
    assert back.rows.geometry == "curved"
    np.testing.assert_array_equal(back.rows.curve.xy, curved.rows.curve.xy)
    np.testing.assert_array_equal(back.lanes, curved.lanes)
    np.testing.assert_array_equal(back.route.lane, curved.route.lane)
    np.testing.assert_array_equal(back.plants.row, curved.plants.row)


def test_ridges_follow_curved_rows() -> None:
    spec = small(
        layout={"row_geometry": "curved", "curve_radius": [15.0, 15.0]},
        furrows={"enabled": True, "roughness": 0.0},
        terrain={"source": "plane", "slope_deg": 0.0, "site": "flattest"},
    )
    scn = generate(spec, 0)
    rows = scn.rows
    # on a plane the ground is the relief alone: crest on the rows, trough mid-lane
    k = len(rows.offsets) // 2
    t = 0.5 * (rows.starts[k] + rows.ends[k]) + np.linspace(-2, 2, 9)
    on_row = scn.terrain.height_at(*rows.to_enu(t, np.full(9, rows.offsets[k])))
    mid = 0.5 * (rows.offsets[k] + rows.offsets[k + 1])
    in_lane = scn.terrain.height_at(*rows.to_enu(t, np.full(9, mid)))
    assert (on_row - in_lane > 0.8 * spec.furrows.depth).all()
