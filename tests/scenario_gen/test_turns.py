"""Headland turns by type: geometry, the robot's swept footprint, tags, the headland they need."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from scenario_gen import InputError, generate, preset
from scenario_gen.turns import TURN_TYPES, canonical_turn

from .helpers import small

SIZED = ("omega", "keyhole", "three_point")


def _menger(xy: np.ndarray) -> np.ndarray:
    a, b, c = xy[:-2], xy[1:-1], xy[2:]
    ab, bc, ca = (np.hypot(*(q - p).T) for p, q in ((a, b), (b, c), (c, a)))
    cross = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    return 2 * np.abs(cross) / np.maximum(ab * bc * ca, 1e-300)


def _cusps(xy: np.ndarray) -> np.ndarray:
    """Indices where the path doubles back (consecutive steps point apart)."""
    d = np.diff(xy, axis=0)
    return np.flatnonzero(np.einsum("ij,ij->i", d[1:], d[:-1]) < 0) + 1


@pytest.mark.parametrize("kind", TURN_TYPES)
@pytest.mark.parametrize(("w", "radius"), [(1.0, 0.9), (0.76, 0.9), (0.75, 2.0), (1.0, 0.4)])
def test_turns_join_the_lanes_within_the_turning_radius(kind, w, radius) -> None:
    tp = canonical_turn(kind, w, radius, 0.05)
    np.testing.assert_allclose(tp.xy[0], [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(tp.xy[-1], [0.0, w], atol=1e-9)
    assert math.cos(tp.yaw[0]) == pytest.approx(1.0) and math.cos(tp.yaw[-1]) == pytest.approx(-1)
    assert np.hypot(*np.diff(tp.xy, axis=0).T).max() <= 0.05 + 1e-12
    cusps = _cusps(tp.xy)
    np.testing.assert_array_equal(cusps, tp.cusps)
    reverses = kind == "three_point" and w < 2 * radius
    assert len(cusps) == (2 if reverses else 0)
    assert (tp.direction[:-1] < 0).any() == reverses
    kappa = _menger(tp.xy)
    keep = ~np.isin(np.arange(1, len(tp.xy) - 1), cusps)
    limit = 2.0 / w if kind == "semicircle" else 1.0 / radius
    assert kappa[keep].max() <= limit * (1 + 1e-9)
    # facing: along the travel forwards, against it backwards
    travel = np.arctan2(*np.diff(tp.xy, axis=0).T[::-1])
    assert (np.cos(travel - tp.yaw[:-1]) * tp.direction[:-1] > 0.99).all()


def _turn_poses(scn) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each turn of the route as (points, facing yaw) densified to 1 cm, from the route alone:
    the facing is the direction of travel, turned round where the route reverses."""
    r = scn.route
    on = r.turn != ""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(int), [0]])))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        xy, dirs = r.xy[a:b], r.direction[a:b]
        pts, yaw = [], []
        for i in range(len(xy) - 1):
            d = xy[i + 1] - xy[i]
            n = max(2, math.ceil(np.hypot(*d) / 0.01) + 1)
            f = np.linspace(0.0, 1.0, n)[:-1, None]
            pts.append(xy[i] + f * d)
            h = math.atan2(d[1], d[0]) + (math.pi if dirs[i] < 0 else 0.0)
            yaw.append(np.full(n - 1, h))
        out.append((np.concatenate(pts), np.concatenate(yaw)))
    return out


def _swept(pts: np.ndarray, yaw: np.ndarray, length: float, width: float):
    hl, hw = 0.5 * length, 0.5 * width
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x = pts[:, :1] + c * local[:, 0] - s * local[:, 1]
    y = pts[:, 1:2] + s * local[:, 0] + c * local[:, 1]
    return shapely.union_all(shapely.polygons(np.stack([x, y], -1)))


CASES = [
    ("hillside", {}),
    ("narrow-rows", {"layout": {"headland": 5.0}}),
    # curved rows end staggered and a turn starts past the longest of them: a wider headland
    (
        "hillside",
        {"layout": {"row_geometry": "curved", "curve_radius": [15.0, 15.0], "headland": 5.0}},
    ),
]


@pytest.mark.parametrize("kind", SIZED)
@pytest.mark.parametrize(("name", "over"), CASES)
def test_the_swept_footprint_clears_every_plant(kind, name, over) -> None:
    spec = preset(name, **over).replace({"route.turn": kind, "route.lanes": 3})
    scn = generate(spec, seed=5)
    length, width = spec.route.footprint
    crop = ~scn.plants.is_weed
    plants = shapely.points(scn.plants.x[crop], scn.plants.y[crop])
    turns = _turn_poses(scn)
    assert len(turns) == 2
    for pts, yaw in turns:
        swept = _swept(pts, yaw, length, width)
        # the clearance, less what 5 cm between waypoints lets a corner cut (< 5 cm)
        assert shapely.distance(swept, plants).min() >= 0.5 * spec.route.turn_clearance
        assert shapely.contains(scn.field, swept)  # inside the field: in its headland band


@pytest.mark.parametrize("kind", SIZED)
def test_route_turns_keep_the_radius_except_at_declared_cusps(kind) -> None:
    spec = preset("hillside", route={"turn": kind, "lanes": 3})
    scn = generate(spec, seed=2)
    r = scn.route
    on = np.flatnonzero(r.turn == kind)
    assert (r.segment[on] == "headland").all() and (r.lane[on] == -1).all()
    xy = r.xy[on[0] : on[-1] + 1]
    declared = np.flatnonzero(np.diff(r.direction[on[0] : on[-1] + 1]) != 0) + 1
    cusps = _cusps(xy)  # where the path itself doubles back
    np.testing.assert_array_equal(cusps, declared)
    keep = ~np.isin(np.arange(1, len(xy) - 1), cusps)
    assert _menger(xy)[keep].max() <= (1 + 1e-6) / spec.route.turn_radius
    assert ((r.direction < 0).any()) == (kind == "three_point")
    assert (r.turn[r.direction < 0] == "three_point").all()


def test_semicircle_turns_are_tagged_and_unchanged_in_shape() -> None:
    scn = generate(small(), seed=1)
    r = scn.route
    on = r.turn == "semicircle"
    assert on.any() and (r.direction == 1).all()
    xy = r.xy[on]
    # half a circle of the lane spacing's diameter
    centre = 0.5 * (xy[0] + xy[-1])
    np.testing.assert_allclose(np.hypot(*(xy - centre).T), 0.5 * scn.rows.spacing, atol=1e-9)


def test_a_turn_that_does_not_fit_the_headland_is_refused() -> None:
    spec = preset("hillside", layout={"headland": 2.0}, route={"turn": "keyhole"})
    with pytest.raises(InputError, match="route.turn.*headland"):
        generate(spec, seed=0)


def test_turns_start_where_the_footprint_clears_the_crop() -> None:
    spec = preset("hillside", route={"turn": "omega", "turn_offset": 0.0})
    scn = generate(spec, seed=3)
    r = scn.route
    start = np.flatnonzero(r.turn == "omega")[0]
    crop = ~scn.plants.is_weed
    d = np.hypot(scn.plants.x[crop] - r.xy[start, 0], scn.plants.y[crop] - r.xy[start, 1])
    # at least half the footprint's length plus the clearance from the nearest plant
    assert d.min() >= 0.5 * spec.route.footprint[0] + spec.route.turn_clearance - 1e-9


@pytest.mark.parametrize("kind", ["semicircle", "keyhole"])
def test_turns_start_past_every_plant_of_the_rows_beside_both_lanes(kind) -> None:
    # curved rows end staggered: a lane ends where the first of its two rows does and the other
    # row goes on; the turn must be laid past the last plant of either, not past the lane's end
    spec = preset(
        "hillside",
        layout={"row_geometry": "curved", "curve_radius": [15.0, 15.0], "headland": 5.0},
        route={"turn": kind, "lanes": 3, "turn_offset": 0.3},
    )
    scn = generate(spec, seed=5)
    r, rows = scn.route, scn.rows
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (r.turn != "").astype(int), [0]])))
    crop = ~scn.plants.is_weed
    tp, sp = rows.to_rows(scn.plants.x[crop], scn.plants.y[crop])
    stagger = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        (t0, _t1), (s0, s1) = rows.to_rows(r.xy[[a, b - 1], 0], r.xy[[a, b - 1], 1])
        (tb,), _ = rows.to_rows(r.xy[[a - 20], 0], r.xy[[a - 20], 1])
        d = np.sign(t0 - tb)
        lo, hi = min(s0, s1) - 0.5 * rows.spacing, max(s0, s1) + 0.5 * rows.spacing
        beside = (sp > lo - 0.1) & (sp < hi + 0.1)  # the three rows, within lateral jitter
        # turn_offset (0.3 m) past the last of them, less along-row jitter: still past all
        assert (d * (tp[beside] - t0)).max() < 0
        near = beside & (np.abs(tp - t0) < 5.0)
        rows_here = [near & (np.abs(sp - o) < 0.1) for o in rows.offsets]
        stagger.append(np.ptp([np.max(d * tp[m]) for m in rows_here if m.any()]))
    assert max(stagger) > 0.3  # the case in question: the rows end at different places
