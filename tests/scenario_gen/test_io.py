import csv
import json
from pathlib import Path

import numpy as np
import pytest

from scenario_gen import ScenarioError, generate, load, save
from scenario_gen.io import PLANT_HEADER, ROUTE_HEADER

from .helpers import small


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory):
    scn = generate(small(layout={"weed_density": 0.5}), seed=11)
    out = tmp_path_factory.mktemp("io") / "scn"
    save(scn, out)
    return scn, out


def test_directory_has_every_output(saved) -> None:
    _, out = saved
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [
            "scenario.json",
            "terrain.npz",
            "plants.csv",
            "route.csv",
            "obstacles.csv",
            "field.geojson",
            "route.geojson",
            "plants.geojson",
            "preview.png",
            ".agrinav-output",  # the marker that lets --force replace it later
        ]
    )
    assert (out / "preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_csv_headers_and_metadata(saved) -> None:
    scn, out = saved
    with open(out / "plants.csv") as f:
        assert next(csv.reader(f)) == PLANT_HEADER
    with open(out / "route.csv") as f:
        assert next(csv.reader(f)) == ROUTE_HEADER
    meta = json.loads((out / "scenario.json").read_text())
    assert meta["format_version"] == 4 and meta["seed"] == 11
    assert meta["counts"]["plants"] + meta["counts"]["weeds"] == len(scn.plants)
    assert meta["datum"]["lat"] == scn.geo.lat and meta["lod"] == 20
    assert {"numpy", "pyproj", "PROJ", "agrinav-gym"} <= set(meta["versions"])


def test_scenario_json_regenerates_the_same_scenario(saved) -> None:
    scn, out = saved
    from scenario_gen import ScenarioSpec

    meta = json.loads((out / "scenario.json").read_text())
    again = generate(ScenarioSpec.from_dict(meta["spec"]), meta["seed"])
    assert np.array_equal(again.plants.x, scn.plants.x)
    assert np.array_equal(again.terrain.heights, scn.terrain.heights)


def test_load_round_trip(saved) -> None:
    scn, out = saved
    back = load(out)
    assert back.spec == scn.spec and back.seed == scn.seed
    np.testing.assert_array_equal(back.terrain.heights, scn.terrain.heights)
    for k in ("x", "y", "z", "roll", "pitch", "yaw"):
        np.testing.assert_allclose(getattr(back.plants, k), getattr(scn.plants, k), atol=1e-6)
    np.testing.assert_array_equal(back.plants.species, scn.plants.species)
    np.testing.assert_array_equal(back.plants.row, scn.plants.row)
    np.testing.assert_allclose(back.route.xyz, scn.route.xyz, atol=1e-6)
    np.testing.assert_array_equal(back.route.segment, scn.route.segment)
    np.testing.assert_array_equal(back.route.lane, scn.route.lane)
    assert back.field.equals(scn.field)


def test_geojson_is_wgs84_and_matches_plants(saved) -> None:
    scn, out = saved
    layers = {
        n: json.loads((out / f"{n}.geojson").read_text()) for n in ("field", "route", "plants")
    }
    for name, fc in layers.items():
        # one geometry type per file, unique feature ids: GDAL converts each to any format
        types = {f["geometry"]["type"] for f in fc["features"]}
        assert len(types) == 1, (name, types)
        assert [f["id"] for f in fc["features"]] == list(range(len(fc["features"])))
    assert len(layers["field"]["features"]) == 1
    assert len(layers["route"]["features"]) >= 3  # headland, furrow, headland, ...
    plants = layers["plants"]["features"]
    assert [f["properties"]["plant_id"] for f in plants] == list(range(len(scn.plants)))
    pts = np.array([f["geometry"]["coordinates"] for f in plants])
    lat, lon, _ = scn.geo.enu_to_geodetic(scn.plants.x, scn.plants.y, scn.plants.z)
    np.testing.assert_allclose(pts[:, 0], lon, atol=1e-8)  # 1e-8 deg ≈ 1 mm
    np.testing.assert_allclose(pts[:, 1], lat, atol=1e-8)


def test_existing_directory_is_not_overwritten_unless_asked(saved, tmp_path: Path) -> None:
    scn, _ = saved
    out = tmp_path / "x"
    save(scn, out)
    with pytest.raises(ScenarioError, match="already exists"):
        save(scn, out)
    save(scn, out, overwrite=True)
    assert (out / "scenario.json").is_file()


def test_failed_save_leaves_nothing(saved, tmp_path: Path, monkeypatch) -> None:
    scn, _ = saved
    import scenario_gen.io as preview

    def boom(*_a, **_k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(preview, "render_preview", boom)
    with pytest.raises(RuntimeError):
        save(scn, tmp_path / "half")
    assert list(tmp_path.iterdir()) == []


def test_load_refuses_non_scenarios(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="not a scenario directory"):
        load(tmp_path)


# ----------------------------------------------------------------------------- loading
def test_scenario_json_stores_resolved_paths_and_regenerates_from_anywhere(
    tmp_path: Path, monkeypatch
) -> None:
    import shutil

    from scenario_gen import ScenarioSpec
    from scenario_gen.geodesy import GeoFrame

    work = tmp_path / "work"
    (work / "inputs").mkdir(parents=True)
    geo = GeoFrame(36.549167, -84.1425, 0.0)
    ring = [geo.enu_to_geodetic(x, y) for x, y in [(-6, -8), (6, -8), (6, 8), (-6, 8), (-6, -8)]]
    (work / "inputs" / "f.geojson").write_text(
        json.dumps(
            {"type": "Polygon", "coordinates": [[[float(lo), float(la)] for la, lo, _ in ring]]}
        )
    )
    monkeypatch.chdir(work)
    spec = small(field={"geojson": "inputs/f.geojson"})  # relative, as a user types it
    scn = generate(spec, seed=1)
    assert scn.spec.field.geojson == str((work / "inputs" / "f.geojson").resolve())
    save(scn, "out")
    meta = json.loads((work / "out" / "scenario.json").read_text())
    assert meta["spec"]["field"]["geojson"] == str((work / "inputs" / "f.geojson").resolve())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    again = generate(ScenarioSpec.from_dict(meta["spec"]), meta["seed"])
    np.testing.assert_array_equal(again.plants.x, scn.plants.x)
    shutil.rmtree(work / "out")


def test_load_recovers_rows_of_a_version_1_folder(saved, tmp_path: Path) -> None:
    # version 1 had no row column and no segments: rows come from the nearest row line
    import shutil

    scn, out = saved
    old = tmp_path / "v1"
    shutil.copytree(out, old)
    meta = json.loads((old / "scenario.json").read_text())
    meta["format_version"] = 1
    del meta["rows"]["segments"], meta["crop_model"]
    (old / "scenario.json").write_text(json.dumps(meta))
    lines = (old / "plants.csv").read_text().splitlines()
    (old / "plants.csv").write_text(
        "\n".join(",".join(line.split(",")[:-1]) for line in lines) + "\n"
    )
    lines = (old / "route.csv").read_text().splitlines()  # no turn, direction before 3
    (old / "route.csv").write_text(
        "\n".join(",".join(line.split(",")[:-2]) for line in lines) + "\n"
    )
    back = load(old)
    np.testing.assert_array_equal(back.plants.row, scn.plants.row)
    np.testing.assert_array_equal(back.lanes, scn.lanes)


def test_the_readme_lists_the_csv_columns_the_files_have() -> None:
    """README.md's output table is where people learn the columns: it must name them all."""
    import re

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    for name, header in (("plants.csv", PLANT_HEADER), ("route.csv", ROUTE_HEADER)):
        row = re.search(rf"^\| `{re.escape(name)}` \| `([^`]+)`", readme, re.MULTILINE)
        assert row is not None, name
        assert row.group(1).split(",") == header, (name, row.group(1))
