"""The env's routes on curved rows and through a reversing turn (no simulator needed)."""

from __future__ import annotations

import math

import numpy as np

from agrinav_gym.routes import CUSP_REACH, Tracker, lane_route, scenario_route
from scenario_gen import generate, preset


def test_furrow_follow_lane_follows_curved_rows() -> None:
    spec = preset(
        "default",
        field={"width": 10.0, "length": 14.0},
        layout={"headland": 2.0, "row_geometry": "curved", "curve_radius": [15.0, 15.0]},
        terrain={"margin": 4.0},
    )
    scn = generate(spec, seed=1)
    path = lane_route(scn, 1, lead=1.0)
    rows = scn.rows
    _, s = rows.to_rows(path.xy[:, 0], path.xy[:, 1])
    np.testing.assert_allclose(s, 0.5 * (rows.offsets[1] + rows.offsets[2]), atol=1e-6)
    assert np.hypot(*np.diff(path.xy, axis=0).T).max() <= 0.05 + 1e-9
    lead = path.arc[np.argmax(path.furrow)]
    assert lead == path.arc[path.furrow][0] and abs(lead - 1.0) < 0.06
    # it curves: the heading turns by the lane's length over its radius
    turned = abs(np.unwrap(path.heading)[-2] - path.heading[0])
    assert turned > 0.2


def test_reversing_legs_face_against_the_direction_of_travel() -> None:
    scn = generate(preset("hillside", route={"turn": "three_point"}), seed=0)
    path = scenario_route(scn)
    assert path.reverse is not None
    back = np.flatnonzero(path.reverse[:-1])
    assert len(back) > 0
    d = np.diff(path.xy, axis=0)
    travel = np.arctan2(d[:, 1], d[:, 0])
    assert (np.cos(path.heading[back] - travel[back]) < -0.99).all()
    fwd = np.flatnonzero(~path.reverse[:-1])
    assert (np.cos(path.heading[fwd] - travel[fwd]) > 0.99).all()
    # the tracker follows the route through the cusps: the legs overlap there, so it may read
    # up to twice CUSP_REACH ahead at a cusp, never more, and never falls back onto the lane
    # it came along
    tr = Tracker(path)
    tr.reset(*path.xy[0])
    arcs = np.array([tr.update(*p)[1] for p in path.xy[::2]])
    assert np.diff(arcs).min() >= -2 * CUSP_REACH
    np.testing.assert_allclose(arcs, path.arc[::2], atol=2 * CUSP_REACH)
    assert math.isclose(arcs[-1], path.arc[::2][-1])
