"""Curved rows and a reversing turn through the GIS and Nav2 exports (read back with GDAL)."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from scenario_gen import Scenario, generate, load, save
from scenario_gen.export import ExportOptions, export

from ..helpers import small
from .tools import gdal


@pytest.fixture(scope="module")
def curved(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, Path]:
    spec = small(
        field={"width": 10.0, "length": 16.0},
        layout={"row_geometry": "curved", "curve_radius": [15.0, 15.0], "headland": 3.0},
        route={"turn": "three_point"},
    )
    scn = generate(spec, seed=2)
    out = tmp_path_factory.mktemp("curved") / "scn"
    save(scn, out, preview=False)
    return scn, out


def test_gis_carries_curved_rows_and_tagged_turns(curved, tmp_path: Path) -> None:
    scn, src = curved
    out = tmp_path / "gis"
    export(src, "gis", out, ExportOptions())
    gdal("ogrinfo")
    info = subprocess.run(
        ["ogrinfo", "-ro", "-so", "-al", str(out / "layers.gpkg")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "Layer name: rows" in info and "Layer name: route" in info
    rows = json.loads((out / "rows.geojson").read_text())["features"]
    assert len(rows) == len(scn.rows.offsets)
    for f in rows:  # each row an arc: longer than its chord, its length what the file says
        lonlat = np.array(f["geometry"]["coordinates"])[:, :2]
        x, y, _ = scn.geo.geodetic_to_enu(lonlat[:, 1], lonlat[:, 0], scn.geo.alt)
        drawn = float(np.hypot(np.diff(x), np.diff(y)).sum())
        assert drawn == pytest.approx(f["properties"]["length_m"], rel=1e-3)
        assert drawn > float(np.hypot(x[-1] - x[0], y[-1] - y[0])) + 1e-4
    route = json.loads((out / "route.geojson").read_text())["features"]
    turns = [f["properties"] for f in route if f["properties"]["turn"]]
    assert {p["turn"] for p in turns} == {"three_point"}
    assert [p["direction"] for p in turns] == [1, -1, 1]  # forward, reverse, forward


def test_nav2_carries_the_curved_route_and_its_cusps(curved, tmp_path: Path) -> None:
    _, src = curved
    out = tmp_path / "nav2"
    from baselines.nav2_robot import nav2_options

    export(src, "nav2", out, ExportOptions.from_dict(nav2_options(plants="tiles")))
    with open(out / "reference_path.csv", newline="") as f:
        path = list(csv.DictReader(f))
    r = load(src).route
    assert len(path) == len(r)
    np.testing.assert_array_equal([int(p["direction"]) for p in path], r.direction)
    assert {p["turn"] for p in path} == {"", "three_point"}
    # facing, not travel, on the reversing leg
    back = np.flatnonzero(r.direction[:-1] < 0)
    yaw = np.array([float(p["yaw"]) for p in path])[back]
    d = np.diff(r.xy, axis=0)[back]
    assert (np.cos(yaw - np.arctan2(d[:, 1], d[:, 0])) < -0.99).all()
    text = (out / "config" / "gps_waypoints.yaml").read_text()
    assert text.count("cusp: reverse") == 1 and text.count("cusp: forward") == 1
    assert len(yaml.safe_load(text)["waypoints"]) == 2 * 2 + 2 + 1  # lanes, cusps, end
