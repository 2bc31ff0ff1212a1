"""Nav2 GPS waypoints in: through the datum to ENU and back, the plan through them, refusals."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from scenario_gen import generate
from scenario_gen.errors import InputError
from scenario_gen.waypoints import read_gps_waypoints, route_to_gps

from .helpers import small


def _write(path: Path, wps: list[dict]) -> Path:
    path.write_text(yaml.safe_dump({"waypoints": wps}))
    return path


@pytest.fixture(scope="module")
def field():  # type: ignore[no-untyped-def]
    return generate(small(), seed=0)


def _corners(scn) -> list[dict]:  # type: ignore[no-untyped-def]
    """Four waypoints of the seed robot's shape: a leg along a lane, a headland leg, back."""
    lanes = scn.lanes
    (a0, a1), (b0, b1) = lanes[0], lanes[1]
    pts = [a0, a1, b1, b0]
    lat, lon, _ = scn.geo.enu_to_geodetic(*np.asarray(pts).T, 0.0)
    return [
        {"latitude": float(la), "longitude": float(lo)} for la, lo in zip(lat, lon, strict=True)
    ]


def test_waypoints_round_trip_through_enu_within_a_millimetre(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    wps = _corners(field)
    path = _write(tmp_path / "wps.yaml", wps)
    scn = generate(small(route={"waypoints": str(path)}), seed=0)
    r = scn.route
    ll = route_to_gps(r, scn.geo)
    # the plan passes through every waypoint: each is one of its points, to < 1 mm, the one
    # info["route_goals"] names (the goals Nav2's waypoint follower sends one by one)
    goals = scn.info["route_goals"]
    assert len(goals) == len(wps) and goals[0] == 0 and goals[-1] == len(r.xy) - 1
    for wp, i in zip(wps, goals, strict=True):
        x, y, _ = scn.geo.geodetic_to_enu(wp["latitude"], wp["longitude"], 0.0)
        assert np.hypot(r.xy[:, 0] - x, r.xy[:, 1] - y).min() < 1e-3
        assert np.hypot(r.xy[i, 0] - x, r.xy[i, 1] - y) < 1e-3
    # and back to lat/lon: the first and last route points are the first and last waypoints
    for k, i in ((0, 0), (-1, -1)):
        x, y, _ = scn.geo.geodetic_to_enu(ll[i, 0], ll[i, 1], r.xyz[i, 2])
        assert np.hypot(x - r.xy[i, 0], y - r.xy[i, 1]) < 1e-3
        assert ll[i, 0] == pytest.approx(wps[k]["latitude"], abs=1e-8)
    steps = np.hypot(*np.diff(r.xy, axis=0).T)
    assert steps.max() <= scn.spec.route.spacing + 1e-9
    # the two legs along the lanes are furrow, the headland leg between them is not
    assert set(r.segment) == {"furrow", "headland"}
    assert (r.segment == "furrow").mean() > 0.7


def test_an_altitude_is_read_and_left_to_the_terrain(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    wps = _corners(field)
    plain = read_gps_waypoints(_write(tmp_path / "a.yaml", wps))
    high = read_gps_waypoints(_write(tmp_path / "b.yaml", [{**w, "altitude": 312.5} for w in wps]))
    assert np.array_equal(plain, high, equal_nan=True)


def test_an_exported_waypoint_file_reads_back(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path = _write(tmp_path / "w.yaml", [{**w, "yaw": 1.5} for w in _corners(field)])
    got = read_gps_waypoints(path)
    assert got.shape == (4, 3) and np.all(got[:, 2] == 1.5)


def test_a_waypoint_off_the_terrain_is_refused_by_number(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    wps = _corners(field)
    wps[2] = {"latitude": wps[2]["latitude"] + 0.01, "longitude": wps[2]["longitude"]}  # 1.1 km
    path = _write(tmp_path / "far.yaml", wps)
    with pytest.raises(InputError) as e:
        generate(small(route={"waypoints": str(path)}), seed=0)
    assert e.value.field == "route.waypoints waypoints[2]" and "off the terrain" in str(e.value)
    # it says where a site would hold them: the centre of their box
    found = re.search(r"terrain\.lat=([-\d.]+), terrain\.lon=([-\d.]+)", str(e.value))
    assert found is not None
    lat, lon = (float(v) for v in found.groups())
    lats, lons = [w["latitude"] for w in wps], [w["longitude"] for w in wps]
    assert lat == pytest.approx((min(lats) + max(lats)) / 2, abs=1e-6)
    assert lon == pytest.approx((min(lons) + max(lons)) / 2, abs=1e-6)


def test_waypoints_on_the_far_side_of_the_earth_are_refused_not_folded_in(
    field,
    tmp_path: Path,  # type: ignore[no-untyped-def]
) -> None:
    """East and north alone put a point where the datum's vertical leaves the far side of the
    Earth back inside the field: its distance is measured in three dimensions."""
    wps = _corners(field)
    anti = [{"latitude": -w["latitude"], "longitude": w["longitude"] + 180.0} for w in wps]
    path = _write(tmp_path / "anti.yaml", anti)
    with pytest.raises(InputError) as e:
        generate(small(route={"waypoints": str(path)}), seed=0)
    assert e.value.field == "route.waypoints waypoints[0]" and "12,7" in str(e.value)
    assert "within 100 km" in str(e.value)


def test_a_plane_gets_datum_advice_for_waypoints_far_from_it(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """terrain.site/lat/lon place a DEM's site: a plane is placed by its datum."""
    path = _write(tmp_path / "w.yaml", _corners(field))
    with pytest.raises(InputError) as e:
        generate(small(terrain={"source": "plane"}, route={"waypoints": str(path)}), seed=0)
    found = re.search(r"terrain\.datum=\[([-\d.]+), ([-\d.]+), ALT\]", str(e.value))
    assert found is not None and "terrain.site" not in str(e.value), str(e.value)
    lat, lon = (float(v) for v in found.groups())
    datum = [lat, lon, field.geo.alt]
    generate(small(terrain={"source": "plane", "datum": datum}, route={"waypoints": str(path)}), 0)


def test_waypoints_with_latitude_and_longitude_swapped_get_a_hint(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    wps = _corners(field)
    swapped = [{"latitude": w["longitude"], "longitude": w["latitude"]} for w in wps]
    with pytest.raises(InputError, match="latitude and longitude swapped") as hint:
        generate(small(route={"waypoints": str(_write(tmp_path / "s.yaml", swapped))}), seed=0)
    assert "terrain.site" not in str(hint.value)  # not also "move the site to Antarctica"
    # a waypoint merely far away gets no such hint
    far = [*wps[:2], {"latitude": wps[2]["latitude"] + 0.01, "longitude": wps[2]["longitude"]}]
    with pytest.raises(InputError) as e:
        generate(small(route={"waypoints": str(_write(tmp_path / "f.yaml", far))}), seed=0)
    assert "swapped" not in str(e.value)


@pytest.mark.parametrize(
    "content,needle",
    [
        ({"waypoints": [{"latitude": 36.5, "longitude": -84.1}]}, "list of 2-"),
        ({"points": []}, "'waypoints'"),
        (
            {"waypoints": [{"latitude": 91, "longitude": 0}, {"latitude": 0, "longitude": 0}]},
            "latitude",
        ),
        (
            {"waypoints": [{"latitude": "36", "longitude": 0}, {"latitude": 0, "longitude": 0}]},
            "latitude",
        ),
        (
            {"waypoints": [{"lat": 36, "lon": 0}, {"latitude": 0, "longitude": 0}]},
            "latitude and longitude",
        ),
        (
            {
                "waypoints": [
                    {"latitude": 0, "longitude": 0, "z": 1},
                    {"latitude": 0, "longitude": 0},
                ]
            },
            "unknown",
        ),
        (
            {
                "waypoints": [
                    {"latitude": 0, "longitude": 0, "altitude": "high"},
                    {"latitude": 0, "longitude": 0},
                ]
            },
            r"waypoints\[0\]\.altitude",
        ),
    ],
)
def test_bad_waypoint_files_name_the_entry(tmp_path: Path, content: dict, needle: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(content))
    with pytest.raises(InputError, match=needle):
        read_gps_waypoints(path)


def test_the_cli_reads_waypoints_and_scenario_json_regenerates_them(
    field,
    tmp_path: Path,  # type: ignore[no-untyped-def]
) -> None:
    from baselines.cli import main
    from scenario_gen import load

    path = _write(tmp_path / "wps.yaml", _corners(field))
    argv = ["scenario", "--preset", "default", "--waypoints", str(path), "--out"]
    argv += [str(tmp_path / "scn"), "--set", "field.width=10", "--set", "field.length=14"]
    argv += ["--set", "layout.headland=2", "--set", "terrain.margin=4", "--no-preview"]
    assert main(argv) == 0
    scn = load(tmp_path / "scn")
    assert scn.spec.route.waypoints == str(path.resolve())
    assert len(scn.route) == len(generate(scn.spec, scn.seed).route)


def test_on_curved_rows_a_leg_along_the_local_rows_is_furrow(tmp_path: Path) -> None:
    """Short legs following a curved lane run along the rows wherever they are, even where
    the rows have turned away from their direction at the field's centre."""
    curved = {"layout": {"row_geometry": "curved", "curve_radius": [15.0, 15.0]}}
    scn = generate(small(**curved), seed=0)
    lane = scn.route.xy[scn.route.segment == "furrow"]
    lane = lane[: np.flatnonzero(np.hypot(*np.diff(lane, axis=0).T) > 0.5)[0] + 1]  # lane 1
    pts = lane[:: max(1, len(lane) // 12)]  # legs of ≈ 1 m: chords within 2° of the arc
    turned = np.degrees(np.ptp(np.unwrap(scn.rows.direction_at(pts[:, 0], pts[:, 1]))))
    assert turned > 25  # more than twice the 10° a leg may differ from the rows
    lat, lon, _ = scn.geo.enu_to_geodetic(pts[:, 0], pts[:, 1], 0.0)
    wps = [{"latitude": float(a), "longitude": float(b)} for a, b in zip(lat, lon, strict=True)]
    path = _write(tmp_path / "curved.yaml", wps)
    r = generate(small(**curved, route={"waypoints": str(path)}), seed=0).route
    assert (r.segment == "furrow").mean() > 0.9


def test_a_waypoint_route_exports_its_waypoints_and_reads_back(field, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """``export --to nav2`` writes the file's own waypoints (not lane ends rebuilt from the
    route), each with the yaw the file gave or else its leaving leg's heading; reading the
    export back plans the same route."""
    from baselines.nav2_robot import nav2_options
    from scenario_gen import save
    from scenario_gen.export import ExportOptions, export

    wps = _corners(field)
    wps[0]["yaw"] = 0.5
    wps[1]["yaw"] = None  # YAML's null: no yaw
    scn = generate(small(route={"waypoints": str(_write(tmp_path / "w.yaml", wps))}), seed=0)
    save(scn, tmp_path / "scn")
    out = tmp_path / "nav2"
    export(tmp_path / "scn", "nav2", out, ExportOptions.from_dict(nav2_options(plants="tiles")))
    got = yaml.safe_load((out / "config" / "gps_waypoints.yaml").read_text())["waypoints"]
    assert len(got) == len(wps)
    for w, g in zip(wps, got, strict=True):
        assert g["latitude"] == pytest.approx(w["latitude"], abs=1e-9)  # ≈ 0.1 mm
        assert g["longitude"] == pytest.approx(w["longitude"], abs=1e-9)
    from scenario_gen import load

    xy = load(tmp_path / "scn").route.xy  # what the export read (route.csv, 1 µm)
    goals = scn.info["route_goals"]
    leg = [float(np.arctan2(*(xy[i + 1] - xy[i])[::-1])) for i in goals[:-1]]
    # the last waypoint faces along the leg arriving at it
    last = float(np.arctan2(*(xy[goals[-1]] - xy[goals[-1] - 1])[::-1]))
    assert [g["yaw"] for g in got] == pytest.approx([0.5, leg[1], leg[2], last], abs=1e-12)
    again = generate(small(route={"waypoints": str(out / "config" / "gps_waypoints.yaml")}), seed=0)
    assert again.info["route_goals"] == scn.info["route_goals"]
    np.testing.assert_allclose(again.route.xy, scn.route.xy, atol=1e-4)


def test_yaw_null_is_no_yaw_and_a_huge_integer_is_refused(tmp_path: Path) -> None:
    ok = [{"latitude": 0, "longitude": 0, "yaw": None}, {"latitude": 0, "longitude": 1e-5}]
    assert np.isnan(read_gps_waypoints(_write(tmp_path / "null.yaml", ok))[:, 2]).all()
    big = [{"latitude": 10**400, "longitude": 0}, {"latitude": 0, "longitude": 0}]
    with pytest.raises(InputError, match=r"waypoints\[0\]\.latitude"):
        read_gps_waypoints(_write(tmp_path / "big.yaml", big))


def test_a_route_too_short_for_any_env_is_refused_where_it_is_built(
    field,
    tmp_path: Path,  # type: ignore[no-untyped-def]
) -> None:
    """Waypoints 1 cm apart built a 0.02 m route that every env then refused at reset."""
    x0, y0 = field.lanes[0][0]

    def along(*east: float) -> str:
        lat, lon, _ = field.geo.enu_to_geodetic(x0 + np.array(east), np.full(len(east), y0), 0.0)
        wps = [{"latitude": float(a), "longitude": float(o)} for a, o in zip(lat, lon, strict=True)]
        return str(_write(tmp_path / f"{east[-1]}.yaml", wps))

    with pytest.raises(InputError, match="1.00 m of route'; allowed: at least 1.3 m"):
        generate(small(route={"waypoints": along(0.0, 0.5, 1.0)}), seed=0)
    scn = generate(small(route={"waypoints": along(0.0, 0.5, 1.5)}), seed=0)
    assert scn.route.length == pytest.approx(1.5, abs=0.01)


def test_waypoints_past_the_terrain_grids_latitudes_get_no_site_advice(
    tmp_path: Path,
) -> None:
    """Near the pole the advice named a site that was then refused in turn."""
    wps = [{"latitude": 89.9999, "longitude": 10.0}, {"latitude": 89.9999, "longitude": -170.0}]
    with pytest.raises(InputError, match="no site can hold them: .* beyond the ±85.06°"):
        generate(small(route={"waypoints": str(_write(tmp_path / "pole.yaml", wps))}), seed=0)


def test_a_waypoint_file_with_another_top_level_key_is_refused(tmp_path: Path) -> None:
    wps = [{"latitude": 0, "longitude": 0}, {"latitude": 0, "longitude": 1e-5}]
    path = tmp_path / "extra.yaml"
    path.write_text(yaml.safe_dump({"waypoints": wps, "datum": [36.5, -84.1]}))
    with pytest.raises(InputError, match=r"\['datum'\].*unknown top-level keys"):
        read_gps_waypoints(path)


def test_degrees_minutes_seconds_are_refused_not_read_as_base_60(tmp_path: Path) -> None:
    # YAML 1.1 reads 0:32 as the integer 32 (base 60): a plausible, wrong latitude
    path = tmp_path / "dms.yaml"
    path.write_text(
        "waypoints:\n  - {latitude: 0:32, longitude: 12.5}\n  - {latitude: 0.5, longitude: 12.5}\n"
    )
    with pytest.raises(InputError, match=r"latitude.*'0:32'.*decimal degrees"):
        read_gps_waypoints(path)


def test_legs_along_a_crop_row_are_noted_and_legs_between_rows_are_not(
    field, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:  # type: ignore[no-untyped-def]
    from scenario_gen.errors import Notice

    lanes = field.lanes
    (a0, a1), (b0, b1) = (
        (np.asarray(p, np.float64) for p in lanes[0]),
        (np.asarray(p, np.float64) for p in lanes[1]),
    )
    d = (a1 - a0) / np.hypot(*(a1 - a0))
    half = 0.5 * field.spec.layout.row_spacing * np.array([-d[1], d[0]])

    def write(shift: np.ndarray, name: str) -> Path:
        pts = [a0 + shift, a1 + shift, b1 + shift, b0 + shift]
        lat, lon, _ = field.geo.enu_to_geodetic(*np.asarray(pts).T, 0.0)
        wps = [{"latitude": float(a), "longitude": float(o)} for a, o in zip(lat, lon, strict=True)]
        return _write(tmp_path / name, wps)

    with warnings.catch_warnings():
        warnings.simplefilter("error", Notice)  # lane centres: nothing to say
        generate(small(route={"waypoints": str(write(0 * half, "lanes.yaml"))}), seed=0)
    with pytest.warns(Notice, match=r"legs 0→1 \(\d+ cm\), 2→3 \(\d+ cm\) run along a crop row"):
        generate(small(route={"waypoints": str(write(half, "rows.yaml"))}), seed=0)
    # a file of many such legs is a count past the first few, not a line of each
    import scenario_gen.waypoints as wp

    monkeypatch.setattr(wp, "NOTE_LEGS", 1)
    with pytest.warns(Notice, match=r"legs 0→1 \(\d+ cm\) and 1 more \(2 in all\) run along"):
        generate(small(route={"waypoints": str(write(half, "rows.yaml"))}), seed=0)


def test_waypoints_closer_than_an_rtk_fix_resolves_are_refused_by_number(
    field,  # type: ignore[no-untyped-def]
    tmp_path: Path,
) -> None:
    """A leg of micrometres has no heading: the exported yaw of such a waypoint was noise."""
    wps = _corners(field)
    x, y, _ = field.geo.geodetic_to_enu(wps[1]["latitude"], wps[1]["longitude"], 0.0)
    lat, lon, _ = field.geo.enu_to_geodetic(x + 0.004, y, 0.0)
    near = [*wps[:2], {"latitude": float(lat), "longitude": float(lon)}, *wps[2:]]
    with pytest.raises(InputError, match=r"waypoints\[2\].*mm from waypoints\[1\].*1 cm"):
        generate(small(route={"waypoints": str(_write(tmp_path / "n.yaml", near))}), seed=0)


def test_legs_of_whole_route_spacings_plan_the_same_points_after_a_round_trip(
    field,  # type: ignore[no-untyped-def]
    tmp_path: Path,
) -> None:
    """A 1 m leg is 20 spacings of 0.05 m; read back from lat/lon it is 1 m ± a micrometre,
    which ceil() made 20 or 21 points, so the goals moved between the file and its export."""
    (a0, a1) = field.lanes[0]
    heading = np.asarray(a1) - np.asarray(a0)
    heading /= np.hypot(*heading)
    side = np.array([-heading[1], heading[0]])
    start = np.asarray(a0) + 2.0 * heading
    pts = [start, start + 1.0 * side, start + 1.0 * side + 1.0 * heading, start + 1.0 * heading]
    results = []
    for jitter in (0.0, 3e-7, -3e-7):  # metres along the first leg: float noise of a round trip
        q = [pts[0], pts[1] + jitter * side, *pts[2:]]
        lat, lon, _ = field.geo.enu_to_geodetic(*np.asarray(q).T, 0.0)
        wps = [{"latitude": float(a), "longitude": float(b)} for a, b in zip(lat, lon, strict=True)]
        path = _write(tmp_path / f"w{len(results)}.yaml", wps)
        scn = generate(small(route={"waypoints": str(path)}), seed=0)
        results.append(scn.info["route_goals"])
    spacing = small().route.spacing
    assert results[0] == [0, round(1.0 / spacing), round(2.0 / spacing), round(3.0 / spacing)]
    assert results[1] == results[0] and results[2] == results[0]
