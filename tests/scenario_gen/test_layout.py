import math

import numpy as np
import pytest
import shapely

from scenario_gen import generate

from .helpers import plane, small


@pytest.mark.parametrize("angle", [0.0, 33.0, -75.0])
def test_all_plants_inside_the_field(angle: float) -> None:
    scn = generate(small(field={"angle_deg": angle}, layout={"weed_density": 2.0}), seed=3)
    assert len(scn.plants) > 500
    assert shapely.contains_xy(scn.field, scn.plants.x, scn.plants.y).all()


def test_plants_inside_concave_geojson_field_with_hole(tmp_path) -> None:
    from scenario_gen.geodesy import GeoFrame

    geo = GeoFrame(36.549167, -84.1425, 305.0)
    outer = [(-12, -10), (12, -10), (12, 10), (0, 2), (-12, 10)]  # a notch: concave
    hole = [(-3, -4), (3, -4), (3, -1), (-3, -1)]
    ring = [geo.enu_to_geodetic(x, y) for x, y in outer]
    inner = [geo.enu_to_geodetic(x, y) for x, y in hole]
    gj = {
        "type": "Feature",
        "properties": {},
        "geometry": {
            "type": "Polygon",
            "coordinates": [
                [[float(lon), float(lat)] for lat, lon, _ in ring + ring[:1]],
                [[float(lon), float(lat)] for lat, lon, _ in inner + inner[:1]],
            ],
        },
    }
    path = tmp_path / "field.geojson"
    import json

    path.write_text(json.dumps(gj))
    scn = generate(small(field={"geojson": str(path)}, layout={"row_angle_deg": 0.0}), seed=0)
    assert shapely.contains_xy(scn.field, scn.plants.x, scn.plants.y).all()
    assert len(scn.field.interiors) == 1  # the hole survived the lon/lat -> ENU transform
    hole_enu = shapely.Polygon(scn.field.interiors[0])
    assert hole_enu.area == pytest.approx(18.0, rel=1e-4)
    assert not shapely.intersects_xy(hole_enu, scn.plants.x, scn.plants.y).any()
    assert scn.field.area == pytest.approx(24 * 20 - 24 * 8 / 2 - 6 * 3, rel=0.01)


def test_row_and_plant_spacing_match_spec() -> None:
    spec = plane(
        layout={
            "row_spacing": 0.8,
            "plant_spacing": 0.25,
            "row_angle_deg": 20.0,
            "jitter_lateral": 0.0,
            "jitter_longitudinal": 0.0,
            "gap_prob": 0.0,
        }
    )
    scn = generate(spec, seed=0)
    t, s = scn.rows.to_rows(scn.plants.x, scn.plants.y)
    np.testing.assert_allclose(np.diff(scn.rows.offsets), 0.8, atol=1e-9)
    # every plant sits on its row line, and neighbours in a row are one plant spacing apart
    np.testing.assert_allclose(s, scn.rows.offsets[scn.plants.row], atol=1e-9)
    for r in range(len(scn.rows.offsets)):
        along = np.sort(t[scn.plants.row == r])
        np.testing.assert_allclose(np.diff(along), 0.25, atol=1e-9)


def test_spacing_with_jitter_is_spec_on_average() -> None:
    spec = plane(layout={"jitter_lateral": 0.03, "jitter_longitudinal": 0.03, "gap_prob": 0.0})
    scn = generate(spec, seed=5)
    t, s = scn.rows.to_rows(scn.plants.x, scn.plants.y)
    lateral = s - scn.rows.offsets[scn.plants.row]
    # std of a clipped (±3σ) normal is 0.986σ; 1,000+ samples pin it within ~5 %
    assert np.std(lateral) == pytest.approx(0.03 * 0.986, rel=0.08)
    assert np.abs(lateral).max() <= 3 * 0.03 + 1e-9
    d = [np.diff(np.sort(t[scn.plants.row == r])).mean() for r in range(len(scn.rows.offsets))]
    assert np.mean(d) == pytest.approx(0.18, rel=0.01)


@pytest.mark.parametrize("which", ["plant_spacing", "row_spacing"])
def test_doubling_spacing_halves_the_count(which: str) -> None:
    base = {"row_spacing": 1.0, "plant_spacing": 1.0, "gap_prob": 0.0}
    one = generate(plane(field={"width": 40.0, "length": 50.0}, layout=base), seed=0)
    two = generate(
        plane(field={"width": 40.0, "length": 50.0}, layout={**base, which: 2.0}), seed=0
    )
    assert len(two.plants) / len(one.plants) == pytest.approx(0.5, abs=0.025)


def test_paper_densities_scale_like_the_paper() -> None:
    from scenario_gen import preset

    counts = {
        n: int((~generate(preset(n), 0).plants.is_weed).sum())
        for n in ("paper-p1", "paper-p2", "paper-p3", "paper-p4")
    }
    assert 2000 <= counts["paper-p1"] <= 2400
    assert counts["paper-p2"] / counts["paper-p1"] == pytest.approx(1 / 2, rel=0.05)
    assert counts["paper-p3"] / counts["paper-p1"] == pytest.approx(1 / 4, rel=0.05)
    assert counts["paper-p4"] / counts["paper-p1"] == pytest.approx(1 / 6, rel=0.05)


def test_gap_probability_removes_that_fraction() -> None:
    full = generate(plane(layout={"gap_prob": 0.0}), seed=1)
    gappy = generate(plane(layout={"gap_prob": 0.2}), seed=1)
    n = len(full.plants)
    missing = 1 - len(gappy.plants) / n
    sigma = math.sqrt(0.2 * 0.8 / n)
    assert abs(missing - 0.2) < 4 * sigma


def test_gap_runs_remove_consecutive_plants_within_a_row() -> None:
    spec = plane(
        layout={
            "gap_prob": 0.0,
            "gap_run_prob": 0.02,
            "gap_run_mean": 6.0,
            "jitter_longitudinal": 0.0,
        }
    )
    scn = generate(spec, seed=2)
    t, _ = scn.rows.to_rows(scn.plants.x, scn.plants.y)
    runs = []
    for r in range(len(scn.rows.offsets)):
        along = np.sort(t[scn.plants.row == r])
        steps = np.round(np.diff(along) / 0.18).astype(int)
        runs += list(steps[steps > 1] - 1)
    assert len(runs) > 5
    assert np.mean(runs) > 3  # runs, not isolated singles (mean run 6, merged runs longer)


def test_weed_density() -> None:
    scn = generate(plane(layout={"weed_density": 3.0}), seed=4)
    from scenario_gen.layout import planting_area

    area = planting_area(scn.field, scn.spec.layout, scn.rows.angle).area
    n = int(scn.plants.is_weed.sum())
    assert abs(n - 3.0 * area) < 4 * math.sqrt(3.0 * area)
    assert (scn.plants.species[scn.plants.is_weed] == "weed").all()


# ----------------------------------------------------------------------------- counts
@pytest.mark.parametrize("rows,per_row", [(20, 50), (7, 12), (2, 2)])
def test_row_and_plant_counts_are_honoured_and_centred(rows: int, per_row: int) -> None:
    # the source paper's maizes.world: 20 rows x 50 plants, 0.75 x 0.18 m
    spec = plane(
        field={"width": 20.0, "length": 14.0, "angle_deg": 25.0},
        layout={
            "rows": rows,
            "plants_per_row": per_row,
            "row_spacing": 0.75,
            "plant_spacing": 0.18,
            "gap_prob": 0.0,
            "headland": 2.0,
        },
        route={"lanes": 1},
    )
    scn = generate(spec, seed=0)
    assert len(scn.rows.offsets) == rows
    assert np.bincount(scn.plants.row).tolist() == [per_row] * rows
    # centred on the field: row offsets and along-row positions symmetric about its centre
    c = scn.field.centroid
    t_c, s_c = scn.rows.to_rows(np.array([c.x]), np.array([c.y]))
    assert np.mean(scn.rows.offsets) == pytest.approx(s_c[0], abs=1e-9)
    assert 0.5 * (scn.rows.starts + scn.rows.ends) == pytest.approx(t_c[0], abs=1e-9)
    np.testing.assert_allclose(np.diff(scn.rows.offsets), 0.75, atol=1e-9)


@pytest.mark.parametrize(
    "layout,field,room",
    [
        ({"rows": 30}, "layout.rows", "at most 26"),
        ({"plants_per_row": 80}, "layout.plants_per_row", "at most 53"),
    ],
)
def test_counts_that_do_not_fit_say_how_many_do(layout: dict, field: str, room: str) -> None:
    from scenario_gen import ScenarioError

    # planting area 20 - 2 x 0.3 = 19.4 m across (26 rows at 0.75 m), 14 - 2 x 2 - 2 x 0.3 =
    # 9.4 m along (53 positions at 0.18 m)
    spec = plane(
        field={"width": 20.0, "length": 14.0},
        layout={"row_spacing": 0.75, "plant_spacing": 0.18, "headland": 2.0, **layout},
    )
    with pytest.raises(ScenarioError) as info:
        generate(spec, seed=0)
    assert info.value.field == field and room in str(info.value), str(info.value)
