"""Nav2 bundle (waypoints, reference path, launch file) and the mesh export."""

from __future__ import annotations

import ast
import csv
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

from scenario_gen import Scenario, load
from scenario_gen.export import ExportOptions, export
from scenario_gen.export.nav2 import sparse_waypoints

URDF = Path(__file__).resolve().parents[3] / "src" / "agrinav_gym" / "assets" / "summit_xl.urdf"


@pytest.fixture(scope="module")
def nav2(nav2_bundle) -> tuple[Scenario, Path]:
    return nav2_bundle


def test_gps_waypoints_are_sparse_and_on_the_route(nav2) -> None:
    scn, out = nav2
    doc = yaml.safe_load((out / "config" / "gps_waypoints.yaml").read_text())
    wps = doc["waypoints"]
    assert all(set(w) == {"latitude", "longitude", "yaw"} for w in wps)
    lanes = scn.spec.route.lanes
    assert len(wps) == 2 * lanes + (lanes - 1) + 1  # lane ends, turn apexes, the end
    idx = [i for i, _ in sparse_waypoints(scn)]
    r = scn.route
    lat, lon, _ = scn.geo.enu_to_geodetic(r.xyz[idx, 0], r.xyz[idx, 1], r.xyz[idx, 2])
    np.testing.assert_allclose([w["latitude"] for w in wps], lat, atol=1e-10)
    np.testing.assert_allclose([w["longitude"] for w in wps], lon, atol=1e-10)
    # lane entries and exits face along the rows, alternating direction; yaw is in radians
    yaw = np.array([w["yaw"] for w in wps])
    assert np.abs(yaw).max() <= math.pi
    row = scn.rows.angle
    ends = [k for k, (_, label) in enumerate(sparse_waypoints(scn)) if "lane" in label]
    for k in ends:
        lane_number = ends.index(k) // 2
        want = row if lane_number % 2 == 0 else row + math.pi
        assert abs(math.remainder(yaw[k] - want, 2 * math.pi)) < 1e-6
    enu = yaml.safe_load((out / "config" / "waypoints_enu.yaml").read_text())["waypoints"]
    np.testing.assert_allclose([[w["x"], w["y"]] for w in enu], r.xyz[idx, :2], atol=1e-4)


def test_reference_path_is_the_dense_route(nav2) -> None:
    scn, out = nav2
    with open(out / "reference_path.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    r = scn.route
    assert len(rows) == len(r)
    xyz = np.array([[float(row[k]) for k in "xyz"] for row in rows])
    np.testing.assert_allclose(xyz, r.xyz, atol=1e-6)
    step = np.hypot(*np.diff(xyz[:, :2], axis=0).T)
    assert step.max() <= 0.1 + 1e-6
    assert [row["segment"] for row in rows] == r.segment.tolist()
    assert float(rows[-1]["s"]) == pytest.approx(r.length, abs=1e-3)


def test_launch_file_spawns_at_the_route_start(nav2) -> None:
    scn, out = nav2
    text = (out / "launch" / "agrinav_field.launch.py").read_text()
    tree = ast.parse(text)  # valid Python; ROS itself is not installed here
    spawn = next(
        n.value
        for n in ast.walk(tree)
        if isinstance(n, ast.Assign)
        and isinstance(n.targets[0], ast.Tuple)
        and [t.id for t in n.targets[0].elts] == ["SPAWN_X", "SPAWN_Y", "SPAWN_Z", "SPAWN_YAW"]
    )
    x, y, z, yaw = ast.literal_eval(spawn)
    r = scn.route
    assert (x, y) == pytest.approx(tuple(r.xyz[0, :2]), abs=1e-4)
    assert z == pytest.approx(r.xyz[0, 2] + 0.13, abs=1e-4)
    assert yaw == pytest.approx(math.atan2(*(r.xy[1] - r.xy[0])[::-1]), abs=1e-5)
    for rel in ("worlds/field.sdf", "worlds/field_classic.world", "robot/summit_xl.urdf"):
        assert rel.split("/")[-1] in text and (out / rel).is_file()
    assert (out / "robot" / "summit_xl.urdf").read_bytes() == URDF.read_bytes()
    nav = yaml.safe_load((out / "config" / "navsat_transform.yaml").read_text())
    params = nav["navsat_transform"]["ros__parameters"]
    assert params["use_local_cartesian"] is True
    assert params["datum"][:2] == pytest.approx([scn.geo.lat, scn.geo.lon], abs=1e-10)


def test_mesh_export_formats(dem, tmp_path) -> None:
    import trimesh

    scn, src = dem
    out = tmp_path / "mesh"
    opts = ExportOptions(formats=("glb", "obj", "ply", "dae"), mesh_plants=True)
    export(src, "mesh", out, opts)
    t = scn.terrain
    for fmt in opts.formats:
        mesh = trimesh.load(out / f"terrain.{fmt}", force="mesh")
        assert len(mesh.vertices) == t.size
        up = 1 if fmt == "glb" else 2  # glTF is Y-up
        assert mesh.bounds[1, up] == pytest.approx(t.heights.max(), abs=1e-4)
    plants = trimesh.load(out / "plants.ply", force="mesh")
    p = load(src).plants
    for name in ("terrain.dae", "plants.dae"):
        _dae_is_z_up(out / name, t.heights.max() if name == "terrain.dae" else None)
    lo, hi = plants.bounds
    assert hi[2] == pytest.approx((p.z + p.height).max(), abs=0.05)
    assert lo[0] > p.x.min() - 1.0 and hi[0] < p.x.max() + 1.0


def test_merged_plants_past_the_budget_are_refused_before_anything_is_written(
    dem, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """200 plants of a 41k-triangle model took 13 GB as OBJ (and ignored SIGTERM for
    minutes): past the budget the export is one line naming the count, and leaves nothing."""
    from scenario_gen.errors import InputError
    from scenario_gen.export import mesh
    from scenario_gen.export.plantmodels import assign

    _, src = dem
    total = mesh.check_merged_size(assign(load(src)))
    monkeypatch.setattr(mesh, "MAX_MERGED_TRIANGLES", total - 1)
    out = tmp_path / "mesh"
    with pytest.raises(InputError, match=f"got '{total:,} triangles"):
        export(src, "mesh", out, ExportOptions(formats=("obj",), mesh_plants=True))
    assert list(tmp_path.iterdir()) == []
    export(src, "mesh", out, ExportOptions(formats=("obj",)))  # the terrain alone is fine


def _dae_is_z_up(path: Path, top: float | None) -> None:
    """The file declares Z_UP and its vertices are Z-up: a reader that honours the up axis
    (Blender, assimp) lays the field flat."""
    import collada

    ns = {"c": "http://www.collada.org/2005/11/COLLADASchema"}
    root = ET.parse(path).getroot()
    assert [e.text for e in root.iterfind("c:asset/c:up_axis", ns)] == ["Z_UP"]
    doc = collada.Collada(str(path))
    assert doc.assetInfo.upaxis == "Z_UP"
    v = np.concatenate([g.primitives[0].vertex.reshape(-1, 3) for g in doc.geometries])
    extent = v.max(axis=0) - v.min(axis=0)
    assert extent[2] < 0.5 * min(extent[0], extent[1])  # flat along z: z is up
    if top is not None:
        assert v[:, 2].max() == pytest.approx(top, abs=1e-4)
