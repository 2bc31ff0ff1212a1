"""``--force`` replaces an earlier output folder, never the command's own input inside it."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from baselines.cli import main
from scenario_gen import generate, preset, save

TINY = {
    "field": {"width": 6.0, "length": 8.0},
    "layout": {"headland": 1.5},
    "terrain": {"margin": 3.0},
    "route": {"lead_in": 1.0},
}


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str], kept: Path) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "holds this command's input" in err and len(err.splitlines()) == 1, err
    assert kept.exists(), f"{kept} was deleted"


def test_export_keeps_a_scenario_that_lies_inside_its_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "export"
    save(generate(preset("default", **TINY), 1), tmp_path / "scn", preview=False)
    assert main(["export", str(tmp_path / "scn"), "--to", "gis", "--out", str(out)]) == 0
    shutil.copytree(tmp_path / "scn", out / "scn")  # a user keeps the scenario with its export
    argv = ["export", str(out / "scn"), "--to", "gis", "--out", str(out), "--force"]
    _refused(capsys, argv, out / "scn" / "scenario.json")


def test_export_policy_keeps_a_checkpoint_that_lies_inside_its_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from policies import shipped_model

    out = tmp_path / "onnx"
    argv = ["export-policy", "shipped:AgriNav/FurrowFollow-v3", "--to", "onnx", "--out", str(out)]
    assert main(argv) == 0
    shutil.copytree(shipped_model("AgriNav/FurrowFollow-v3"), out / "ck")
    argv = ["export-policy", str(out / "ck"), "--to", "onnx", "--out", str(out), "--force"]
    _refused(capsys, argv, out / "ck" / "checkpoint.json")


def test_bench_keeps_a_parameter_file_that_lies_inside_its_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "bench"
    out.mkdir()
    (out / ".agrinav-output").write_text("bench\n")  # an earlier bench's folder
    params = out / "mine.yaml"
    params.write_text(yaml.safe_dump({"max_lookahead": 0.6}))
    argv = ["bench", "--suite", "smoke", "--policies", f"rpp:{params}", "--seeds", "1"]
    _refused(capsys, [*argv, "--out", str(out), "--force"], params)


def test_scenario_keeps_a_waypoint_file_that_lies_inside_its_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "scn"
    assert main(["scenario", "--out", str(out), "--no-preview"]) == 0
    wps = out / "w.yaml"
    wps.write_text("waypoints: [{latitude: 0, longitude: 0}, {latitude: 0, longitude: 1}]\n")
    _refused(capsys, ["scenario", "--waypoints", str(wps), "--out", str(out), "--force"], wps)


def test_trajectories_keep_a_checkpoint_that_lies_inside_its_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("minari")
    from policies import shipped_model

    out = tmp_path / "traj"
    out.mkdir()
    (out / ".agrinav-output").write_text("kind: dataset\n")  # an earlier dataset's folder
    shutil.copytree(shipped_model("AgriNav/FurrowFollow-v3"), out / "ck")
    argv = ["dataset", "trajectories", "--policy", f"ppo:{out / 'ck'}", "--episodes", "1"]
    _refused(capsys, [*argv, "--out", str(out), "--force"], out / "ck" / "checkpoint.json")


def test_run_keeps_a_scenario_folder_that_lies_inside_its_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only policy files were protected: ``run --force`` deleted its own --scenario folder."""
    out = tmp_path / "run"
    out.mkdir()
    (out / ".agrinav-output").write_text("run\n")  # an earlier run's folder
    save(generate(preset("default", **TINY), 1), out / "field", preview=False)
    argv = ["run", "--policy", "rpp", "--scenario", str(out / "field"), "--max-steps", "5"]
    _refused(capsys, [*argv, "--out", str(out), "--force"], out / "field" / "scenario.json")
