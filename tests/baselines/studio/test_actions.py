"""The buttons' actions: same bytes as the CLI, nothing written on bad input, safe uploads."""

from __future__ import annotations

import shlex
import zipfile
from pathlib import Path

import pytest
from shapely.geometry import Polygon

from agrinav_gym.robot import urdf_path
from baselines.cli import main
from baselines.studio import actions
from baselines.studio.session import Session, field_file
from scenario_gen.errors import InputError
from scenario_gen.export import TARGETS

FILES = ("scenario.json", "plants.csv", "route.csv", "field.geojson", "terrain.npz")


def _small(drawn: bool) -> Session:
    s = Session(seed=3)
    s.set("layout.headland", 2.0)
    s.set("terrain.margin", 4.0)
    s.set("terrain.lod", 19)
    if drawn:
        d = 0.0001
        lat, lon = 36.55, -84.14
        s.set_field(
            Polygon(
                [
                    (lon - d, lat - d),
                    (lon + d, lat - d),
                    (lon + 1.2 * d, lat + d),
                    (lon - d, lat + d),
                ]
            )
        )
    else:
        s.set("field.width", 8.0)
        s.set("field.length", 12.0)
    return s


@pytest.mark.parametrize("drawn", [False, True])
def test_generate_and_save_equals_the_cli(
    tmp_path: Path, drawn: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    s = _small(drawn)
    summary = actions.generate_and_save(s, "page")
    assert summary["out"] == "page" and (tmp_path / "page" / "scenario.json").is_file()
    assert (tmp_path / "page.field.geojson").is_file() == drawn
    argv = shlex.split(s.command("page"))  # the page's command, into another folder
    argv[argv.index("--out") + 1] = "cli"
    assert main(argv[1:]) == 0
    for name in FILES:
        assert (tmp_path / "page" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), (
            name
        )


def test_bad_input_writes_nothing(tmp_path: Path) -> None:
    s = _small(True)
    out = tmp_path / "scn"
    out.mkdir()
    (out / "mine.txt").write_text("mine")
    with pytest.raises(InputError) as e:  # exists, no overwrite
        actions.generate_and_save(s, str(out))
    assert e.value.field == "out" and not field_file(out).exists()
    s.set("route.lanes", 400)  # only generation finds this one
    with pytest.raises(InputError) as e:
        actions.generate_and_save(s, str(tmp_path / "new"))
    assert e.value.field == "route.lanes"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]
    with pytest.raises(InputError):
        actions.generate_and_save(s, "  ")


def test_overwrite_restores_the_field_file_when_generation_fails(tmp_path: Path) -> None:
    s = _small(True)
    out = str(tmp_path / "scn")
    actions.generate_and_save(s, out)
    before = field_file(out).read_text()
    other = _small(True)
    d = 0.0002
    other.set_field(Polygon([(-84.14, 36.55), (-84.14 + d, 36.55), (-84.14, 36.55 + d)]))
    other.set("route.lanes", 400)
    with pytest.raises(InputError):
        actions.generate_and_save(other, out, overwrite=True)
    assert field_file(out).read_text() == before


def _zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


OBJ = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def test_model_upload_is_checked_like_the_cli(tmp_path: Path) -> None:
    models = tmp_path / "models"
    bad = _zip(tmp_path / "up1", {"../evil.obj": OBJ})
    with pytest.raises(InputError) as e:
        actions.install_model(bad, "plant.zip", models, 1.0)
    assert e.value.field == "crop.model" and "zip-slip" in str(e.value)
    assert not models.exists()
    garbage = tmp_path / "up0"
    garbage.write_bytes(b"not a mesh")
    with pytest.raises(InputError) as e:
        actions.install_model(garbage, "leaf.glb", models, 1.0)
    # named as uploaded: the server's temporary copy means nothing to the page's user
    assert e.value.value == "leaf.glb" and "agrinav-model-" not in str(e.value), str(e.value)
    with pytest.raises(InputError):
        actions.install_model(bad, "plant.exe", models, 1.0)
    good = _zip(tmp_path / "up2", {"plant/stem.obj": OBJ})
    kept = actions.install_model(good, "../plant.zip", models, 1.0)
    assert kept == models / "plant.zip" and kept.read_bytes() == good.read_bytes()
    s = Session()
    s.set("crop.model", str(kept))
    assert s.spec().crop.model == str(kept)
    # another model of the same name is kept beside it, the same one again is that file
    other = _zip(tmp_path / "up3", {"plant/stem.obj": OBJ + b"f 1 2 3\n"})
    second = actions.install_model(other, "plant.zip", models, 1.0)
    assert second == models / "plant-2.zip" and second.read_bytes() == other.read_bytes()
    assert kept.read_bytes() == good.read_bytes()
    assert actions.install_model(good, "plant.zip", models, 1.0) == kept
    assert actions.install_model(other, "plant.zip", models, 1.0) == second
    assert sorted(p.name for p in models.iterdir()) == ["plant-2.zip", "plant.zip"]


def test_run_and_export_need_a_saved_scenario(tmp_path: Path) -> None:
    with pytest.raises(InputError) as e:
        actions.run_policy(str(tmp_path), "rpp", str(tmp_path / "run"))
    assert e.value.field == "scenario"
    with pytest.raises(InputError) as e:
        actions.run_policy(str(tmp_path), "bogus", str(tmp_path / "run"))
    assert e.value.field == "policy"


def test_export_runs_the_exporter_like_the_cli(tmp_path: Path) -> None:
    """The button's call end to end: the CLI's defaults, the simulated robot in a Nav2 bundle,
    an existing output or an unknown format refused before anything is written."""
    s = _small(False)
    actions.generate_and_save(s, str(tmp_path / "scn"))
    info = actions.export(str(tmp_path / "scn"), "mesh", str(tmp_path / "scn-mesh"))
    assert info["target"] == "mesh" and any((tmp_path / "scn-mesh").iterdir())
    with pytest.raises(InputError) as e:  # exists: refused before anything is written
        actions.export(str(tmp_path / "scn"), "mesh", str(tmp_path / "scn-mesh"))
    assert e.value.field == "out"
    actions.export(str(tmp_path / "scn"), "nav2", str(tmp_path / "scn-nav2"))
    robot = tmp_path / "scn-nav2" / "robot" / "summit_xl.urdf"
    assert robot.read_bytes() == Path(urdf_path()).read_bytes()
    with pytest.raises(InputError) as e:
        actions.export(str(tmp_path / "scn"), "unity", str(tmp_path / "u"))
    assert e.value.field == "export" and not (tmp_path / "u").exists()
    assert actions.export_formats() == TARGETS
