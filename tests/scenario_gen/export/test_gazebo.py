"""Gazebo worlds checked by libsdformat and lat/lon recomputed with ignition-math (Gazebo's own)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from scenario_gen import CATALOG, Scenario, load
from scenario_gen.export import ExportOptions, export
from scenario_gen.export import tiles as tiles_mod
from scenario_gen.export.plantmodels import SCALE_STEP, assign
from scenario_gen.export.tiles import rotations

from .tools import Check, ground_metres, quat_to_matrix, run_check, run_checks


@pytest.fixture(scope="module")
def included(hill, tmp_path_factory) -> tuple[Scenario, Path]:
    _, src = hill
    out = tmp_path_factory.mktemp("gz") / "include"
    export(src, "gazebo", out, ExportOptions(plants="include"))
    return load(src), out


@pytest.fixture(scope="module")
def tiled(hill, tmp_path_factory) -> tuple[Scenario, Path]:
    _, src = hill
    out = tmp_path_factory.mktemp("gz") / "tiles"
    export(src, "gazebo", out, ExportOptions(plants="tiles", tile_plants=4, heightmap=True))
    return load(src), out


@pytest.fixture(scope="module")
def checks(included, sdf_check) -> dict[str, Check]:
    _, out = included
    names = ("field.sdf", "field_classic.world")
    worlds = [out / "worlds" / w for w in names]
    return dict(zip(names, run_checks(sdf_check, worlds, out / "models"), strict=True))


def _plant_rows(scn: Scenario, check: Check) -> np.ndarray:
    names = [f"plant_{i:06d}" for i in range(len(scn.plants))]
    assert set(names) <= set(check.models)
    return np.array([check.models[n] for n in names])


def test_worlds_pass_the_sdformat_checks(checks, included) -> None:
    scn, _ = included
    for world, c in checks.items():
        assert c.returncode == 0 and c.valid, (world, c.stderr)
        assert len(c.models) == len(scn.plants) + 1  # plants and the terrain
        assert c.spherical[:3] == pytest.approx((scn.geo.lat, scn.geo.lon, scn.geo.alt), abs=1e-9)
    assert checks["field.sdf"].spherical[3] == 0.0
    assert checks["field_classic.world"].spherical[3] == 180.0
    # every mesh resolved to a file of this export
    assert all(Path(m).is_file() for m in checks["field.sdf"].meshes)


def test_navsat_latlon_matches_plants_csv(checks, included) -> None:
    """Gazebo Sim's NavSat formula (LOCAL2, heading 0) and Gazebo Classic's GPS formula
    (SphericalFromLocal, heading 180) both give plants.csv's lat/lon/alt within 1 cm."""
    scn, _ = included
    lat, lon, alt = scn.geo.enu_to_geodetic(scn.plants.x, scn.plants.y, scn.plants.z)
    sim = _plant_rows(scn, checks["field.sdf"])
    classic = _plant_rows(scn, checks["field_classic.world"])
    for rows, cols in ((sim, slice(7, 10)), (classic, slice(10, 13))):
        la, lo, al = rows[:, cols].T
        assert ground_metres(scn.geo.lat, la - lat, lo - lon).max() < 0.01
        assert np.abs(al - alt).max() < 0.01
    # the test can fail: Classic's formula on the heading-0 world puts plants at (-x, -y)
    la, lo, _ = sim[:, 10:13].T
    far = np.hypot(scn.plants.x, scn.plants.y) > 1.0
    assert far.sum() > 10
    assert ground_metres(scn.geo.lat, la - lat, lo - lon)[far].min() > 1.99


def test_sdf_pose_is_the_scenarios_rpy(checks, included) -> None:
    """libsdformat reads <pose> x y z roll pitch yaw as R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    scn, _ = included
    p = scn.plants
    rows = _plant_rows(scn, checks["field.sdf"])
    np.testing.assert_allclose(rows[:, :3], np.column_stack([p.x, p.y, p.z]), atol=1e-6)
    got = quat_to_matrix(rows[:, 3:7])
    want = rotations(p.roll, p.pitch, p.yaw)
    assert np.abs(got - want).max() < 1e-6
    assert np.abs(p.roll).max() > 0.15 and np.abs(p.pitch).max() > 0.15  # a real slope
    # the other order (Rx·Ry·Rz) would be told apart on this slope
    rx = rotations(p.roll, 0 * p.roll, 0 * p.roll)
    ry = rotations(0 * p.roll, p.pitch, 0 * p.roll)
    rz = rotations(0 * p.roll, 0 * p.roll, p.yaw)
    assert np.abs(got - rx @ ry @ rz).max() > 1e-2


def test_plant_sizes_and_stem_proxies(checks, included) -> None:
    scn, _ = included
    p = scn.plants
    a = assign(scn)
    nominal = np.array([m.height for m in a.models])[a.model]
    assert np.abs(nominal * a.scale / p.height - 1).max() <= (SCALE_STEP - 1) / 2 + 1e-9
    assert {m.species for m in a.models} == {"corn", "weed"}
    c = checks["field.sdf"]
    for i in np.flatnonzero(~p.is_weed)[:50]:
        x, y, z, *_, radius, length = c.collisions[f"plant_{i:06d}/stem"]
        pm = a.models[a.model[i]]
        assert radius == pytest.approx(pm.proxy_radius * a.scale[i], rel=1e-3)
        # the stalk circle agrinav_gym counts crop contact with, within the 1 % size binning
        sp = CATALOG[str(p.species[i])]
        g = sp.growth_of_stage(p.stage[i])
        assert radius == pytest.approx(sp.stem_radius(g) * p.height[i] / sp.height(g), rel=0.011)
        assert length == pytest.approx(pm.height * a.scale[i], rel=1e-3)
        axis = rotations(p.roll[i : i + 1], p.pitch[i : i + 1], p.yaw[i : i + 1])[0, :, 2]
        centre = np.array([p.x[i], p.y[i], p.z[i]]) + 0.5 * length * axis
        np.testing.assert_allclose([x, y, z], centre, atol=1e-5)
    weeds = np.flatnonzero(p.is_weed)
    assert len(weeds) and not any(f"plant_{i:06d}/stem" in c.collisions for i in weeds)


def test_collada_models_load_with_their_textures(included) -> None:
    import trimesh

    scn, out = included
    a = assign(scn)
    for pm in a.models:
        dae = out / "models" / pm.name / "meshes" / "plant.dae"
        # Gazebo's model layout keeps textures beside meshes/, so the DAE says ../materials
        where = trimesh.resolvers.FilePathResolver(dae, allow_anywhere=True)
        mesh = trimesh.load(dae, force="mesh", resolver=where)
        assert len(mesh.faces) == len(pm.mesh.faces)
        assert mesh.visual.kind == "texture"
        assert mesh.visual.material.baseColorTexture is not None
        np.testing.assert_allclose(mesh.bounds, pm.mesh.bounds, atol=1e-4)
    terrain = trimesh.load(out / "models/agrinav_terrain/meshes/terrain.dae", force="mesh")
    assert len(terrain.vertices) == scn.terrain.size
    assert terrain.bounds[1, 2] == pytest.approx(scn.terrain.heights.max(), abs=1e-4)


def test_heightmap_holds_the_terrain(tiled, sdf_check) -> None:
    from PIL import Image

    scn, out = tiled
    c = run_check(sdf_check, out / "worlds" / "field_heightmap.sdf", out / "models")
    assert c.returncode == 0 and c.valid, c.stderr
    img = np.asarray(
        Image.open(out / "models/agrinav_terrain_heightmap/materials/textures/heightmap.png")
    )
    n = img.shape[0]
    assert img.shape == (n, n) and img.dtype == np.uint16 and (n - 1) & (n - 2) == 0
    sdf = (out / "models/agrinav_terrain_heightmap/model.sdf").read_text()
    size = [float(v) for v in re.search(r"<size>([^<]+)</size>", sdf).group(1).split()]
    pos = [float(v) for v in re.search(r"<pos>([^<]+)</pos>", sdf).group(1).split()]
    # node (row r from the top = north, column c) -> ENU point, height by Gazebo's rule
    r, c = n - 1, n // 3  # southern edge, a third of the way east
    x = pos[0] - size[0] / 2 + c * size[0] / (n - 1)
    y = pos[1] + size[1] / 2 - r * size[1] / (n - 1)
    z = pos[2] + img[r, c] / 65535.0 * size[2]
    assert z == pytest.approx(float(scn.terrain.height_at(x, y)), abs=size[2] / 65535 + 1e-6)


def test_checker_catches_broken_worlds(included, sdf_check, tmp_path) -> None:
    _, out = included
    bad = tmp_path / "bad"
    shutil.copytree(out, bad)
    world = bad / "worlds" / "field.sdf"
    # the terrain and three plants: each check then takes a fraction of a second
    full = world.read_text()
    head, _, _ = full.partition("<include>")
    text = head + "\n".join(re.findall(r"<include>.*?</include>", full)[:4]) + "</world></sdf>"

    def check(t: str) -> Check:
        world.write_text(t)
        return run_check(sdf_check, world, bad / "models")

    dup = check(text.replace("<name>plant_000001</name>", "<name>plant_000000</name>"))
    assert dup.returncode != 0 and not dup.valid
    gone = check(text.replace("model://agrinav_terrain<", "model://agrinav_nothing<"))
    assert gone.returncode != 0 and "agrinav_nothing" in gone.stderr
    lat = check(text.replace("<latitude_deg>", "<latitude_deg>1", 1))  # 136.5°
    assert lat.returncode != 0 and "spherical" in lat.stderr
    pose = re.sub(r"(<name>plant_000000</name><pose>)[^<]+", r"\1nan 0 0 0 0 0", text)
    assert pose != text and check(pose).returncode != 0
    world.write_text(text)
    assert run_check(sdf_check, world, bad / "models").valid  # the cut-down world is fine
    (bad / "models/agrinav_terrain/materials/textures/soil.png").unlink()
    tex = run_check(sdf_check, world, bad / "models")
    assert tex.returncode != 0 and "soil.png" in tex.stderr
    (bad / "models/agrinav_terrain/materials/textures/soil.png").write_bytes(b"")
    first = re.search(r"model://([^<]+)</uri><name>plant_000000<", text).group(1)
    plant = bad / "models" / first / "model.sdf"
    plant.write_text(plant.read_text().replace("<radius>", "<radius>-"))
    neg = run_check(sdf_check, world, bad / "models")
    assert neg.returncode != 0 and "non-positive" in neg.stderr


def test_tiles_bake_every_plant(tiled, sdf_check) -> None:
    import trimesh

    scn, out = tiled
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.returncode == 0 and c.valid, c.stderr
    p = scn.plants
    tiles = [m for m in c.models if m.startswith("tile_")]
    assert len(tiles) >= 3 and len(c.models) == len(tiles) + 1
    assert not c.collisions  # no per-plant <collision>: see tiles.PRISM_SIDES
    a = assign(scn)
    faces = np.array([len(m.mesh.faces) for m in a.models])[a.model].sum()
    stl = [trimesh.load(f) for f in (out / "models").glob("agrinav_tile_*/meshes/colour*.stl")]
    assert sum(len(m.faces) for m in stl) == faces
    # each tile's collision is one mesh of stem prisms, in plant order, on each crop's axis
    prism = len(tiles_mod.prism())
    for tile in tiles_mod.make_tiles(scn, 4):
        crops = tile.plants[~p.is_weed[tile.plants]]
        stems = out / "models" / tile.name / "meshes" / "stems.stl"
        assert stems.is_file() == bool(len(crops))
        if not len(crops):
            continue
        tri = trimesh.load(stems).triangles.reshape(len(crops), prism, 3, 3)
        origin = c.models[tile.name.removeprefix("agrinav_")][:3]
        axis = rotations(p.roll, p.pitch, p.yaw)[crops, :, 2]
        base = np.column_stack([p.x, p.y, p.z])[crops]
        verts = tri.reshape(len(crops), -1, 3) + origin
        centre = np.array([np.unique(v.round(7), axis=0).mean(axis=0) for v in verts])
        np.testing.assert_allclose(centre, base + 0.5 * p.height[crops, None] * axis, atol=2e-5)
        rel = verts - base[:, None, :]
        along = np.einsum("kvi,ki->kv", rel, axis)
        np.testing.assert_allclose(along.max(axis=1), p.height[crops], atol=2e-5)
        across = np.linalg.norm(rel - along[..., None] * axis[:, None, :], axis=2).max(axis=1)
        r = np.array([a.models[a.model[i]].proxy_radius for i in crops])
        r *= p.height[crops] / np.array([a.models[a.model[i]].height for i in crops])
        np.testing.assert_allclose(across, r / np.cos(np.pi / tiles_mod.PRISM_SIDES), rtol=1e-4)
    # tile meshes are in their tile's frame: shifted by the include pose they cover the plants
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for folder in (out / "models").glob("agrinav_tile_*"):
        origin = c.models[folder.name.removeprefix("agrinav_")][:3]
        for f in (folder / "meshes").glob("colour*.stl"):
            b = trimesh.load(f).bounds + origin
            lo, hi = np.minimum(lo, b[0]), np.maximum(hi, b[1])
    reach = 1.0  # m: beyond the widest canopy here (V10 corn, ≈0.8 m across)
    assert (lo[:2] > np.array([p.x.min(), p.y.min()]) - reach).all()
    assert (hi[:2] < np.array([p.x.max(), p.y.max()]) + reach).all()
    assert hi[2] == pytest.approx((p.z + p.height).max(), abs=0.5)


def test_user_model_keeps_its_texture(tmp_path, sdf_check) -> None:
    """crop.model: a textured glTF plant becomes the base model, texture and all."""
    import trimesh
    from PIL import Image

    # two crossed quads 1 m tall, Y up as glTF wants, red below and green above; glTF's
    # texels are baseColorFactor × the image: a factor of 1 keeps the image's colours
    # (trimesh's default material would write 0.4)
    img = Image.new("RGB", (4, 4), (200, 30, 30))
    img.paste((30, 160, 40), (0, 0, 4, 2))  # the image's top half: high v
    model = _quads_glb(tmp_path / "plant.glb", img)
    src = _quads_scenario(tmp_path, model)
    scn = load(src)
    out = tmp_path / "gz"
    export(src, "gazebo", out, ExportOptions(plants="include"))
    (base,) = [m for m in assign(scn).models if m.species == "corn"]
    # the scenario folder carries its own byte-identical copy of the model (models/)
    copy = Path(base.source)
    assert base.name.startswith("agrinav_plant_corn") and copy.name == model.name
    assert copy.read_bytes() == model.read_bytes()
    dae = out / "models" / base.name / "meshes" / "plant.dae"
    where = trimesh.resolvers.FilePathResolver(dae, allow_anywhere=True)
    mesh = trimesh.load(dae, force="mesh", resolver=where)
    tex = np.asarray(mesh.visual.material.baseColorTexture.convert("RGB"))
    assert tex.shape == (4, 4, 3) and (tex == np.asarray(img)).all()
    assert mesh.bounds[1, 2] == pytest.approx(base.height, rel=1e-4)  # Z up, nominal height
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.valid, c.stderr
    # in tiles the texture becomes flat colours: both halves of the image survive
    tiled = tmp_path / "tiles"
    export(src, "gazebo", tiled, ExportOptions(plants="tiles"))
    sdf = next(tiled.glob("models/agrinav_tile_*/model.sdf")).read_text()
    for rgb in ((200, 30, 30), (30, 160, 40)):
        assert "<diffuse>" + " ".join(f"{c / 255:.4f}" for c in rgb) + " 1.0000" in sdf


CUTOUT = Path(__file__).resolve().parents[2] / "data" / "crop_models" / "cutout_plant"


def _pose_scale(sdf: str, uri: str) -> list[tuple[np.ndarray, float]]:
    """(pose, scale) of every visual of ``sdf`` naming ``uri``."""
    out = []
    for m in re.finditer(
        r"<pose>([^<]+)</pose><geometry><mesh><uri>" + re.escape(uri) + r"</uri>"
        r"<scale>([^ <]+)",
        sdf,
    ):
        out.append((np.array(m.group(1).split(), float), float(m.group(2))))
    return out


def test_user_collada_model_is_referenced_with_its_textures(tmp_path, sdf_check) -> None:
    """crop.model in Gazebo's own layout (meshes/plant.dae naming ../materials/textures/*.png)
    is exported as those files, byte for byte, and every plant's visual names that mesh with
    the pose and scale that stand it on the plant, the plant's height tall — in include mode
    and in merged tiles alike; libsdformat finds the mesh and the textures it names."""
    import trimesh

    from scenario_gen import generate, save

    from ..helpers import plane

    src = tmp_path / "user"
    shutil.copytree(CUTOUT, src)
    spec = plane(
        field={"width": 3.0, "length": 3.6},
        layout={"headland": 0.8, "plant_spacing": 0.5},
        terrain={"margin": 2.5},
        route={"lead_in": 0.8},
        crop={"model": str(src / "meshes" / "plant.dae")},
    )
    save(generate(spec, 2), tmp_path / "scn", preview=False)
    scn = load(tmp_path / "scn")
    out = tmp_path / "gz"
    export(tmp_path / "scn", "gazebo", out, ExportOptions(plants="include"))
    a = assign(scn)
    (base,) = [m for m in a.models if m.species == "corn"]
    assert base.user is not None and base.user.mesh == "user/meshes/plant.dae"
    folder = out / "models" / base.name
    for rel in ("meshes/plant.dae", "materials/textures/leaf.png", "materials/textures/stem.png"):
        assert (folder / "user" / rel).read_bytes() == (CUTOUT / rel).read_bytes(), rel
    assert not (folder / "meshes").exists()  # not flattened into a mesh of our own
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.valid, c.stderr
    assert str(folder / "user" / "meshes" / "plant.dae") in [str(Path(m)) for m in c.meshes]
    # the visual stands the mesh on the model's origin, as tall as the variant's plants
    dae = folder / "user" / "meshes" / "plant.dae"
    native = trimesh.load(dae, force="mesh", resolver=trimesh.resolvers.FilePathResolver(dae))
    uri = f"model://{base.name}/user/meshes/plant.dae"
    for m, step in a.variants():
        if a.models[m] is not base:
            continue
        sdf = (out / "models" / base.variant(step) / "model.sdf").read_text()
        ((pose, s),) = _pose_scale(sdf, uri)
        assert np.allclose(pose[3:], 0.0)
        lo, hi = native.bounds * s + pose[:3]
        assert lo[2] == pytest.approx(0.0, abs=1e-5)
        assert hi[2] == pytest.approx(base.height * SCALE_STEP**step, rel=1e-5)
        # on its stem's foot (the test plant's stem stands at x 0.05 in its file, its leaf
        # quad at 0), not on its bounding box's centre
        foot = np.array([0.05, 0.0]) * s + pose[:2]
        assert np.allclose(foot, 0.0, atol=1e-5), foot
    # merged tiles: the user's plants stay visuals of that mesh, none is flattened into STL
    tiled = tmp_path / "tiles"
    export(tmp_path / "scn", "gazebo", tiled, ExportOptions(plants="tiles", tile_plants=4))
    c = run_check(sdf_check, tiled / "worlds" / "field.sdf", tiled / "models")
    assert c.valid, c.stderr
    p = scn.plants
    crops = np.flatnonzero(~p.is_weed)
    found = {}
    for tile in (tiled / "models").glob("agrinav_tile_*"):
        sdf = (tile / "model.sdf").read_text()
        origin = c.models[tile.name.removeprefix("agrinav_")][:3]
        for i, (pose, s) in zip(
            [int(k) for k in re.findall(r'<visual name="plant_(\d+)"', sdf)],
            _pose_scale(sdf, uri),
            strict=True,
        ):
            found[i] = (pose[:3] + origin, pose[3:], s)
    assert sorted(found) == crops.tolist()
    for i in crops:
        xyz, rpy, s = found[i]
        r = rotations(np.array([rpy[0]]), np.array([rpy[1]]), np.array([rpy[2]]))[0]
        corners = np.array(np.meshgrid(*native.bounds.T, indexing="ij")).reshape(3, -1).T
        world = (r @ (corners * s).T).T + xyz
        assert s * float(np.ptp(native.bounds[:, 2])) == pytest.approx(p.height[i], rel=1e-5)
        # the mesh's stem foot lies on the plant's base point, its axis along the plant's
        foot = np.array([0.05, 0.0, native.bounds[0, 2]])
        assert np.allclose(r @ (foot * s) + xyz, [p.x[i], p.y[i], p.z[i]], atol=1e-4)
        want = rotations(p.roll[i : i + 1], p.pitch[i : i + 1], p.yaw[i : i + 1])[0]
        assert np.allclose(r, want, atol=1e-6)
        top = (world - xyz) @ want[:, 2]  # heights of the box corners along the plant's axis
        assert top.max() - top.min() == pytest.approx(p.height[i], rel=1e-5)


def _quads_glb(path: Path, image: Any, mode: str | None = None) -> Path:
    """Two crossed quads 1 m tall (glTF's Y up) textured with ``image``: each quad's lower
    triangle samples the image's lower half, its upper triangle the upper half."""
    import trimesh

    v = [[-0.1, 0, 0], [0.1, 0, 0], [0.1, 1, 0], [-0.1, 1, 0]]
    v += [[0, 0, -0.1], [0, 0, 0.1], [0, 1, 0.1], [0, 1, -0.1]]
    f = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]] * 2, float)
    pbr = trimesh.visual.material.PBRMaterial(
        baseColorTexture=image, baseColorFactor=[1.0] * 4, alphaMode=mode
    )
    visual = trimesh.visual.TextureVisuals(uv=uv, material=pbr)
    trimesh.Trimesh(np.array(v, float), f, visual=visual, process=False).export(path)
    return path


def _quads_scenario(tmp_path: Path, model: Path) -> Path:
    from scenario_gen import generate, save

    from ..helpers import plane

    spec = plane(
        field={"width": 3.0, "length": 3.6},
        layout={"headland": 0.8, "plant_spacing": 0.5},
        terrain={"margin": 2.5},
        route={"lead_in": 0.8},
        crop={"model": str(model)},
    )
    save(generate(spec, 2), tmp_path / "scn", preview=False)
    return tmp_path / "scn"


def test_a_cut_out_model_keeps_its_alpha_and_is_never_painted_its_hidden_colour(
    tmp_path: Path,
) -> None:
    """A leaf whose upper half is cut out (alpha 0 over a magenta the cameras never show): the
    converted Gazebo model keeps the texture's alpha and declares it (gz-common's COLLADA
    loader alpha-tests a ``<transparent>`` texture); flat-colour copies (merged tiles, the mesh
    export) leave the cut-out faces out instead of painting them magenta."""
    from PIL import Image

    img = Image.new("RGBA", (4, 4), (30, 160, 40, 255))
    img.paste((255, 0, 255, 0), (0, 0, 4, 2))  # the image's top half: high v, cut out
    src = _quads_scenario(tmp_path, _quads_glb(tmp_path / "leaf.glb", img, "MASK"))
    scn = load(src)
    out = tmp_path / "gz"
    export(src, "gazebo", out, ExportOptions(plants="include"))
    (base,) = [m for m in assign(scn).models if m.species == "corn"]
    folder = out / "models" / base.name
    with Image.open(folder / "materials" / "textures" / "plant.png") as png:
        rgba = np.asarray(png.convert("RGBA"))
        assert png.mode == "RGBA" and (rgba[..., 3] == 0).any()
    assert '<transparent opaque="A_ONE">' in (folder / "meshes" / "plant.dae").read_text()
    tiled = tmp_path / "tiles"
    export(src, "gazebo", tiled, ExportOptions(plants="tiles"))
    sdf = next(tiled.glob("models/agrinav_tile_*/model.sdf")).read_text()
    assert "<diffuse>1.0000 0.0000 1.0000" not in sdf and "<diffuse>0.1176 0.6275" in sdf
    mesh_out = tmp_path / "mesh"
    export(src, "mesh", mesh_out, ExportOptions(mesh_plants=True, formats=("ply",)))
    import trimesh

    ply = trimesh.load(mesh_out / "plants.ply", process=False)
    colours = np.unique(np.asarray(ply.visual.face_colors)[:, :3], axis=0)
    assert colours.tolist() == [[30, 160, 40]]


def test_merged_plants_in_glb_and_obj_keep_one_colour_per_face(tmp_path: Path) -> None:
    """glTF and OBJ colour vertices, not faces: a leaf red below and green above, whose two
    triangles share an edge, is written with no vertex shared by the two colours (a shared
    one was blended into a brown no face had)."""
    import trimesh
    from PIL import Image

    img = Image.new("RGB", (4, 4), (200, 30, 30))
    img.paste((30, 160, 40), (0, 0, 4, 2))
    src = _quads_scenario(tmp_path, _quads_glb(tmp_path / "plant.glb", img))
    out = tmp_path / "mesh"
    export(src, "mesh", out, ExportOptions(mesh_plants=True, formats=("glb", "obj")))
    for name in ("plants.glb", "plants.obj"):
        mesh = trimesh.load(out / name, force="mesh", process=False)
        corner = np.asarray(mesh.visual.vertex_colors)[np.asarray(mesh.faces)][..., :3]
        assert (corner == corner[:, :1]).all(), name  # one colour per face
        got = {tuple(c) for c in corner[:, 0].tolist()}
        assert got == {(200, 30, 30), (30, 160, 40)}, name


def test_a_user_model_named_outside_uri_characters_is_renamed_in_its_uri(
    tmp_path: Path, sdf_check
) -> None:
    """gz-common's URIPath::Valid refuses non-ASCII bytes (older releases spaces too): an OBJ
    named ``my plänt é.obj`` is exported as ``user/my_pl_nt__.obj``, its material library and
    texture beside it as they were, and libsdformat resolves the mesh."""
    src = tmp_path / "model"
    shutil.copytree(
        Path(__file__).resolve().parents[2] / "data" / "crop_models" / "textured_obj", src
    )
    obj = src / "my plänt é.obj"
    (src / "plant.obj").rename(obj)
    scn_dir = _quads_scenario(tmp_path, obj)
    out = tmp_path / "gz"
    export(scn_dir, "gazebo", out, ExportOptions(plants="include"))
    (base,) = [m for m in assign(load(scn_dir)).models if m.species == "corn"]
    assert base.user is not None and base.user.mesh == "user/my_pl_nt__.obj"
    folder = out / "models" / base.name / "user"
    assert sorted(p.name for p in folder.iterdir()) == ["my_pl_nt__.obj", "plant.mtl", "plant.png"]
    assert (folder / "my_pl_nt__.obj").read_bytes() == obj.read_bytes()
    sdf = (out / "models" / base.name / "model.sdf").read_text()
    assert f"model://{base.name}/user/my_pl_nt__.obj" in sdf and "plänt" not in sdf
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.valid, c.stderr


def test_references_a_loader_may_not_read_as_written_are_renamed_with_their_files(
    tmp_path: Path, sdf_check
) -> None:
    """A COLLADA texture written ``leaf%20tex.png`` (a URI, for ``leaf tex.png``) and an OBJ's
    ``mtllib my mat.mtl`` naming ``map_Kd leaf tex.png``: not every loader decodes the one or
    keeps the spaces of the other (the export's own checker did neither). The copies and their
    references take literal names, and the world checks."""
    from ..helpers import url_encoded_leaf

    dae = url_encoded_leaf(CUTOUT, tmp_path / "dae")
    obj_src = tmp_path / "obj"
    shutil.copytree(
        Path(__file__).resolve().parents[2] / "data" / "crop_models" / "textured_obj", obj_src
    )
    (obj_src / "plant.mtl").rename(obj_src / "my mat.mtl")
    (obj_src / "plant.png").rename(obj_src / "leaf tex.png")
    obj = obj_src / "plant.obj"
    obj.write_text(obj.read_text().replace("mtllib plant.mtl", "mtllib my mat.mtl"))
    mtl = obj_src / "my mat.mtl"
    mtl.write_text(mtl.read_text().replace("map_Kd plant.png", "map_Kd leaf tex.png"))
    expect = {
        "d": {"meshes/plant.dae": "<init_from>../materials/textures/leaf_tex.png</init_from>"},
        "o": {"plant.obj": "mtllib my_mat.mtl", "my_mat.mtl": "map_Kd leaf_tex.png"},
    }
    for mesh, name in ((dae, "d"), (obj, "o")):
        scn_dir = _quads_scenario(tmp_path / name, mesh)
        out = tmp_path / name / "gz"
        export(scn_dir, "gazebo", out, ExportOptions(plants="include"))
        (base,) = [m for m in assign(load(scn_dir)).models if m.species == "corn"]
        user = out / "models" / base.name / "user"
        files = sorted(str(p.relative_to(user)) for p in user.rglob("*") if p.is_file())
        assert not [f for f in files if " " in f or "%" in f], files
        for rel, line in expect[name].items():
            assert line in (user / rel).read_text(), (rel, line)
        c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
        assert c.valid, c.stderr


def test_a_texture_folder_named_outside_literal_characters_gets_a_literal_copy(
    tmp_path: Path, sdf_check
) -> None:
    """``../materials/tex tures/leaf.png``: a folder with a space is as unreadable to some
    loaders as a file name with one; the texture is copied into a literal folder beside it
    and the reference names the copy (the original stays for whatever else names it)."""
    src = tmp_path / "user"
    shutil.copytree(CUTOUT, src)
    (src / "materials" / "textures").rename(src / "materials" / "tex tures")
    dae = src / "meshes" / "plant.dae"
    dae.write_text(dae.read_text().replace("textures/", "tex%20tures/"))
    scn_dir = _quads_scenario(tmp_path, dae)
    out = tmp_path / "gz"
    export(scn_dir, "gazebo", out, ExportOptions(plants="include"))
    (base,) = [m for m in assign(load(scn_dir)).models if m.species == "corn"]
    user = out / "models" / base.name / "user"
    text = (user / "meshes" / "plant.dae").read_text()
    assert "<init_from>../materials/tex_tures/leaf.png</init_from>" in text
    assert "<init_from>../materials/tex_tures/stem.png</init_from>" in text
    for name in ("leaf.png", "stem.png"):
        copied = user / "materials" / "tex_tures" / name
        assert copied.read_bytes() == (src / "materials" / "tex tures" / name).read_bytes()
    c = run_check(sdf_check, out / "worlds" / "field.sdf", out / "models")
    assert c.valid, c.stderr
