from pathlib import Path

import numpy as np
import pytest

from scenario_gen import ScenarioError, generate
from scenario_gen.sources import export_terrain_mesh, load_mesh_vertices

from .helpers import small


@pytest.fixture(scope="module")
def source():
    # Real DEM relief plus furrows and roughness: a surface with centimetre detail to preserve.
    return generate(small(terrain={"margin": 6.0}), seed=0)


@pytest.mark.parametrize("suffix", [".glb", ".obj", ".ply"])
def test_mesh_round_trip_keeps_heights_within_2cm(source, tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"terrain{suffix}"
    export_terrain_mesh(source.terrain, path)
    g = source.geo
    spec = small(
        terrain={"source": "mesh", "path": str(path), "datum": [g.lat, g.lon, g.alt], "margin": 4.0}
    )
    # without adding a second layer of furrows and roughness on top of the exported ones
    base = generate(spec.replace({"furrows.enabled": False, "furrows.roughness": 0.0}), seed=0)
    x, y = np.meshgrid(base.terrain.xs, base.terrain.ys)
    dz = base.terrain.heights - source.terrain.height_at(x, y)
    assert np.abs(dz).max() < 0.02


def test_gltf_is_read_y_up(source, tmp_path: Path) -> None:
    path = tmp_path / "t.glb"
    export_terrain_mesh(source.terrain, path)
    v, _ = load_mesh_vertices(path)
    t = source.terrain
    assert v[:, 0].min() == pytest.approx(t.bounds[0]) and v[:, 1].max() == pytest.approx(
        t.bounds[3]
    )
    assert v[:, 2].max() == pytest.approx(t.heights.max())


def test_field_off_the_mesh_is_refused(source, tmp_path: Path) -> None:
    path = tmp_path / "t.ply"
    export_terrain_mesh(source.terrain, path)
    g = source.geo
    with pytest.raises(ScenarioError, match="off the terrain mesh"):
        generate(
            small(
                terrain={
                    "source": "mesh",
                    "path": str(path),
                    "datum": [g.lat, g.lon, g.alt],
                    "margin": 40.0,
                }
            ),
            seed=0,
        )


def test_mesh_needs_a_datum_and_a_mesh(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="terrain.datum"):
        generate(small(terrain={"source": "mesh", "path": str(tmp_path / "x.glb")}), seed=0)
    bad = tmp_path / "bad.obj"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(ScenarioError, match="terrain.path"):
        generate(
            small(terrain={"source": "mesh", "path": str(bad), "datum": [36.5, -84.1, 300.0]}),
            seed=0,
        )


# ----------------------------------------------------------------------------- mesh terrain
def _unmerged(terrain, path: Path) -> None:
    """The terrain as an STL: every triangle has its own three vertices (nothing shared)."""
    mesh = terrain.to_trimesh()
    mesh.export(path)


def _split_cell(t, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height of Terrain.to_trimesh's surface: each cell split along its (i, j)-(i+1, j+1)
    diagonal into two planar triangles (computed independently of the code under test)."""
    u, v = (x - t.x0) / t.spacing, (y - t.y0) / t.spacing
    j, i = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - j, v - i
    h = t.heights
    h00, h01, h10, h11 = h[i, j], h[i, j + 1], h[i + 1, j], h[i + 1, j + 1]
    upper = h00 + fu * (h01 - h00) + fv * (h11 - h01)  # triangle (00, 01, 11): fu >= fv
    lower = h00 + fv * (h10 - h00) + fu * (h11 - h10)  # triangle (00, 11, 10): fv > fu
    return np.where(fu >= fv, upper, lower)


def test_stl_terrain_without_shared_vertices_is_sampled_exactly(source, tmp_path: Path) -> None:
    path = tmp_path / "terrain.stl"
    _unmerged(source.terrain, path)
    v, faces = load_mesh_vertices(path)
    assert len(v) == 3 * len(faces)  # really unmerged: no triangle shares a vertex
    g = source.geo
    spec = small(
        terrain={
            "source": "mesh",
            "path": str(path),
            "datum": [g.lat, g.lon, g.alt],
            "margin": 4.0,
        },
        furrows={"enabled": False, "roughness": 0.0},
    )
    scn = generate(spec, seed=0)  # was refused: "lies off the terrain mesh"
    x, y = np.meshgrid(scn.terrain.xs, scn.terrain.ys)
    expect = _split_cell(source.terrain, x, y)
    # STL stores float32: 300 m heights keep 2e-5 m, x/y as much; the surface is otherwise exact
    np.testing.assert_allclose(scn.terrain.heights, expect, atol=1e-4)


def test_triangle_surface_is_barycentric_and_knows_what_it_covers() -> None:
    from scenario_gen.meshsurface import TriangleSurface
    from scenario_gen.terrain import Terrain

    rng = np.random.default_rng(0)
    t = Terrain(rng.normal(0.0, 0.3, (30, 40)), -5.0, 2.0, 0.5)
    mesh = t.to_trimesh()
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    unmerged = v[f].reshape(-1, 3)
    surf = TriangleSurface(unmerged, np.arange(len(unmerged)).reshape(-1, 3))
    x = rng.uniform(t.bounds[0], t.bounds[2], 20000)
    y = rng.uniform(t.bounds[1], t.bounds[3], 20000)
    z, covered = surf.heights(x, y)
    assert covered.all()
    np.testing.assert_allclose(z, _split_cell(t, x, y), atol=1e-12)
    # outside every triangle: not covered, no height
    z_off, covered_off = surf.heights(np.array([t.bounds[0] - 0.01, 0.0]), np.array([5.0, 1.99]))
    assert not covered_off.any() and np.isnan(z_off).all()


def test_mesh_with_a_hole_refuses_a_field_over_the_hole(source, tmp_path: Path) -> None:
    mesh = source.terrain.to_trimesh()
    centre = mesh.triangles_center
    cx, cy = np.mean(centre[:, 0]), np.mean(centre[:, 1])
    keep = np.hypot(centre[:, 0] - cx, centre[:, 1] - cy) > 1.0  # a 2 m hole mid-field
    mesh.update_faces(keep)
    path = tmp_path / "holed.ply"
    mesh.export(path)
    g = source.geo
    with pytest.raises(ScenarioError, match="no triangle under it"):
        generate(
            small(
                terrain={"source": "mesh", "path": str(path), "datum": [g.lat, g.lon, g.alt]},
                furrows={"enabled": False, "roughness": 0.0},
            ),
            seed=0,
        )


def _tile(z0: float = 0.0, offset: tuple[float, float] = (0.0, 0.0), n: int = 31) -> tuple:
    """A 60 × 60 m tile of z = 0.05 x + 0.02 y (+ z0), its vertices ``offset`` east, north."""
    s = np.linspace(-30.0, 30.0, n)
    x, y = np.meshgrid(s + offset[0], s + offset[1])
    v = np.column_stack([x.ravel(), y.ravel(), (0.05 * x + 0.02 * y).ravel() + z0])
    k = np.arange(n * n).reshape(n, n)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel()
    f = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return v, f


def _mesh_spec(path: Path, **terrain: object):  # type: ignore[no-untyped-def]
    t = {"source": "mesh", "path": str(path), "datum": [42.6, -5.57, 830.0], "margin": 2.0}
    return small(terrain=t | terrain).replace({"furrows.enabled": False, "furrows.roughness": 0.0})


def test_a_collada_terrain_honours_its_unit_and_up_axis(tmp_path: Path) -> None:
    """COLLADA files say their unit and up axis (SketchUp: inches, Maya: Y_UP): the tile in
    centimetres, y up, is the same ground as in metres, z up (it was read 100x too large, and
    a Y_UP file lay on its side)."""
    import trimesh

    from scenario_gen.sources import save_mesh

    v, f = _tile()
    plain = tmp_path / "m.dae"
    save_mesh(trimesh.Trimesh(v, f, process=False), plain)
    cm = tmp_path / "cm.dae"
    yup = np.column_stack([v[:, 0], v[:, 2], -v[:, 1]]) * 100.0
    text = trimesh.Trimesh(yup, f, process=False).export(file_type="dae").decode()
    assert "<up_axis>Y_UP</up_axis>" in text
    cm.write_text(text.replace("<asset>", '<asset><unit meter="0.01" name="centimeter"/>', 1))
    a, _ = load_mesh_vertices(plain)
    b, _ = load_mesh_vertices(cm)

    def rows(x: np.ndarray) -> np.ndarray:  # the writer may order vertices its own way
        return x[np.lexsort(np.round(x, 3).T[::-1])]

    assert np.allclose(rows(a), rows(v), atol=1e-4) and np.allclose(rows(b), rows(v), atol=1e-4)
    scn = generate(_mesh_spec(cm), seed=0)
    p = scn.plants
    assert np.allclose(p.z, 0.05 * p.x + 0.02 * p.y, atol=0.01)


def test_a_mesh_far_from_its_datum_is_refused_at_generation(tmp_path: Path) -> None:
    """A UTM-placed tile (or one 12 km up) made a folder that loading then refused; the frame
    is the datum's tangent plane, so it is refused when made, saying what to shift."""
    import trimesh

    for name, (v, f) in {
        "utm": _tile(offset=(500_000.0, 4_000_000.0)),
        "far": _tile(offset=(50_000.0, 0.0)),
        "high": _tile(z0=12_000.0),
    }.items():
        path = tmp_path / f"{name}.ply"
        trimesh.Trimesh(v, f, process=False).export(path)
        with pytest.raises(ScenarioError, match="terrain.path") as e:
            generate(_mesh_spec(path), seed=0)
        assert ("km from its origin" in str(e.value)) == (name != "high"), str(e.value)


def test_the_default_field_lies_on_the_meshs_ground_whatever_else_it_holds(
    tmp_path: Path,
) -> None:
    """An unused vertex 100 m off (PLY keeps them) moved the field 20 m, a stray triangle
    500 m off put it off the mesh: the field is laid out on the ground's own extent."""
    import trimesh

    v, f = _tile()
    clean = tmp_path / "clean.ply"
    trimesh.Trimesh(v, f, process=False).export(clean)
    ref = generate(_mesh_spec(clean), seed=0).plants
    stray = tmp_path / "stray.ply"
    extra = np.array(
        [[100.0, 0.0, 0.0], [500.0, 500.0, 0.0], [501.0, 500.0, 0.0], [500.0, 501.0, 0.0]]
    )
    n = len(v)
    trimesh.Trimesh(
        np.concatenate([v, extra]), np.concatenate([f, [[n + 1, n + 2, n + 3]]]), process=False
    ).export(stray)
    got = generate(_mesh_spec(stray), seed=0).plants
    assert abs(float(np.mean(got.x) - np.mean(ref.x))) < 1.0
    assert abs(float(np.mean(got.y) - np.mean(ref.y))) < 1.0


def test_a_point_cloud_or_a_quantized_gltf_is_refused_for_what_it_is(tmp_path: Path) -> None:
    import json
    import struct

    import trimesh

    cloud = tmp_path / "lidar.ply"
    trimesh.PointCloud(_tile()[0]).export(cloud)
    with pytest.raises(ScenarioError, match="a point cloud"):
        load_mesh_vertices(cloud)
    doc = {"asset": {"version": "2.0"}, "extensionsRequired": ["KHR_mesh_quantization"]}
    js = json.dumps(doc).encode() + b" " * (-len(json.dumps(doc)) % 4)
    glb = tmp_path / "q.glb"
    glb.write_bytes(
        struct.pack("<4sII", b"glTF", 2, 20 + len(js)) + struct.pack("<I4s", len(js), b"JSON") + js
    )
    with pytest.raises(ScenarioError, match="KHR_mesh_quantization") as e:
        load_mesh_vertices(glb)
    assert e.value.field == "terrain.path"


def test_a_second_layer_over_the_field_is_noted_and_taken_as_the_ground(tmp_path: Path) -> None:
    """A roof (or a crown, or a photogrammetry tile's crop) over the ground: the topmost
    surface is the ground, and a note says so; a one-layer tile gets no note."""
    import warnings

    import trimesh

    from scenario_gen.errors import Notice

    v, f = _tile()
    clean = tmp_path / "clean.ply"
    trimesh.Trimesh(v, f, process=False).export(clean)
    with warnings.catch_warnings():
        warnings.simplefilter("error", Notice)
        generate(_mesh_spec(clean), seed=0)
    roof = np.array([[-2.0, -2.0, 3.0], [2.0, -2.0, 3.0], [2.0, 2.0, 3.0], [-2.0, 2.0, 3.0]])
    n = len(v)
    shed = tmp_path / "shed.ply"
    trimesh.Trimesh(
        np.concatenate([v, roof]),
        np.concatenate([f, [[n, n + 1, n + 2], [n, n + 2, n + 3]]]),
        process=False,
    ).export(shed)
    with pytest.warns(Notice, match="stacked more than 0.5 m apart"):
        scn = generate(_mesh_spec(shed), seed=0)
    p = scn.plants
    # a grid cell (0.11 m) and more inside the roof's edge, where the terrain grid is all roof
    on_roof = (np.abs(p.x) < 1.75) & (np.abs(p.y) < 1.75)
    assert on_roof.any() and np.allclose(p.z[on_roof], 3.0, atol=0.01)
