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
