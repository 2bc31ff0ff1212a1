import numpy as np
import pytest
import shapely

from scenario_gen import generate

from .helpers import plane


@pytest.fixture(scope="module")
def scn():
    return generate(
        plane(route={"lanes": 3}, layout={"row_angle_deg": 30.0}, field={"angle_deg": 30.0}), seed=0
    )


def test_waypoints_are_at_most_10cm_apart_and_tagged(scn) -> None:
    r = scn.route
    step = np.linalg.norm(np.diff(r.xy, axis=0), axis=1)
    assert step.max() <= 0.1 + 1e-9 and step.min() > 0
    assert set(np.unique(r.segment)) == {"furrow", "headland"}
    assert r.segment[0] == "headland" and r.segment[-1] == "headland"


def test_furrow_waypoints_lie_on_lane_centrelines(scn) -> None:
    r = scn.route
    furrow = r.segment == "furrow"
    t, s = scn.rows.to_rows(r.xy[furrow, 0], r.xy[furrow, 1])
    lane = r.lane[furrow]
    centre = 0.5 * (scn.rows.offsets[lane] + scn.rows.offsets[lane + 1])
    np.testing.assert_allclose(s, centre, atol=1e-9)
    assert sorted(set(lane.tolist())) == [lane[0], lane[0] + 1, lane[0] + 2]
    # consecutive lanes are driven in opposite directions
    directions = [np.sign(np.diff(t[lane == k]).mean()) for k in sorted(set(lane.tolist()))]
    assert directions == [1.0, -1.0, 1.0]


def test_headland_turns_stay_out_of_the_crop(scn) -> None:
    r = scn.route
    head = r.segment == "headland"
    from scenario_gen.layout import planting_area

    area = planting_area(scn.field, scn.spec.layout, scn.rows.angle)
    assert not shapely.contains_xy(area.buffer(-0.05), r.xy[head, 0], r.xy[head, 1]).any()
    crops = ~scn.plants.is_weed
    tree_d = np.min(
        np.hypot(
            r.xy[head, None, 0] - scn.plants.x[None, crops],
            r.xy[head, None, 1] - scn.plants.y[None, crops],
        ),
        axis=1,
    )
    assert tree_d.min() > 0.3  # a U-turn never runs over a plant


def test_route_follows_terrain(scn) -> None:
    r = scn.route
    np.testing.assert_allclose(r.xyz[:, 2], scn.terrain.height_at(r.xy[:, 0], r.xy[:, 1]))


def test_lane_lines_sit_midway_between_rows(scn) -> None:
    lanes = scn.lanes
    assert len(lanes) == len(scn.rows.offsets) - 1
    _, s = scn.rows.to_rows(lanes[:, 0, 0], lanes[:, 0, 1])
    np.testing.assert_allclose(s, 0.5 * (scn.rows.offsets[:-1] + scn.rows.offsets[1:]))
