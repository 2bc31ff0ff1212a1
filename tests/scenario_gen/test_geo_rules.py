"""The LoD rule, the datum rules and a field that must lie on its terrain."""

import json
from pathlib import Path

import numpy as np
import pytest
from pyproj import Geod

from scenario_gen import ScenarioError, generate
from scenario_gen.bounds import min_lod
from scenario_gen.geodesy import GeoFrame, ground_sample_distance

from .helpers import plane, small

LAT = 36.549167  # the embedded DEM's flattest site, where small() lands
RIDGED = {"enabled": True}  # the ridges' rule: 4 samples per row period


@pytest.mark.parametrize("lod", [0, 4, 12, 18])
def test_coarse_lod_is_refused_with_the_rule_and_the_lod_that_works(lod: int) -> None:
    # 1 m rows with furrows: at most 0.25 m between samples; at 36.5° that is LoD 19 (0.240 m)
    with pytest.raises(ScenarioError) as info:
        generate(small(terrain={"lod": lod}, furrows=RIDGED), seed=0)
    e = info.value
    assert e.field == "terrain.lod" and e.value == lod
    assert "off the DEM" not in str(e)
    assert "at most 0.25 m" in str(e) and "use LoD >= 19" in str(e), str(e)
    assert ground_sample_distance(19, LAT) <= 0.25 < ground_sample_distance(18, LAT)


def test_the_smallest_lod_the_error_names_is_accepted() -> None:
    scn = generate(small(terrain={"lod": 19}, furrows=RIDGED), seed=0)
    assert scn.terrain.spacing <= 0.25


def test_without_relief_only_the_10m_triangle_bound_applies() -> None:
    flat = {"furrows": {"enabled": False, "roughness": 0.0}}
    need = min_lod(10.0, LAT)
    assert need == 14  # 7.7 m at 36.5°; LoD 13 is 15 m
    generate(small(terrain={"lod": need}, **flat), seed=0)
    with pytest.raises(ScenarioError, match=r"at most 10 m .*use LoD >= 14"):
        generate(small(terrain={"lod": need - 1}, **flat), seed=0)


def test_roughness_needs_samples_closer_than_its_correlation_length() -> None:
    spec = small(furrows={"enabled": False, "roughness": 0.01, "roughness_length": 1.0})
    generate(spec.replace({"terrain.lod": 17}), seed=0)  # 0.96 m at 36.5°
    with pytest.raises(ScenarioError, match="roughness_length 1 m"):
        generate(spec.replace({"terrain.lod": 16}), seed=0)  # 1.92 m


def test_no_lod_is_fine_enough_says_so() -> None:
    with pytest.raises(ScenarioError, match="no LoD up to 22"):
        spec = small(layout={"row_spacing": 0.1, "jitter_lateral": 0.0}, furrows=RIDGED)
        generate(spec, seed=0)


# ----------------------------------------------------------------------------- datum
@pytest.mark.parametrize("source", ["embedded", "dem"])
def test_datum_is_refused_on_a_dem(source: str) -> None:
    over = {"terrain": {"source": source, "datum": [36.5, -84.1, 300.0]}}
    if source == "dem":
        over["terrain"]["path"] = "/any.tif"
    with pytest.raises(ScenarioError) as info:
        generate(small(**over), seed=0)
    assert info.value.field == "terrain.datum" and "a DEM fixes the datum" in str(info.value)


def _square(tmp_path: Path, lat: float, lon: float, side_m: float = 24.0) -> Path:
    geo = GeoFrame(lat, lon, 0.0)
    h = side_m / 2
    ring = [geo.enu_to_geodetic(x, y) for x, y in [(-h, -h), (h, -h), (h, h), (-h, h), (-h, -h)]]
    p = tmp_path / "square.geojson"
    coords = [[float(lo), float(la)] for la, lo, _ in ring]
    p.write_text(json.dumps({"type": "Polygon", "coordinates": [coords]}))
    return p


def test_plane_under_a_geojson_field_lies_where_the_field_is(tmp_path: Path) -> None:
    # a field in Iowa; the plane's default datum is in Spain, 6,900 km away
    gj = _square(tmp_path, 42.03, -93.6)
    scn = generate(plane(field={"geojson": str(gj)}, layout={"row_angle_deg": 0.0}), seed=0)
    assert scn.geo.lat == pytest.approx(42.03, abs=1e-4) and scn.geo.lon == pytest.approx(-93.6)
    _lat, _lon, alt = scn.geo.enu_to_geodetic(scn.plants.x, scn.plants.y, scn.plants.z)
    assert np.abs(alt).max() < 0.01  # on the plane at 0 m, not at 2,000 km
    with open(gj) as f:
        ring = np.array(json.load(f)["coordinates"][0])
    area, _ = Geod(ellps="WGS84").polygon_area_perimeter(ring[:, 0], ring[:, 1])
    assert scn.field.area == pytest.approx(abs(area), rel=1e-4)
    assert scn.field.area == pytest.approx(24.0**2, rel=1e-3)


def test_plane_far_from_its_datum_is_refused(tmp_path: Path) -> None:
    gj = _square(tmp_path, 42.03, -93.6)
    with pytest.raises(ScenarioError) as info:
        generate(plane(field={"geojson": str(gj)}, terrain={"datum": [42.6, -5.57, 830.0]}), seed=0)
    assert info.value.field == "terrain.datum"
    assert "km from the plane's datum" in str(info.value) and "within 5 km" in str(info.value)


def test_a_field_on_the_far_side_of_the_earth_is_not_folded_onto_the_plane(
    tmp_path: Path,
) -> None:
    """The datum's vertical leaves the Earth again at its antipode: east and north alone put
    that field inside 5 km of the datum."""
    gj = _square(tmp_path, -42.03, -93.6 + 180.0)
    with pytest.raises(ScenarioError) as info:
        generate(plane(field={"geojson": str(gj)}, terrain={"datum": [42.03, -93.6, 0.0]}), 0)
    assert info.value.field == "terrain.datum" and "12,7" in str(info.value), str(info.value)


def test_plane_datum_near_the_field_is_honoured(tmp_path: Path) -> None:
    gj = _square(tmp_path, 42.03, -93.6)
    datum = [42.03 + 1000 / 111_000, -93.6, 250.0]  # 1 km north of the field, at 250 m
    scn = generate(plane(field={"geojson": str(gj)}, terrain={"datum": datum}), seed=0)
    assert (scn.geo.lat, scn.geo.lon, scn.geo.alt) == pytest.approx(tuple(datum))
    cy = scn.field.centroid.y
    assert cy == pytest.approx(-1000.0, abs=15.0)
    _lat, _lon, alt = scn.geo.enu_to_geodetic(scn.plants.x, scn.plants.y, scn.plants.z)
    # the tangent plane at 1 km lies d²/2R = 8 cm above the ellipsoid
    assert np.abs(alt - 250.0 - 1000.0**2 / (2 * 6.371e6)).max() < 0.03


def test_every_broken_lod_rule_is_named_at_once() -> None:
    """One refusal lists each rule the LoD breaks, the fields that set it with their values,
    and what meets it, then the LoD that meets them all: no fixing one to meet the next."""
    rough = {"enabled": True, "roughness": 0.01, "roughness_length": 0.5}
    with pytest.raises(ScenarioError) as info:
        generate(small(terrain={"lod": 16}, furrows=rough), seed=0)
    e, text = info.value, str(info.value)
    assert e.field == "terrain.lod" and e.value == 16 and "\n" not in text
    assert "breaks 2 rules" in text, text
    assert "(1) at most 0.25 m (4 samples per layout.row_spacing 1 m" in text
    assert "LoD >= 19, or layout.row_spacing >= 7.68 m, or furrows.enabled false" in text
    assert "(2) at most 0.5 m (furrows.roughness_length 0.5 m" in text
    assert "LoD >= 18, or furrows.roughness_length >= 1.92 m, or furrows.roughness 0" in text
    assert text.endswith("use LoD >= 19 at latitude 36.55°")
    # the 10 m rule as well on a coarser grid, and nothing out of a field's range (row spacing
    # is at most 50 m: "layout.row_spacing >= 123 m" would be no advice)
    with pytest.raises(ScenarioError, match=r"breaks 3 rules: \(1\) at most 10 m") as coarse:
        generate(small(terrain={"lod": 12}, furrows=rough), seed=0)
    assert "layout.row_spacing >=" not in str(coarse.value)


def test_an_lod_between_the_grid_rules_and_the_terrain_size_is_named_or_refused() -> None:
    """Too coarse for the ridges and, at the LoD they need, too many samples: both at once."""
    spec = plane(
        field={"width": 1000.0, "length": 1000.0},
        layout={"plant_spacing": 2.0},  # within the plant bound: the terrain is what is tested
        terrain={"lod": 15},
        furrows=RIDGED,
    )
    with pytest.raises(ScenarioError) as info:
        generate(spec, seed=0)
    assert "need LoD >= 19, the terrain's size LoD <= 18" in str(info.value), str(info.value)
