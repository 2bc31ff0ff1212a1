"""crop.model is part of the scenario: recorded, copied, loaded from the copy, previewed; a zip
with two meshes is refused."""

import hashlib
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from scenario_gen import ScenarioError, generate, load, save
from scenario_gen.models import inspect_model, load_model
from scenario_gen.preview import preview_figure

from .helpers import small


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
    ],
)
def test_single_file_model_with_external_files_must_be_zipped(
    tmp_path: Path, name: str, text: str, ref: str
) -> None:
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(ScenarioError, match=rf"references other files \({ref}\).*one \.zip"):
        inspect_model(p)


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
