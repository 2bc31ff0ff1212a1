"""crop.model is part of the scenario: recorded, copied, loaded from the copy, previewed; a zip
with two meshes is refused."""

import dataclasses
import hashlib
import json
import re
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from scenario_gen import CATALOG, ScenarioError, generate, load, save
from scenario_gen.models import inspect_model, load_model
from scenario_gen.preview import preview_figure

from ..data.crop_models.make_models import CUT, LEAF, OBJ_RGB, STEM
from .helpers import small, url_encoded_leaf

DATA = Path(__file__).resolve().parents[1] / "data" / "crop_models"
CUTOUT = DATA / "cutout_plant"


def _plant_obj(height: float = 3.0, radius: float = 0.2) -> bytes:
    import trimesh

    mesh = trimesh.creation.cone(radius=radius, height=height)
    return trimesh.exchange.obj.export_obj(mesh).encode()


@pytest.fixture
def model_zip(tmp_path: Path) -> Path:
    p = tmp_path / "user" / "plant.zip"
    p.parent.mkdir()
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meshes/plant.obj", _plant_obj())
        zf.writestr("textures/leaf.png", b"\x89PNG not really")
    return p


@pytest.fixture
def model_obj(tmp_path: Path) -> Path:
    p = tmp_path / "user" / "cone.obj"
    p.parent.mkdir(exist_ok=True)
    p.write_bytes(_plant_obj(2.0, 0.3))
    return p


@pytest.mark.parametrize("kind", ["zip", "obj"])
def test_model_is_recorded_copied_and_loaded_from_the_copy(
    kind: str, model_zip: Path, model_obj: Path, tmp_path: Path
) -> None:
    src = model_zip if kind == "zip" else model_obj
    scn = generate(small(crop={"model": str(src)}), seed=0)
    digest = hashlib.sha256(src.read_bytes()).hexdigest()
    assert scn.crop_model is not None and scn.crop_model_path == src.resolve()
    out = save(scn, tmp_path / "scn")
    meta = json.loads((out / "scenario.json").read_text())
    rec = meta["crop_model"]
    assert rec["file"] == f"models/{src.name}" and rec["sha256"] == digest
    assert rec["source"] == str(src.resolve())
    assert rec["mesh"] == ("meshes/plant.obj" if kind == "zip" else "cone.obj")
    expect_h = 3.0 if kind == "zip" else 2.0
    assert rec["native_size"][2] == pytest.approx(expect_h)
    assert "plant height / native_size[2]" in rec["scale"]
    assert (out / rec["file"]).read_bytes() == src.read_bytes()
    # the original may go away: the scenario keeps its own copy
    shutil.rmtree(src.parent)
    back = load(out)
    assert back.crop_model_path == (out / rec["file"]).resolve()
    assert back.spec.crop.model == str(back.crop_model_path)
    m = load_model(back.crop_model_path, height=1.5)
    assert m.bounds[1, 2] - m.bounds[0, 2] == pytest.approx(1.5)


def test_model_changes_the_outputs(model_zip: Path, tmp_path: Path) -> None:
    plain = save(generate(small(), 0), tmp_path / "a")
    with_model = save(generate(small(crop={"model": str(model_zip)}), 0), tmp_path / "b")
    for name in ("scenario.json", "preview.png"):
        assert (plain / name).read_bytes() != (with_model / name).read_bytes(), name
    assert (with_model / "models" / "plant.zip").is_file()


def test_preview_shows_the_model(model_obj: Path) -> None:
    scn = generate(small(crop={"model": str(model_obj)}), seed=0)
    fig = preview_figure(scn)
    insets = [a for a in fig.axes if "crop.model\ncone.obj" in a.get_title()]
    assert len(insets) == 1
    assert "native 0.6 x 0.6 x 2\n" in insets[0].get_title()
    assert len(insets[0].collections[0].get_paths()) > 10  # the model's faces are drawn


def test_loaded_copy_is_checked_against_its_hash(model_obj: Path, tmp_path: Path) -> None:
    out = save(generate(small(crop={"model": str(model_obj)}), seed=0), tmp_path / "s")
    with open(out / "models" / "cone.obj", "ab") as f:
        f.write(b"# tampered\n")
    with pytest.raises(ScenarioError, match="does not match its SHA-256"):
        load(out)


def test_model_changed_between_generate_and_save_is_refused(
    model_obj: Path, tmp_path: Path
) -> None:
    scn = generate(small(crop={"model": str(model_obj)}), seed=0)
    model_obj.write_bytes(_plant_obj(5.0))
    with pytest.raises(ScenarioError, match="changed since"):
        save(scn, tmp_path / "s")
    assert not (tmp_path / "s").exists()


def test_zip_with_two_meshes_is_refused_naming_both(tmp_path: Path) -> None:
    p = tmp_path / "two.zip"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("a/stalk.obj", _plant_obj())
        zf.writestr("b/leaf.ply", b"ply\n")
    with pytest.raises(ScenarioError) as info:
        inspect_model(p)
    assert info.value.field == "crop.model"
    assert "a/stalk.obj" in str(info.value) and "b/leaf.ply" in str(info.value)
    with pytest.raises(ScenarioError, match="2 meshes"):
        load_model(p, 1.0)


@pytest.mark.parametrize(
    "name,text,ref",
    [
        ("plant.obj", "mtllib plant.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n", "plant.mtl"),
        (
            "plant.gltf",
            json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "plant.bin"}]}),
            "plant.bin",
        ),
        ("plant.dae", None, "../materials/textures/leaf.png"),
    ],
)
def test_a_model_whose_files_are_missing_is_refused_naming_them(
    tmp_path: Path, name: str, text: str | None, ref: str
) -> None:
    p = tmp_path / "meshes" / name
    p.parent.mkdir()
    if text is None:  # the test plant's COLLADA file without its textures
        shutil.copy(CUTOUT / "meshes" / "plant.dae", p)
    else:
        p.write_text(text)
    with pytest.raises(ScenarioError, match=rf"references {re.escape(ref)}.* missing") as info:
        inspect_model(p)
    assert "\n" not in str(info.value)  # one line
    with pytest.raises(ScenarioError, match=re.escape(ref)):
        load_model(p, 1.0)


def test_references_by_absolute_path_or_far_above_are_refused(tmp_path: Path) -> None:
    deep = tmp_path / "a" / "b" / "c" / "d"
    deep.mkdir(parents=True)
    (tmp_path / "x.png").write_bytes((CUTOUT / "materials/textures/stem.png").read_bytes())
    for ref, why in ((str(tmp_path / "x.png"), "absolute"), ("../../../../x.png", "outside")):
        mtl = deep / "plant.mtl"
        mtl.write_text(f"newmtl a\nmap_Kd {ref}\n")
        obj = deep / "plant.obj"
        obj.write_bytes(b"mtllib plant.mtl\n" + _plant_obj())
        with pytest.raises(ScenarioError, match=why):
            inspect_model(obj)


def test_a_collada_model_is_kept_with_its_textures_in_their_folders(tmp_path: Path) -> None:
    """Gazebo's layout (meshes/plant.dae naming ../materials/textures/*.png) is copied whole,
    each file checked against its hash, and the copy is what loads once the original is gone."""
    src = tmp_path / "user" / "cutout_plant"
    shutil.copytree(CUTOUT, src)
    scn = generate(small(crop={"model": str(src / "meshes" / "plant.dae")}), seed=0)
    out = save(scn, tmp_path / "scn", preview=False)
    rec = json.loads((out / "scenario.json").read_text())["crop_model"]
    assert rec["file"] == "models/plant/meshes/plant.dae"
    assert rec["mesh"] == "meshes/plant.dae"
    names = sorted(f["path"] for f in rec["files"])
    assert names == ["materials/textures/leaf.png", "materials/textures/stem.png"]
    for f in rec["files"]:
        copy = out / "models" / "plant" / f["path"]
        assert copy.read_bytes() == (src / f["path"]).read_bytes()
        assert hashlib.sha256(copy.read_bytes()).hexdigest() == f["sha256"]
    shutil.rmtree(src)
    back = load(out)
    assert back.crop_model is not None and back.crop_model.files == scn.crop_model.files
    mesh = load_model(back.crop_model_path, 1.0)
    assert mesh.visual.material.image is not None  # the textures were found beside the copy
    (out / "models/plant/materials/textures/leaf.png").write_bytes(b"\x89PNG tampered")
    with pytest.raises(ScenarioError, match="leaf.png.*SHA-256"):
        load(out)
    (out / "models/plant/materials/textures/leaf.png").unlink()
    with pytest.raises(ScenarioError, match="leaf.png"):
        load(out)


def test_an_obj_is_kept_with_its_material_library_and_texture(tmp_path: Path) -> None:
    src = tmp_path / "obj"
    shutil.copytree(DATA / "textured_obj", src)
    out = save(generate(small(crop={"model": str(src / "plant.obj")}), 0), tmp_path / "s")
    assert sorted(p.name for p in (out / "models" / "plant").iterdir()) == [
        "plant.mtl",
        "plant.obj",
        "plant.png",
    ]
    shutil.rmtree(src)
    mesh = load_model(load(out).crop_model_path, 1.0)
    tex = np.asarray(mesh.visual.material.image.convert("RGB"))
    assert (tex.reshape(-1, 3) == OBJ_RGB).all(axis=1).any()


def test_texture_colours_are_the_files(tmp_path: Path) -> None:
    """Two parts with a texture each: every face keeps its own texture's colour (trimesh's own
    packing multiplied the texels by 255: green maize came out purple), and the leaf's cut-out
    texels are transparent in the atlas."""
    mesh = load_model(CUTOUT / "meshes" / "plant.dae", 1.0)
    image = np.asarray(mesh.visual.material.image)
    uv = np.asarray(mesh.visual.uv)[np.asarray(mesh.faces)].mean(axis=1)
    h, w = image.shape[:2]
    texel = image[
        np.clip(((1 - uv[:, 1]) * h).astype(int), 0, h - 1),
        np.clip((uv[:, 0] * w).astype(int), 0, w - 1),
    ]
    centre = np.asarray(mesh.triangles_center)
    leaf = centre[:, 0] < -0.02  # the quad, 4-6 cm in front of the stalk (base centred)
    assert (texel[leaf, :3] == LEAF).all() and (texel[~leaf, :3] == STEM).all()
    assert (texel[:, 3] == 255).all()  # face centres lie on opaque texels
    rgba = image.reshape(-1, 4)
    assert (rgba[rgba[:, 3] == 0, :3] == CUT).all(axis=1).any()  # the cut-out is kept


@pytest.mark.parametrize("scale", ["stage", "native"])
def test_model_scale_native_keeps_the_files_size(scale: str) -> None:
    model = str(DATA / "textured_obj" / "plant.obj")  # 0.5 m tall
    spec = small(crop={"model": model, "model_scale": scale, "stage": 3, "height_std": 0.0})
    scn = generate(spec, 0)
    crop = ~scn.plants.is_weed
    stage_height = float(CATALOG["corn"].height(CATALOG["corn"].growth_of_stage(3)))
    want = 0.5 if scale == "native" else stage_height
    assert np.allclose(scn.plants.height[crop], want)
    assert scn.crop_model is not None and scn.crop_model.scale == scale
    assert scn.crop_model.to_dict()["model_scale"] == scale


@pytest.mark.parametrize("height", [1500.0, 1e-7])
def test_a_native_size_no_plant_has_is_refused_before_anything_is_written(
    tmp_path: Path, height: float
) -> None:
    """A model in millimetres kept at its size wrote a scenario its own loader refused."""
    w = 0.1 * height
    model = tmp_path / "mm.obj"
    model.write_text(
        f"v 0 0 0\nv {w} 0 0\nv 0 {w} 0\nv 0 0 {height}\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    )
    spec = small(crop={"model": str(model), "model_scale": "native"})
    with pytest.raises(ScenarioError, match="crop.model") as info:
        generate(spec, 0)
    assert "model_scale stage" in str(info.value)
    generate(small(crop={"model": str(model), "model_scale": "stage"}), 0)  # scaled: fine


def test_plant_heights_stay_positive_over_the_whole_height_spread() -> None:
    """Heights are drawn within 3 std: a std above 1/3 wrote negative heights."""
    with pytest.raises(ScenarioError, match="crop.height_std"):
        small(crop={"height_std": 0.5})
    scn = generate(small(crop={"height_std": 0.3}), 0)
    assert scn.plants.height.min() > 0


def test_flat_or_empty_models_are_refused(tmp_path: Path) -> None:
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ScenarioError, match="flat"):
        inspect_model(flat)
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 1\nf 1 2 3\n")
    with pytest.raises(ScenarioError, match="crop.model"):
        inspect_model(nan)
    assert np.isfinite(inspect_model(_write(tmp_path / "ok.obj", _plant_obj())).size).all()


def test_a_model_with_some_nan_vertices_is_refused_not_trimmed(tmp_path: Path) -> None:
    """trimesh's processing drops the faces on a NaN vertex: the model used to load with a
    part missing and no word."""
    part = tmp_path / "part.obj"
    tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    part.write_text(tetra + "v nan 0 0.5\nf 1 2 5\n")
    with pytest.raises(ScenarioError, match=r"crop.model.*NaN or infinite coordinates in 1 of"):
        inspect_model(part)
    part.write_text(tetra)  # the same model without it loads
    assert inspect_model(part).size[2] > 0


def _write(p: Path, data: bytes) -> Path:
    p.write_bytes(data)
    return p


def test_models_over_the_triangle_budget_or_without_area_are_refused(tmp_path: Path) -> None:
    from scenario_gen.models import MAX_MODEL_TRIANGLES

    n = MAX_MODEL_TRIANGLES + 1  # identical triangles: an 800 kB file, minutes per frame
    many = tmp_path / "many.obj"
    many.write_text("v 0 0 0\nv 1 0 0\nv 0 1 1\n" + "f 1 2 3\n" * n)
    with pytest.raises(ScenarioError, match=f"{n:,} triangles"):
        inspect_model(many)
    from scenario_gen.spec import CropSpec

    doc = {f.name: f.metadata for f in dataclasses.fields(CropSpec)}["model"]
    assert f"at most {MAX_MODEL_TRIANGLES:,} triangles" in str(doc)  # the limit is documented
    line = tmp_path / "line.obj"  # collinear vertices: tall but no surface
    line.write_text("v 0 0 0\nv 0 0 1\nv 0 0 2\nf 1 2 3\n")
    with pytest.raises(ScenarioError, match="no surface area"):
        inspect_model(line)


@pytest.mark.parametrize("member", [".", "./", "plant/."])
def test_a_zip_member_named_dot_is_refused(tmp_path: Path, member: str) -> None:
    z = tmp_path / "m.zip"
    with zipfile.ZipFile(z, "w") as f:
        f.writestr("plant.obj", _plant_obj())
        f.writestr(member, b"")
    with pytest.raises(ScenarioError, match="not '.'"):
        inspect_model(z)


@pytest.mark.parametrize(
    "rename,map_kd",
    [
        ("plant.png", "-s 1 1 1 -bm 1 plant.png"),  # an MTL map with options before its file
        ("tex/plant.png", "tex\\plant.png"),  # a Windows folder separator
    ],
)
def test_a_texture_referenced_as_exporters_write_it_is_loaded(
    tmp_path: Path, rename: str, map_kd: str
) -> None:
    """The texture ``model_files`` found and copied is the one the mesh is drawn with: trimesh
    asks for the reference as written and, missing it, draws the Kd grey without a word."""
    src = tmp_path / "obj"
    shutil.copytree(DATA / "textured_obj", src)
    (src / rename).parent.mkdir(exist_ok=True)
    (src / "plant.png").rename(src / rename)
    (src / "plant.mtl").write_text(
        (src / "plant.mtl").read_text().replace("map_Kd plant.png", f"map_Kd {map_kd}")
    )
    mesh = load_model(str(src / "plant.obj"), 1.0)
    tex = np.asarray(mesh.visual.material.image.convert("RGB"))
    assert (tex.reshape(-1, 3) == OBJ_RGB).all(axis=1).any()


def test_a_url_encoded_collada_texture_is_loaded(tmp_path: Path) -> None:
    """COLLADA's (and glTF's) references are URIs: a file named ``leaf tex.png`` is written
    ``leaf%20tex.png``; the leaf keeps its texture's colour."""
    dae = url_encoded_leaf(CUTOUT, tmp_path / "plant")
    image = np.asarray(load_model(str(dae), 1.0).visual.material.image).reshape(-1, 4)
    assert (image[:, :3] == LEAF).all(axis=1).any()


def test_an_opaque_model_of_several_materials_has_no_cut_outs(tmp_path: Path) -> None:
    """Two textured parts packed into one atlas: the space between their blocks is not a
    cut-out, so the cameras need not test alpha on this model (nor ray-cast it for that)."""
    from agrinav_gym.render.plant_meshes import CROP, Prototype

    src = tmp_path / "two"
    shutil.copytree(DATA / "textured_obj", src)
    obj = (src / "plant.obj").read_text()
    (src / "plant.png").rename(src / "b.png")
    shutil.copyfile(src / "b.png", src / "a.png")
    (src / "plant.mtl").write_text(
        "newmtl a\nKd 0.8 0.8 0.8\nmap_Kd a.png\nnewmtl b\nKd 0.8 0.8 0.8\nmap_Kd b.png\n"
    )
    lines = obj.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("f "))
    half = first + sum(line.startswith("f ") for line in lines) // 2
    lines = [ln for ln in lines if not ln.startswith("usemtl")]
    lines.insert(half, "usemtl b")
    lines.insert(first, "usemtl a")
    (src / "plant.obj").write_text("\n".join(lines) + "\n")
    mesh = load_model(str(src / "plant.obj"), 1.0)
    assert mesh.visual.material.image.size[0] > 1  # an atlas of the two
    assert Prototype.from_trimesh(mesh, "two", CROP).alpha is None


@pytest.mark.parametrize("mode,cut", [(None, False), ("OPAQUE", False), ("MASK", True)])
def test_a_gltf_without_an_alpha_mode_is_opaque(
    tmp_path: Path, mode: str | None, cut: bool
) -> None:
    """glTF 2.0: a material without ``alphaMode`` is OPAQUE, its texture's alpha ignored; only
    MASK (or BLEND) cuts out (COLLADA and OBJ keep their textures' alpha)."""
    import trimesh
    from PIL import Image

    img = Image.new("RGBA", (4, 4), (30, 160, 40, 255))
    img.paste((255, 0, 255, 0), (0, 0, 4, 2))
    v = np.array([[-0.1, 0, 0], [0.1, 0, 0], [0.1, 1, 0], [-0.1, 1, 0]], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    pbr = trimesh.visual.material.PBRMaterial(
        baseColorTexture=img, baseColorFactor=[1.0] * 4, alphaMode=mode
    )
    visual = trimesh.visual.TextureVisuals(uv=uv, material=pbr)
    path = tmp_path / "leaf.glb"
    trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], visual=visual, process=False).export(path)
    alpha = np.asarray(load_model(str(path), 1.0).visual.material.image)[..., 3]
    assert (alpha == 0).any() == cut


def test_a_zip_missing_a_texture_names_the_archives_folder(tmp_path: Path) -> None:
    """Not the temporary folder it was extracted to, which is gone when the user reads it."""
    p = tmp_path / "plant.zip"
    with zipfile.ZipFile(p, "w") as z:
        z.write(CUTOUT / "meshes" / "plant.dae", "corn/meshes/plant.dae")
    with pytest.raises(ScenarioError, match=r"looked for in the archive's corn/meshes/") as e:
        inspect_model(p)
    assert "agrinav-model-" not in str(e.value)


def test_a_y_up_obj_stands_up_when_the_spec_says_so(tmp_path: Path) -> None:
    """Blender's OBJ export writes y up by default: a 2 m cone along +y lies on its side as z
    up (0.6 m tall), stands 2 m tall with crop.model_up_axis=y, is recorded so in scenario.json,
    and the Gazebo export converts it rather than reference a file Gazebo would lay down."""
    import trimesh

    from scenario_gen.export import ExportOptions, export
    from scenario_gen.export.plantmodels import assign

    cone = trimesh.creation.cone(radius=0.3, height=2.0)
    cone.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    assert cone.bounds[1, 1] == pytest.approx(2.0)  # its tip on +y
    p = tmp_path / "yup.obj"
    p.write_text(trimesh.exchange.obj.export_obj(cone))
    assert inspect_model(p, "native").size[2] == pytest.approx(0.6, abs=1e-6)
    um = inspect_model(p, "native", "y")
    assert um.size[2] == pytest.approx(2.0, abs=1e-6)
    spec = small(crop={"model": str(p), "model_scale": "native", "model_up_axis": "y"})
    out = save(generate(spec, 0), tmp_path / "s", preview=False)
    scn = load(out)
    assert scn.crop_model is not None and scn.crop_model.up_axis == "y"
    crop = ~scn.plants.is_weed
    assert np.median(scn.plants.height[crop]) == pytest.approx(2.0, rel=0.2)
    (base,) = [m for m in assign(scn).models if m.species == "corn"]
    assert base.user is None and base.mesh.bounds[1, 2] == pytest.approx(base.height, rel=1e-6)
    export(out, "gazebo", tmp_path / "gz", ExportOptions(plants="include"))
    assert (tmp_path / "gz" / "models" / base.name / "meshes" / "plant.dae").is_file()
    with pytest.raises(ScenarioError, match="crop.model_up_axis"):
        inspect_model(p, "native", "x")


def test_a_collada_file_stands_along_the_axis_it_declares(tmp_path: Path) -> None:
    """``auto`` read every COLLADA file z up, so a Y_UP file (Blender's and SketchUp's
    exports can be) lay on its side while the Gazebo export, reading the declaration, did
    not reference it; X_UP is neither axis and is refused."""
    shutil.copytree(CUTOUT, tmp_path / "m")
    dae = tmp_path / "m" / "meshes" / "plant.dae"
    text = dae.read_text()
    assert "<up_axis>Z_UP</up_axis>" in text
    as_z = inspect_model(dae, "native")
    dae.write_text(text.replace("Z_UP", "Y_UP"))
    declared = inspect_model(dae, "native")
    assert declared.size == pytest.approx(inspect_model(dae, "native", "y").size, abs=1e-9)
    assert declared.size[2] == pytest.approx(as_z.size[1], abs=1e-9)  # its y is up now
    dae.write_text(text.replace("<up_axis>Z_UP</up_axis>", ""))  # COLLADA's default: Y_UP
    assert inspect_model(dae, "native").size == pytest.approx(declared.size, abs=1e-9)
    dae.write_text(text.replace("Z_UP", "X_UP"))
    with pytest.raises(ScenarioError, match=r"crop.model.*X_UP.*crop.model_up_axis"):
        inspect_model(dae, "native")
    assert inspect_model(dae, "native", "z").size == pytest.approx(as_z.size, abs=1e-9)


def test_a_model_far_wider_than_tall_is_noted_as_maybe_lying(tmp_path: Path) -> None:
    import trimesh

    from scenario_gen.errors import Notice

    cone = trimesh.creation.cone(radius=0.2, height=2.0)  # 2 m along +y: 0.4 m "tall" as z up
    cone.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    p = tmp_path / "yup.obj"
    p.write_text(trimesh.exchange.obj.export_obj(cone))
    with pytest.warns(Notice, match="crop.model_up_axis=y"):
        inspect_model(p, "native")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", Notice)
        inspect_model(p, "native", "y")  # stood up: nothing to note


def test_a_truncated_gltf_is_named_as_such(tmp_path: Path) -> None:
    """Not trimesh's KeyError for a file name the user never wrote."""
    p = tmp_path / "plant.gltf"
    p.write_text('{"asset": {"version": "2.0"}, "meshes": [{"name": "lea')
    with pytest.raises(ScenarioError, match="not valid glTF JSON: Unterminated string") as e:
        inspect_model(p)
    assert "model.gltf" not in str(e.value)


def test_a_texture_repeated_over_a_huge_uv_span_stays_within_the_texel_budget() -> None:
    """UVs 0..1000 on a 64-texel image tiled 15 GB before shrinking it; a 2048² image over
    0..20 peaked at 10 GB. The repeated texture is sampled directly, within the budget, and
    each texel is one of the image's at the right phase."""
    import numpy as np

    from scenario_gen import model_mesh as mm

    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (64, 64, 4), dtype=np.uint8)
    reps = np.array([1000.0, 1000.0])
    out = mm._tiled(img, reps, max(reps.max() / mm.MAX_TILES, 1.0))
    assert out.shape[0] * out.shape[1] <= mm.MAX_TILED_TEXELS and out.shape[2] == 4
    # the first output texel's centre falls in the first tile: nearest is image texel (y, x)
    step = 64 * 1000 / out.shape[1]
    assert (out[0, 0] == img[int(0.5 * step) % 64, int(0.5 * step) % 64]).all()
    colours = {tuple(c) for c in img.reshape(-1, 4)}
    assert all(tuple(c) in colours for c in out[::97, ::89].reshape(-1, 4))
    # small repeats are built whole, as before
    small = mm._tiled(img, np.array([3.0, 2.0]), 1.0)
    assert small.shape == (128, 192, 4) and (small[64:, 128:] == img).all()


def test_a_material_library_in_a_subfolder_names_its_texture_from_there(tmp_path: Path) -> None:
    """``mtllib mats/plant.mtl`` whose ``map_Kd plant.png`` lies in ``mats/``: found and
    copied, but the loader looked beside the OBJ and drew the plants the material's grey."""
    src = tmp_path / "obj"
    shutil.copytree(DATA / "textured_obj", src)
    (src / "mats").mkdir()
    (src / "plant.mtl").rename(src / "mats" / "plant.mtl")
    (src / "plant.png").rename(src / "mats" / "plant.png")
    obj = src / "plant.obj"
    obj.write_text(obj.read_text().replace("mtllib plant.mtl", "mtllib mats/plant.mtl"))
    tex = np.asarray(load_model(str(obj), 1.0).visual.material.image.convert("RGB"))
    assert (tex.reshape(-1, 3) == OBJ_RGB).all(axis=1).any()
    out = save(generate(small(crop={"model": str(obj)}), 0), tmp_path / "s")
    tex = np.asarray(load_model(load(out).crop_model_path, 1.0).visual.material.image)
    assert (tex.reshape(-1, 4)[:, :3] == OBJ_RGB).all(axis=1).any()


def test_a_texture_that_is_not_an_image_or_is_a_link_is_refused_naming_it(tmp_path: Path) -> None:
    src = tmp_path / "obj"
    shutil.copytree(DATA / "textured_obj", src)
    (src / "plant.png").write_text("not a png")
    with pytest.raises(ScenarioError, match="references plant.png, which is not an image"):
        generate(small(crop={"model": str(src / "plant.obj")}), 0)
    (src / "plant.png").unlink()
    shutil.copy(DATA / "textured_obj" / "plant.png", tmp_path / "real.png")
    (src / "plant.png").symlink_to(tmp_path / "real.png")
    with pytest.raises(ScenarioError, match="references plant.png, a symbolic link"):
        generate(small(crop={"model": str(src / "plant.obj")}), 0)


def test_a_16_bit_grey_texture_keeps_its_grey(tmp_path: Path) -> None:
    """Pillow's conversion of a 16-bit greyscale PNG clips it: 60 % grey read as white."""
    from PIL import Image

    src = tmp_path / "obj"
    shutil.copytree(DATA / "textured_obj", src)
    Image.fromarray(np.full((16, 16), 38550, np.uint16)).save(src / "plant.png")  # 150 / 255
    tex = np.asarray(load_model(str(src / "plant.obj"), 1.0).visual.material.image.convert("RGB"))
    assert (tex.reshape(-1, 3) == 150).all(axis=1).any()
    assert not (tex.reshape(-1, 3) == 255).all(axis=1).any()


def test_a_texture_without_texture_coordinates_is_noted(tmp_path: Path) -> None:
    """An OBJ whose material has map_Kd but whose faces have no vt was drawn in the material's
    colour without a word."""
    from scenario_gen.errors import Notice

    src = tmp_path / "obj"
    shutil.copytree(DATA / "textured_obj", src)
    obj = src / "plant.obj"
    lines = [ln for ln in obj.read_text().splitlines() if not ln.startswith("vt")]
    obj.write_text(
        "\n".join(re.sub(r"(\d+)/\d+", r"\1", ln) if ln.startswith("f") else ln for ln in lines)
    )
    with pytest.warns(Notice, match="has a texture but no texture coordinates"):
        load_model(str(obj), 1.0)


def _glb(path: Path, attributes: dict[str, np.ndarray], material: dict, **top: object) -> Path:
    """A one-quad glTF binary (y up, 0.5 × 1 m) with the given vertex attributes, material and
    top-level members (extensionsRequired, ...)."""
    import struct

    blob, views, accessors = b"", [], []
    kinds = {np.float32: 5126, np.uint8: 5121, np.uint16: 5123}
    types = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
    for arr in [*attributes.values(), np.array([0, 1, 2, 0, 2, 3], np.uint16)]:
        blob += b"\0" * (-len(blob) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": arr.nbytes})
        blob += arr.tobytes()
        acc = {
            "bufferView": len(views) - 1,
            "componentType": kinds[arr.dtype.type],
            "count": len(arr),
            "type": types[arr.shape[1] if arr.ndim == 2 else 1],
        }
        if arr.dtype == np.uint8:
            acc["normalized"] = True
        if arr.ndim == 2 and arr.shape[1] == 3:
            acc |= {"min": arr.min(0).tolist(), "max": arr.max(0).tolist()}
        accessors.append(acc)
    blob += b"\0" * (-len(blob) % 4)
    names = list(attributes)
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {k: i for i, k in enumerate(names)},
                        "indices": len(names),
                        "material": 0,
                    }
                ]
            }
        ],
        "materials": [material],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
        **top,
    }
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    head = struct.pack("<4sII", b"glTF", 2, 28 + len(js) + len(blob))
    path.write_bytes(head + struct.pack("<I4s", len(js), b"JSON") + js)
    with path.open("ab") as f:
        f.write(struct.pack("<I4s", len(blob), b"BIN\0") + blob)
    return path


QUAD = np.array([[-0.25, 0, 0], [0.25, 0, 0], [0.25, 1, 0], [-0.25, 1, 0]], np.float32)


def test_gltf_vertex_colours_multiply_the_base_colour(tmp_path: Path) -> None:
    """glTF's COLOR_0 (a vertex-painted or photogrammetry plant): the faces take it times the
    base colour; it was dropped (the plant drawn white)."""
    colours = np.array([[0, 0, 255, 255]] * 4, np.uint8)
    half = {"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 0.5, 1.0]}}
    path = _glb(tmp_path / "painted.glb", {"POSITION": QUAD, "COLOR_0": colours}, half)
    mesh = load_model(str(path), 1.0, up_axis="y")
    assert np.asarray(mesh.visual.face_colors)[:, :3].tolist() == [[0, 0, 128]] * 2


def test_a_gltf_requiring_a_geometry_extension_is_refused_naming_it(tmp_path: Path) -> None:
    """Draco, meshopt and quantized files: trimesh reads their buffers as plain floats (or not
    at all), so they are refused by the extension's name, with how to write them plainly."""
    for ext in ("KHR_mesh_quantization", "KHR_draco_mesh_compression"):
        path = _glb(
            tmp_path / f"{ext}.glb",
            {"POSITION": QUAD},
            {},
            extensionsUsed=[ext],
            extensionsRequired=[ext],
        )
        with pytest.raises(ScenarioError, match=f"requires the glTF extension {ext}") as e:
            inspect_model(path)
        assert e.value.field == "crop.model" and "gltf-transform" in str(e.value)


def test_a_gltf_texture_drawn_otherwise_than_its_file_says_is_noted(tmp_path: Path) -> None:
    """A texture transform (Blender writes one for any Mapping node) or a second UV set: the
    texture is mapped by TEXCOORD_0 as it is, and a note says so."""
    from scenario_gen.errors import Notice

    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    shift = {"extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0]}}}
    for name, tex in (("shifted", shift), ("second-uv", {"texCoord": 1})):
        material = {"name": name, "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, **tex}}}
        path = _glb(tmp_path / f"{name}.glb", {"POSITION": QUAD, "TEXCOORD_0": uv}, material)
        with pytest.warns(Notice, match=f"material\\(s\\) {name}: .*drawn otherwise"):
            from scenario_gen.model_mesh import check_gltf

            check_gltf(path, path)


def test_a_one_sided_plant_stands_on_its_stalks_foot(tmp_path: Path) -> None:
    """A stalk at x 0.3 with one 0.8 m leaf towards +x: placed by its bounding box's centre the
    stalk stood 0.4 m off the plant's position (in the lane, for 1 m rows), while crop contact,
    the proxy's core and the dataset's stem points are at that position."""
    import trimesh

    stalk = trimesh.creation.cylinder(radius=0.01, height=1.0, sections=12)
    stalk.apply_translation([0.3, 0.0, 0.5])
    leaf = trimesh.Trimesh([[0.3, 0, 0.5], [1.1, 0.0, 0.6], [1.1, 0.05, 0.6]], [[0, 1, 2]])
    p = tmp_path / "one-sided.obj"
    p.write_text(trimesh.exchange.obj.export_obj(trimesh.util.concatenate([stalk, leaf])))
    placed = load_model(p, 2.0)
    v = np.asarray(placed.vertices)
    foot = v[v[:, 2] < 0.01]
    assert np.allclose(foot[:, :2].mean(axis=0), 0.0, atol=1e-6)
    assert v[:, 2].min() == pytest.approx(0.0) and v[:, 2].max() == pytest.approx(2.0)
    assert v[:, 0].max() == pytest.approx(2.0 * 0.8, abs=0.03)  # the leaf reaches 1.6 m out
