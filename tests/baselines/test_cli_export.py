"""``agrinav export``: one line and exit status 2 for bad input, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from baselines.cli import main
from scenario_gen import generate, preset, save


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    spec = preset(
        "default",
        field={"width": 6.0, "length": 8.0},
        layout={"headland": 1.5},
        terrain={"margin": 3.0},
        route={"lead_in": 1.0},
    )
    out = tmp_path_factory.mktemp("cli") / "scn"
    save(generate(spec, 1), out, preview=False)
    return out


def _error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's own refusals exit from the parser
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("to", ["gazebo", "nav2", "gis", "mesh"])
def test_export_each_target(scenario: Path, tmp_path: Path, capsys, to: str) -> None:
    out = tmp_path / to
    assert main(["export", str(scenario), "--to", to, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "target" in text and str(out) in text
    assert (out / "README.md").is_file() and (out / "preview.png").is_file()
    # the output folder appears whole: no temporaries left beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == [to]


def test_bad_inputs_write_nothing(scenario: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    plain = tmp_path / "plain"
    plain.mkdir()
    cases = [
        (["export", str(tmp_path / "nope"), "--to", "gis"], "scenario: got"),
        (["export", str(plain), "--to", "gis"], "scenario.json: got"),
        (["export", str(scenario), "--to", "unity"], "invalid choice: 'unity'"),
        (["export", str(scenario), "--to", "mesh", "--formats", "fbx"], "formats[0]: got 'fbx'"),
        (
            ["export", str(scenario), "--to", "gis", "--formats", "obj"],
            "--formats is for --to mesh only",
        ),
        (["export", str(scenario), "--to", "mesh", "--formats", "glb,,obj"], "no empty entry"),
        # another target's flag at its own default value is refused as any other value
        (
            ["export", str(scenario), "--to", "gis", "--formats", "glb"],
            "--formats is for --to mesh only",
        ),
        (
            ["export", str(scenario), "--to", "mesh", "--plants", "auto"],
            "--plants is for --to gazebo or nav2",
        ),
        (["export", str(scenario), "--to", "nav2", "--dwb", ""], "--dwb: got ''"),
        (["export", str(scenario), "--to", "nav2", "--dwb", "bogus"], "--dwb: got 'bogus'"),
        (["export", str(scenario), "--to", "gis", "--dwb", "tuned"], "--dwb is for --to nav2"),
        (
            [
                "export",
                str(scenario),
                "--to",
                "gazebo",
                "--plants",
                "include",
                "--tile-plants",
                "5",
            ],
            "--plants include merges no tiles",
        ),
        (
            ["export", str(scenario), "--to", "nav2", "--plants", "tiles", "--include-limit", "5"],
            "--include-limit: got 5; is auto's limit",
        ),
        (["export", str(scenario), "--to", "gazebo", "--tile-plants", "0"], "tile_plants: got 0"),
        (
            ["export", str(scenario), "--to", "gis", "--heightmap"],
            "--to: got 'gis'; --heightmap is",
        ),
        (
            ["export", str(scenario), "--to", "mesh", "--plants", "tiles"],
            "--to: got 'mesh'; --plants is",
        ),
        (
            ["export", str(scenario), "--to", "mesh", "--include-limit", "10", "--heightmap"],
            "--to: got 'mesh'; --include-limit and --heightmap are for --to gazebo or nav2",
        ),
        (["export", str(scenario), "--to", "gis", "--out", str(scenario)], "already exists"),
        (
            ["export", str(scenario), "--to", "gis", "--out", str(scenario), "--force"],
            "is the scenario folder itself",
        ),
    ]
    for argv, needle in cases:
        if "--out" not in argv:
            argv = [*argv, "--out", str(out)]
        assert needle in _error(capsys, argv)
        assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain"]


def test_existing_out_needs_force(scenario: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert "--force" in _error(capsys, ["export", str(scenario), "--to", "gis", "--out", str(out)])
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    # --force replaces only a folder agrinav wrote: the user's own folder stays
    force = ["export", str(scenario), "--to", "gis", "--out", str(out), "--force"]
    assert "not written by agrinav" in _error(capsys, force)
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    ours = tmp_path / "ours"
    assert main(["export", str(scenario), "--to", "mesh", "--out", str(ours)]) == 0
    (ours / "stale.txt").write_text("from the last export")
    assert main(["export", str(scenario), "--to", "gis", "--out", str(ours), "--force"]) == 0
    assert (ours / "terrain.tif").is_file() and not (ours / "stale.txt").exists()


def test_broken_scenario_folders(scenario: Path, tmp_path: Path, capsys) -> None:
    import shutil

    broken = tmp_path / "broken"
    shutil.copytree(scenario, broken)
    meta = json.loads((broken / "scenario.json").read_text())
    meta["spec"]["crop"]["model"] = str(tmp_path / "gone.glb")
    (broken / "scenario.json").write_text(json.dumps(meta))
    out = tmp_path / "out"
    err = _error(capsys, ["export", str(broken), "--to", "gazebo", "--out", str(out)])
    assert "crop.model" in err and "no longer exists" in err and not out.exists()
    (broken / "terrain.npz").unlink()
    err = _error(capsys, ["export", str(broken), "--to", "gis", "--out", str(out)])
    assert "terrain.npz" in err and "is missing" in err and not out.exists()
    (broken / "scenario.json").write_text("{not json")
    assert "scenario" in _error(capsys, ["export", str(broken), "--to", "gis", "--out", str(out)])
    assert not out.exists()


def test_include_limit_help_and_docs_state_the_limit_the_code_uses(capsys) -> None:
    from scenario_gen.export.options import INCLUDE_LIMIT, ExportOptions

    try:
        main(["export", "--help"])
    except SystemExit:  # argparse's --help exits where main does not catch it
        pass
    help_text = " ".join(capsys.readouterr().out.split())
    assert f"auto's limit (default {INCLUDE_LIMIT:,} plants)" in help_text
    assert f"plants per merged tile (default {ExportOptions().tile_plants:,})" in help_text
    doc = (Path(__file__).resolve().parents[2] / "docs" / "exports.md").read_text()
    doc = " ".join(doc.split())
    assert f"`--include-limit N` (auto's switch, {INCLUDE_LIMIT:,};" in doc
    assert f"uses includes up to {INCLUDE_LIMIT:,} plants" in doc


def test_exports_doc_states_the_default_fields_plant_count() -> None:
    """docs/exports.md prices the default field in includes: its count is the generator's."""
    import re

    doc_file = Path(__file__).resolve().parents[2] / "docs" / "exports.md"
    doc = " ".join(doc_file.read_text().split())
    said = re.search(r"the default field's ([\d,]+) plants", doc)
    assert said is not None
    scn = generate(preset("default"), 0)
    assert int(said.group(1).replace(",", "")) == len(scn.plants)


CUTOUT = Path(__file__).resolve().parents[1] / "data" / "crop_models" / "cutout_plant"


@pytest.fixture(scope="module")
def collada(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scenario whose crop.model is a textured COLLADA plant in Gazebo's layout."""
    import shutil

    base = tmp_path_factory.mktemp("collada")
    shutil.copytree(CUTOUT, base / "plant")
    spec = preset(
        "default",
        field={"width": 3.0, "length": 4.0},
        layout={"headland": 1.0},
        terrain={"margin": 2.5},
        route={"lead_in": 1.0},
        crop={"model": str(base / "plant" / "meshes" / "plant.dae")},
    )
    save(generate(spec, 1), base / "scn", preview=False)
    return base / "scn"


@pytest.mark.parametrize(
    "args",
    [
        ["--to", "gazebo"],
        ["--to", "gazebo", "--plants", "tiles"],
        ["--to", "mesh", "--with-plants"],
    ],
)
def test_a_textured_collada_crop_model_exports(collada: Path, tmp_path: Path, args) -> None:
    out = tmp_path / "out"
    assert main(["export", str(collada), *args, "--out", str(out)]) == 0
    assert (out / "README.md").is_file()


@pytest.mark.parametrize("to", [["--to", "gazebo"], ["--to", "mesh", "--with-plants"]])
def test_a_crop_model_whose_texture_is_gone_is_one_line(
    collada: Path, tmp_path: Path, capsys, to
) -> None:
    """A folder kept only the mesh (as scenarios did before their models' files were kept):
    the export names the missing texture in one line and writes nothing."""
    import shutil

    old = tmp_path / "old"
    shutil.copytree(collada, old)
    meta = json.loads((old / "scenario.json").read_text())
    del meta["crop_model"]["files"]
    (old / "scenario.json").write_text(json.dumps(meta))
    shutil.rmtree(old / "models" / "plant" / "materials")
    out = tmp_path / "out"
    err = _error(capsys, ["export", str(old), *to, "--out", str(out)])
    assert "crop.model" in err and "leaf.png" in err and "missing" in err
    assert not out.exists()


def test_nav2_export_runs_the_dwb_config_asked_for(scenario: Path, tmp_path: Path, capsys) -> None:
    """``--dwb``: the bundle's controller and its README follow the configuration (here the
    tuned one with the rotation shim in front); any other target refuses the flag."""
    import yaml

    shim = Path(__file__).parents[2] / "benchmarks" / "dwb_tuned_shim.yaml"
    out = tmp_path / "nav2"
    argv = ["export", str(scenario), "--to", "nav2", "--out", str(out), "--dwb", str(shim)]
    assert main(argv) == 0
    assert "dwb:dwb_tuned_shim" in capsys.readouterr().out
    params = yaml.safe_load((out / "config" / "nav2_params.yaml").read_text())
    fp = params["controller_server"]["ros__parameters"]["FollowPath"]
    assert fp["plugin"] == "nav2_rotation_shim_controller::RotationShimController"
    assert fp["primary_controller"] == "dwb_core::DWBLocalPlanner"
    assert fp["max_vel_x"] == pytest.approx(0.4198)  # the tuned speed
    readme = (out / "README.md").read_text()
    assert (
        "`dwb:dwb_tuned_shim.yaml`" in readme and "RotationShimController stands in front" in readme
    )
    assert "--to: got 'gis'; --dwb is for --to nav2 only" in _error(
        capsys,
        ["export", str(scenario), "--to", "gis", "--out", str(tmp_path / "g"), "--dwb", "tuned"],
    )
