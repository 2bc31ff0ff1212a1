"""Holes and MultiPolygon gaps: lanes end at them, the route crosses them as headland, the
preview draws them."""

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon

from scenario_gen import generate
from scenario_gen.geodesy import GeoFrame
from scenario_gen.preview import preview_figure

from .helpers import plane

LAT, LON = 42.03, -93.6  # the plane is centred on the field's centroid


def _geojson(tmp_path: Path, geom: Polygon | MultiPolygon) -> str:
    """``geom`` given in metres around (LAT, LON), written as lon/lat GeoJSON."""
    geo = GeoFrame(LAT, LON, 0.0)

    def tx(xy: np.ndarray) -> np.ndarray:
        lat, lon, _ = geo.enu_to_geodetic(xy[:, 0], xy[:, 1])
        return np.column_stack([lon, lat])

    p = tmp_path / "field.geojson"
    p.write_text(json.dumps(shapely.geometry.mapping(shapely.transform(geom, tx))))
    return str(p)


def _spec(path: str, lanes: int):
    return plane(
        field={"geojson": path},
        layout={
            "row_angle_deg": 0.0,
            "gap_prob": 0.0,
            "jitter_lateral": 0.0,
            "jitter_longitudinal": 0.0,
            "headland": 1.0,
            "edge_margin": 0.3,
        },
        route={"lanes": lanes},
        terrain={"margin": 5.0},
    )


@pytest.fixture(scope="module")
def holed(tmp_path_factory: pytest.TempPathFactory):
    # 30 x 16 m field, rows along x; a 4 x 6 m hole across the middle lanes
    outer = [(-15, -8), (15, -8), (15, 8), (-15, 8)]
    hole = [(-2, -3), (2, -3), (2, 3), (-2, 3)]
    path = _geojson(tmp_path_factory.mktemp("holed"), Polygon(outer, [hole]))
    return generate(_spec(path, lanes=4), seed=0)


def _hole(scn) -> Polygon:
    return Polygon(scn.field.interiors[0])


def test_furrow_waypoints_never_cross_a_hole(holed) -> None:
    r = holed.route
    furrow = r.segment == "furrow"
    hole = _hole(holed)
    assert not shapely.intersects_xy(hole, r.xy[furrow, 0], r.xy[furrow, 1]).any()
    # ... the route does cross it, as headland, in the middle lanes
    inside = shapely.contains_xy(hole, r.xy[:, 0], r.xy[:, 1])
    assert inside.any() and (r.segment[inside] == "headland").all()
    assert (r.lane[inside] == -1).all()


def test_furrow_waypoints_have_crop_on_both_sides(holed) -> None:
    r, p = holed.route, holed.plants
    furrow = r.segment == "furrow"
    t, _s = holed.rows.to_rows(r.xy[furrow, 0], r.xy[furrow, 1])
    tp, _ = holed.rows.to_rows(p.x, p.y)
    for k in np.unique(r.lane[furrow]):
        on = r.lane[furrow] == k
        for row in (k, k + 1):
            along = np.sort(tp[p.row == row])
            gap = np.abs(t[on][:, None] - along[None, :]).min(axis=1)
            assert gap.max() <= 0.5 * holed.spec.layout.plant_spacing + 1e-9


def test_lanes_end_at_the_hole_and_say_which_centreline(holed) -> None:
    lanes, which = holed.lanes, holed.lane_centreline
    assert len(lanes) == len(which)
    hole = _hole(holed)
    for (a, b), _k in zip(lanes, which, strict=True):
        line = LineString([a, b])
        assert holed.field.contains(line), (a, b)
        assert not line.intersects(hole)
    # the centrelines the hole cuts appear twice, one stretch each side
    counts = np.bincount(which)
    assert counts.max() == 2 and counts.min() == 1
    _, s_hole = holed.rows.to_rows(*np.asarray(hole.exterior.coords).T)
    cut = np.flatnonzero(counts == 2)
    s_cut = 0.5 * (holed.rows.offsets[cut] + holed.rows.offsets[cut + 1])
    margin = holed.spec.layout.edge_margin + holed.rows.spacing
    assert (s_cut > s_hole.min() - margin).all() and (s_cut < s_hole.max() + margin).all()


def test_a_gap_between_parts_is_crossed_as_headland(tmp_path: Path) -> None:
    # two parcels along the rows, 6 m apart (a farm track between them)
    a = Polygon([(-17, -6), (-3, -6), (-3, 6), (-17, 6)])
    b = Polygon([(3, -6), (17, -6), (17, 6), (3, 6)])
    scn = generate(_spec(_geojson(tmp_path, MultiPolygon([a, b])), lanes=3), seed=0)
    r = scn.route
    gap = Polygon([(-3, -6), (3, -6), (3, 6), (-3, 6)])
    inside = shapely.contains_xy(gap, r.xy[:, 0], r.xy[:, 1])
    assert inside.sum() > 3 * 50  # three lanes cross 6 m at 5 cm spacing
    assert (r.segment[inside] == "headland").all()
    assert len(scn.lanes) == 2 * len(np.unique(scn.lane_centreline))


def test_parts_side_by_side_get_no_lane_between_them(tmp_path: Path) -> None:
    # two parcels across the rows, 5 m apart: no lane (and no furrow) in the strip between
    a = Polygon([(-12, -12), (12, -12), (12, -2.5), (-12, -2.5)])
    b = Polygon([(-12, 2.5), (12, 2.5), (12, 12), (-12, 12)])
    scn = generate(_spec(_geojson(tmp_path, MultiPolygon([a, b])), lanes=2), seed=0)
    strip = Polygon([(-12, -2.5), (12, -2.5), (12, 2.5), (-12, 2.5)])
    for a_, b_ in scn.lanes:
        assert not LineString([a_, b_]).intersects(strip.buffer(-0.01))
    offsets = scn.rows.offsets
    assert (np.diff(offsets) > 4.0).sum() == 1  # the rows jump the strip ...
    assert len(np.unique(scn.lane_centreline)) == len(offsets) - 2  # ... with no lane there


def test_simple_field_lanes_are_one_per_centreline_from_row_start_to_row_end() -> None:
    scn = generate(plane(layout={"gap_prob": 0.0}, route={"lanes": 3}), seed=0)
    rows = scn.rows
    assert np.array_equal(scn.lane_centreline, np.arange(len(rows.offsets) - 1))
    t0 = np.maximum(rows.starts[:-1], rows.starts[1:])
    t1 = np.minimum(rows.ends[:-1], rows.ends[1:])
    s = 0.5 * (rows.offsets[:-1] + rows.offsets[1:])
    x0, y0 = rows.to_enu(t0, s)
    x1, y1 = rows.to_enu(t1, s)
    np.testing.assert_array_equal(scn.lanes[:, 0], np.column_stack([x0, y0]))
    np.testing.assert_array_equal(scn.lanes[:, 1], np.column_stack([x1, y1]))


def test_preview_draws_holes_and_every_part(holed, tmp_path: Path) -> None:
    fig = preview_figure(holed)
    ax = fig.axes[0]
    hatched = [p for p in ax.patches if p.get_hatch()]
    assert len(hatched) == len(holed.field.interiors) == 1
    hole_xy = np.asarray(hatched[0].get_xy())
    assert Polygon(hole_xy).equals_exact(_hole(holed), 1e-6)
    a = Polygon([(-17, -6), (-3, -6), (-3, 6), (-17, 6)])
    b = Polygon([(3, -6), (17, -6), (17, 6), (3, 6)])
    two = generate(_spec(_geojson(tmp_path, MultiPolygon([a, b])), lanes=1), seed=0)
    outlines = [ln for ln in preview_figure(two).axes[0].lines if ln.get_color() == "white"]
    assert len([ln for ln in outlines if len(ln.get_xdata()) == 5]) == 2  # both parts


def test_field_geojson_rings_run_as_rfc_7946_says_whichever_way_the_input_ran(
    tmp_path: Path,
) -> None:
    """A clockwise shell (or a counter-clockwise hole) was written as given: tools that go by
    the ring's direction got a negative area or drew the field inside out."""
    from pyproj import Geod

    from scenario_gen.geojson import field_features

    outer = [(-15, -8), (-15, 8), (15, 8), (15, -8)]  # clockwise
    hole = [(-2, -3), (2, -3), (2, 3), (-2, 3)]  # counter-clockwise, as a shell runs
    scn = generate(_spec(_geojson(tmp_path, Polygon(outer, [hole])), lanes=2), seed=0)
    (feature,) = field_features(scn)
    ring, inner = feature["geometry"]["coordinates"]
    assert shapely.is_ccw(LineString(ring)) and not shapely.is_ccw(LineString(inner))
    area = Geod(ellps="WGS84").geometry_area_perimeter(shapely.geometry.shape(feature["geometry"]))[
        0
    ]
    assert area == pytest.approx(30 * 16 - 4 * 6, rel=1e-3)


def test_a_field_just_under_the_least_area_reads_under_it(tmp_path: Path) -> None:
    """3.997 m² was refused as "got '4.00 m²'; allowed: at least 4.0 m²"."""
    from scenario_gen.errors import InputError
    from scenario_gen.field import MIN_FIELD_AREA, check_field

    side = (MIN_FIELD_AREA - 0.003) ** 0.5
    with pytest.raises(InputError, match=r"got '3\.997 m²'; is too small"):
        check_field(shapely.box(0, 0, side, side), "field.geojson")
