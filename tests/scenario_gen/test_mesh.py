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
