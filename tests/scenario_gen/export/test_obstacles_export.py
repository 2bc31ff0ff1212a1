"""Obstacles (stones, litter, fallen stalks) in every export: Gazebo (checked by libsdformat),
the Nav2 bundle, the meshes, the GeoPackage (checked by GDAL) and the previews; and an export
without obstacles is the one it was before they existed."""

from __future__ import annotations

import dataclasses
import filecmp
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from scenario_gen import Scenario
from scenario_gen.export import ExportOptions, export, export_scenario
from scenario_gen.export.obstacles import KIND_RGB, OBSTACLES_MODEL, TILE_PREFIX, names
from scenario_gen.obstacles import OBSTACLE_KINDS, Obstacles

from .tools import Check, gdal, quat_to_matrix, run_check, run_checks


def _stl(path: Path) -> np.ndarray:
    """(f, 3, 3) triangles of a binary STL, as written (float32)."""
    import trimesh

    return np.asarray(trimesh.load(path, process=False).triangles)


# ---------------------------------------------------------------------------- Gazebo
@pytest.fixture(scope="module")
def gz_models(obstacle_hill, tmp_path_factory) -> tuple[Scenario, Path]:
    _, src = obstacle_hill
    out = tmp_path_factory.mktemp("gz_obstacles") / "include"
    export(src, "gazebo", out, ExportOptions(plants="include"))
    return obstacle_hill[0], out


@pytest.fixture(scope="module")
def gz_checks(gz_models, sdf_check) -> dict[str, Check]:
    _, out = gz_models
    worlds = ("field.sdf", "field_classic.world")
    got = run_checks(sdf_check, [out / "worlds" / w for w in worlds], out / "models")
    return dict(zip(worlds, got, strict=True))


def test_each_obstacle_is_a_static_model_at_its_pose(gz_models, gz_checks) -> None:
    scn, _ = gz_models
    o = scn.obstacles
    want = names(o)
    assert want[0].startswith(str(o.kind[0]) + "_") and len(set(want)) == len(o)
    for world, c in gz_checks.items():
        assert c.returncode == 0 and c.valid, (world, c.stderr)
        assert len(c.models) == len(scn.plants) + 1 + len(o)  # plants, terrain, obstacles
        rows = np.array([c.models[n] for n in want])
        np.testing.assert_allclose(rows[:, :3], np.column_stack([o.x, o.y, o.z]), atol=1e-6)
        got = quat_to_matrix(rows[:, 3:7])
        rot = np.array([o.rotation(i) for i in range(len(o))])
        assert np.abs(got - rot).max() < 1e-6
    # on this 20° slope the ground tilts every obstacle: the rotation is tested for real
    assert np.abs(o.pitch).max() > 0.15 or np.abs(o.roll).max() > 0.15
    kinds = {n.rsplit("_", 1)[0] for n in want}
    assert kinds == set(OBSTACLE_KINDS)
    assert {k: sum(n.startswith(k + "_") for n in want) for k in OBSTACLE_KINDS} == o.counts()


def test_obstacle_meshes_are_their_own_shapes_for_visual_and_collision(
    gz_models, gz_checks
) -> None:
    scn, out = gz_models
    o = scn.obstacles
    folder = out / "models" / OBSTACLES_MODEL / "meshes"
    resolved = [Path(m).resolve() for m in gz_checks["field.sdf"].meshes]
    world = (out / "worlds" / "field.sdf").read_text()
    for i, name in enumerate(names(o)):
        stl = folder / f"{name}.stl"
        # libsdformat resolved the mesh twice: the visual's and the collision's
        assert resolved.count(stl.resolve()) == 2, name
        v, f = o.local_mesh(i)
        np.testing.assert_allclose(_stl(stl), v[f], atol=1e-6)  # float32 in its own frame
        model = re.search(rf'<model name="{name}">.*?</model>', world).group(0)
        rgb = np.array(KIND_RGB[str(o.kind[i])]) / 255.0
        assert f"<diffuse>{' '.join(f'{c:.4f}' for c in rgb)} 1.0000</diffuse>" in model
        assert "<static>true</static>" in model


def test_the_obstacles_model_inserts_them_all(gz_models, sdf_check, tmp_path) -> None:
    """models/agrinav_obstacles/model.sdf: every obstacle as a link at its ENU pose."""
    scn, out = gz_models
    world = (out / "worlds" / "field.sdf").read_text()
    head, _, _ = world.partition("<include>")
    one = tmp_path / "one.sdf"
    one.write_text(
        head + f"<include><uri>model://{OBSTACLES_MODEL}</uri><name>obstacles</name>"
        "<pose>0 0 0 0 0 0</pose></include></world></sdf>"
    )
    c = run_check(sdf_check, one, out / "models")
    assert c.returncode == 0 and c.valid, c.stderr
    assert list(c.models) == ["obstacles"]
    assert len(c.meshes) == 2 * len(scn.obstacles)


def test_merged_obstacle_tiles_hold_every_mesh_at_its_pose(obstacle_hill, sdf_check, tmp_path):
    scn, src = obstacle_hill
    out = tmp_path / "tiles"
    export(src, "gazebo", out, ExportOptions(plants="tiles", tile_plants=4))
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.returncode == 0 and c.valid, c.stderr
    o = scn.obstacles
    tiles = sorted((out / "models").glob(f"{TILE_PREFIX}_*"))
    assert len(tiles) >= 3 and not (out / "models" / OBSTACLES_MODEL).exists()
    assert not any(n in c.models for n in names(o))  # merged: no model per obstacle
    got: dict[str, list[np.ndarray]] = {k: [] for k in OBSTACLE_KINDS}
    for folder in tiles:
        origin = c.models[folder.name.removeprefix("agrinav_")][:3]
        parts = {k: _stl(folder / "meshes" / f"{k}.stl") + origin
                 for k in OBSTACLE_KINDS if (folder / "meshes" / f"{k}.stl").is_file()}  # fmt: skip
        every = np.concatenate(list(parts.values()))
        np.testing.assert_allclose(_stl(folder / "meshes" / "collision.stl") + origin, every,
                                   atol=1e-5)  # fmt: skip
        for k, tri in parts.items():
            got[k].append(tri)
    for k in OBSTACLE_KINDS:
        want = [o.mesh(i) for i in np.flatnonzero(o.kind == k)]
        want_tri = np.concatenate([v[f] for v, f in want])
        have = np.concatenate(got[k])
        assert len(have) == len(want_tri)
        # tiles take their obstacles in their own order: compare the sets of triangles
        key = lambda t: np.lexsort(t.reshape(len(t), -1).T[::-1])  # noqa: E731
        np.testing.assert_allclose(have[key(have)], want_tri[key(want_tri)], atol=1e-5)


def test_obstacles_add_only_their_own_files(obstacle_hill, tmp_path) -> None:
    """The same scenario exported with its obstacles emptied: every file is byte-identical
    except the worlds (which lose exactly the obstacle models), the README and the preview."""
    scn, _ = obstacle_hill
    bare = dataclasses.replace(scn, obstacles=Obstacles.empty())
    opts = ExportOptions(plants="include")
    export_scenario(scn, "gazebo", tmp_path / "with", opts)
    export_scenario(bare, "gazebo", tmp_path / "bare", opts)
    a, b = tmp_path / "with", tmp_path / "bare"
    files_a = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    extra = files_a - files_b
    assert files_b <= files_a and extra
    assert all(p.parts[:2] == ("models", OBSTACLES_MODEL) for p in extra)
    differ = {p for p in files_b if not filecmp.cmp(a / p, b / p, shallow=False)}
    worlds = {Path("worlds/field.sdf"), Path("worlds/field_classic.world")}
    assert differ == worlds | {Path("README.md"), Path("preview.png")}
    for w in worlds:
        text = (a / w).read_text()
        stripped = re.sub(r'\n    <model name="(stone|litter|stalk)_\d+">.*?</model>', "", text)
        assert len(stripped) < len(text) and stripped == (b / w).read_text()
    assert "Obstacles" in (a / "README.md").read_text()
    assert "Obstacles" not in (b / "README.md").read_text()


def test_nav2_bundle_carries_the_obstacles(obstacle_hill, sdf_check, tmp_path) -> None:
    from baselines.nav2_robot import nav2_options

    scn, src = obstacle_hill
    out = tmp_path / "nav2"
    export(src, "nav2", out, ExportOptions.from_dict(nav2_options(plants="include")))
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.returncode == 0 and c.valid, c.stderr
    o = scn.obstacles
    rows = np.array([c.models[n] for n in names(o)])  # ≤ include_limit: one model each
    np.testing.assert_allclose(rows[:, :3], np.column_stack([o.x, o.y, o.z]), atol=1e-6)
    assert "Obstacles (" in (out / "README.md").read_text()


# ---------------------------------------------------------------------------- meshes
@pytest.fixture(scope="module")
def meshes(obstacle_hill, tmp_path_factory) -> tuple[Scenario, Path]:
    _, src = obstacle_hill
    out = tmp_path_factory.mktemp("mesh_obstacles") / "out"
    export(src, "mesh", out, ExportOptions(formats=("glb", "obj", "ply", "dae"), mesh_plants=True))
    return obstacle_hill[0], out


def _sorted_triangles(tri: np.ndarray) -> np.ndarray:
    """Triangles in a canonical order (a reader may reorder faces and split vertices)."""
    flat = np.round(tri.reshape(len(tri), -1), 5)
    return flat[np.lexsort(flat.T[::-1])]


def test_glb_has_a_node_per_obstacle_at_its_pose(meshes) -> None:
    import json
    import struct

    import trimesh

    from scenario_gen.export.obstacles import ENU_TO_Y_UP, pose_matrix

    scn, out = meshes
    o = scn.obstacles
    data = (out / "obstacles.glb").read_bytes()
    (size,) = struct.unpack("<I", data[12:16])
    gltf = json.loads(data[20 : 20 + size])
    nodes = {n["name"]: n for n in gltf["nodes"]}
    assert sorted(nodes) == sorted(names(o))
    back = trimesh.load(out / "obstacles.glb")
    for i, name in enumerate(names(o)):
        matrix = np.array(nodes[name]["matrix"]).reshape(4, 4).T  # glTF: column-major
        np.testing.assert_allclose(matrix, ENU_TO_Y_UP @ pose_matrix(o, i), atol=1e-9)
        v, f = o.local_mesh(i)
        got = back.geometry[name]
        np.testing.assert_allclose(_sorted_triangles(got.triangles), _sorted_triangles(v[f]),
                                   atol=2e-5)  # fmt: skip
        colour = got.visual.face_colors[:, :3]
        assert (colour == KIND_RGB[str(o.kind[i])]).all()


def test_collada_has_a_node_per_obstacle_at_its_pose(meshes) -> None:
    import xml.etree.ElementTree as ET

    import trimesh

    from scenario_gen.export.obstacles import pose_matrix

    scn, out = meshes
    o = scn.obstacles
    ns = {"c": "http://www.collada.org/2005/11/COLLADASchema"}
    root = ET.parse(out / "obstacles.dae").getroot()
    assert root.find("c:asset/c:up_axis", ns).text == "Z_UP"
    nodes = root.findall(".//c:visual_scene/c:node", ns)
    assert [n.get("name") for n in nodes] == names(o)
    for i, node in enumerate(nodes):
        matrix = np.array(node.find("c:matrix", ns).text.split(), float).reshape(4, 4)
        np.testing.assert_allclose(matrix, pose_matrix(o, i), atol=1e-8)
        target = node.find(".//c:instance_material", ns).get("target")
        assert target == f"#{o.kind[i]}-material"
    back = trimesh.load(out / "obstacles.dae")  # pycollada reads it; the scene in ENU
    v, _, _ = o.meshes()
    np.testing.assert_allclose(back.bounds, [v.min(axis=0), v.max(axis=0)], atol=1e-5)


def test_obj_has_an_object_per_obstacle_in_enu(meshes) -> None:
    import trimesh

    scn, out = meshes
    o = scn.obstacles
    text = (out / "obstacles.obj").read_text()
    assert re.findall(r"^o (\S+)$", text, re.M) == names(o)
    back = trimesh.load(out / "obstacles.obj", process=False)
    v, f, _ = o.meshes()
    np.testing.assert_allclose(_sorted_triangles(back.triangles), _sorted_triangles(v[f]),
                               atol=2e-5)  # fmt: skip


def test_ply_faces_carry_the_obstacle_and_its_kind(meshes) -> None:
    import trimesh

    scn, out = meshes
    o = scn.obstacles
    data = (out / "obstacles.ply").read_bytes()
    head, _, body = data.partition(b"end_header\n")
    lines = head.decode().splitlines()
    assert [ln.split()[3] for ln in lines if ln.startswith("comment kind")] == list(OBSTACLE_KINDS)
    v, f, owner = o.meshes()
    vert = np.frombuffer(body[: v.size * 8], "<f8").reshape(-1, 3)
    assert np.array_equal(vert, v)  # doubles: ENU to the bit
    face = np.frombuffer(
        body[v.size * 8 :],
        [("n", "u1"), ("v", "<i4", (3,)), ("rgb", "u1", (3,)), ("obstacle", "<i4"), ("kind", "u1")],
    )
    assert np.array_equal(face["v"], f) and np.array_equal(face["obstacle"], owner)
    kinds = np.array(OBSTACLE_KINDS)[face["kind"]]
    assert np.array_equal(kinds, o.kind[owner])
    assert all((face["rgb"][kinds == k] == KIND_RGB[k]).all() for k in OBSTACLE_KINDS)
    back = trimesh.load(out / "obstacles.ply", process=False)  # a standard reader takes it
    assert len(back.faces) == len(f)


def test_mesh_export_writes_obstacles_only_with_plants_and_obstacles(
    obstacle_hill, tmp_path
) -> None:
    scn, _ = obstacle_hill
    bare = dataclasses.replace(scn, obstacles=Obstacles.empty())
    opts = ExportOptions(formats=("glb", "obj", "ply", "dae"), mesh_plants=True)
    terrain_only = export_scenario(scn, "mesh", tmp_path / "terrain", ExportOptions())
    assert terrain_only["files"] == ["terrain.glb"]
    assert not (tmp_path / "terrain" / "obstacles.glb").exists()
    got = export_scenario(bare, "mesh", tmp_path / "bare", opts)
    assert not any(f.startswith("obstacles.") for f in got["files"])
    assert "Obstacles" not in (tmp_path / "bare" / "README.md").read_text()
    # the obstacle writers are reproducible: the same bytes twice
    from scenario_gen.export.obstacles import write_obstacle_mesh

    for fmt in ("glb", "obj", "ply", "dae"):
        write_obstacle_mesh(scn.obstacles, tmp_path / f"a.{fmt}")
        write_obstacle_mesh(scn.obstacles, tmp_path / f"b.{fmt}")
        assert filecmp.cmp(tmp_path / f"a.{fmt}", tmp_path / f"b.{fmt}", shallow=False), fmt


# ---------------------------------------------------------------------------- GIS
def _ogr(*cmd: str) -> str:
    r = subprocess.run([gdal(cmd[0]), *cmd[1:]], capture_output=True, text=True, check=False)
    assert r.returncode == 0 and "ERROR" not in r.stderr, (cmd, r.stderr)
    return r.stdout


def test_geopackage_obstacles_layer_read_back_by_gdal(obstacle_hill, tmp_path) -> None:
    import csv
    import io

    from shapely import wkt

    scn, src = obstacle_hill
    out = tmp_path / "gis"
    info = export(src, "gis", out, ExportOptions())
    o = scn.obstacles
    assert info["layers"]["obstacles"] == len(o)
    gpkg = str(out / "layers.gpkg")
    listing = _ogr("ogrinfo", "-so", "-q", gpkg)
    assert "obstacles (3D Polygon)" in listing
    assert f"Feature Count: {len(o)}" in _ogr("ogrinfo", "-so", gpkg, "obstacles")
    sql = "SELECT HasSpatialIndex('obstacles', 'geom')"
    assert "HasSpatialIndex (Integer) = 1" in _ogr("ogrinfo", "-q", gpkg, "-sql", sql)
    text = _ogr("ogr2ogr", "-f", "CSV", "/vsistdout/", gpkg, "obstacles", "-lco",
                "GEOMETRY=AS_WKT")  # fmt: skip
    rows = list(csv.DictReader(io.StringIO(text)))
    assert [int(r["obstacle_id"]) for r in rows] == list(range(len(o)))
    assert [r["kind"] for r in rows] == o.kind.tolist()
    for col, want, tol in (
        ("length_m", o.length, 1e-4), ("width_m", o.width, 1e-4), ("height_m", o.height, 1e-4),
        ("yaw", o.yaw, 1e-6), ("roll", o.roll, 1e-12), ("pitch", o.pitch, 1e-12),
        ("x_enu", o.x, 1e-12), ("y_enu", o.y, 1e-12), ("z_enu", o.z, 1e-12),
    ):  # fmt: skip
        np.testing.assert_allclose([float(r[col]) for r in rows], want, atol=tol, err_msg=col)
    # each polygon is the footprint: its corners' lon/lat back in ENU within 1 mm
    feet = o.footprints()
    for r, corners in zip(rows, feet, strict=True):
        ring = np.array(wkt.loads(r["WKT"]).exterior.coords)
        assert len(ring) == 5 and np.array_equal(ring[0], ring[-1])
        x, y, _ = scn.geo.geodetic_to_enu(ring[:4, 1], ring[:4, 0], ring[:4, 2])
        np.testing.assert_allclose(np.column_stack([x, y]), corners, atol=1e-3)
    # the GeoJSON copy converts to a Shapefile (one geometry type per file)
    _ogr("ogr2ogr", "-f", "ESRI Shapefile", str(tmp_path / "o.shp"), str(out / "obstacles.geojson"))
    assert f"Feature Count: {len(o)}" in _ogr("ogrinfo", "-so", "-al", str(tmp_path / "o.shp"))
    assert "`obstacles`" in (out / "README.md").read_text()


def test_gis_without_obstacles_has_no_obstacle_layer(obstacle_hill, tmp_path) -> None:
    scn, _ = obstacle_hill
    bare = dataclasses.replace(scn, obstacles=Obstacles.empty())
    info = export_scenario(bare, "gis", tmp_path / "bare", ExportOptions())
    assert "obstacles" not in info["layers"]
    assert not (tmp_path / "bare" / "obstacles.geojson").exists()
    assert "obstacles" not in _ogr("ogrinfo", "-so", "-q", str(tmp_path / "bare" / "layers.gpkg"))


# ---------------------------------------------------------------------------- previews
def _drawn_obstacles(fig) -> dict[str, np.ndarray]:
    """What a preview drew for each kind, by its legend label: marker centres (stones,
    litter) or line segments (stalks)."""
    from matplotlib.collections import LineCollection, PathCollection

    (ax, *_) = fig.axes
    out = {}
    for c in ax.collections:
        label = c.get_label()
        if isinstance(c, LineCollection) and label.startswith("fallen stalks"):
            out[label] = np.array(c.get_segments())
        elif isinstance(c, PathCollection) and label.startswith(("stones", "litter")):
            out[label] = np.asarray(c.get_offsets())
    return out


def test_previews_draw_each_kind_in_the_legend(obstacle_hill) -> None:
    from scenario_gen.preview import preview_figure

    scn, _ = obstacle_hill
    o = scn.obstacles
    n = o.counts()
    fig = preview_figure(scn)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    labels = [f"stones ({n['stone']})", f"litter ({n['litter']})", f"fallen stalks ({n['stalk']})"]
    assert set(labels) <= set(legend)
    drawn = _drawn_obstacles(fig)
    for label, kind in zip(labels, OBSTACLE_KINDS, strict=True):
        sel = o.kind == kind
        if kind == "stalk":
            seg = drawn[label]
            np.testing.assert_allclose(seg.mean(axis=1), np.column_stack([o.x, o.y])[sel])
            d = seg[:, 1] - seg[:, 0]  # along the stalk, its horizontal reach long
            np.testing.assert_allclose(np.arctan2(d[:, 1], d[:, 0]), o.yaw[sel], atol=1e-9)
            reach = o.length[sel] * np.cos(o.pitch[sel])
            np.testing.assert_allclose(np.hypot(*d.T), reach, rtol=1e-9)
        else:
            np.testing.assert_array_equal(drawn[label], np.column_stack([o.x, o.y])[sel])
    bare = dataclasses.replace(scn, obstacles=Obstacles.empty())
    assert not _drawn_obstacles(preview_figure(bare))


def test_gis_preview_draws_the_obstacles_it_read_back(obstacle_hill, tmp_path) -> None:
    from scenario_gen.export.preview import export_preview_figure

    scn, src = obstacle_hill
    out = tmp_path / "gis"
    export(src, "gis", out, ExportOptions())
    fig = export_preview_figure(scn, geotiff=out / "terrain.tif")
    drawn = _drawn_obstacles(fig)
    o = scn.obstacles
    stones = drawn[f"stones ({o.counts()['stone']})"]
    # the GeoPackage's footprints, projected back: on the obstacles to 1 mm
    np.testing.assert_allclose(stones, np.column_stack([o.x, o.y])[o.kind == "stone"], atol=1e-3)
    assert not np.array_equal(stones, np.column_stack([o.x, o.y])[o.kind == "stone"])
