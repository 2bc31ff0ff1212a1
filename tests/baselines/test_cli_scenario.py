import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from baselines.cli import main


def test_cli_writes_a_scenario_and_prints_a_summary(tmp_path: Path, capsys) -> None:
    out = tmp_path / "scn"
    rc = main(
        [
            "scenario",
            "--preset",
            "default",
            "--seed",
            "2",
            "--out",
            str(out),
            "--set",
            "field.width=8",
            "--set",
            "field.length=12",
            "--set",
            "layout.headland=2",
            "--lod",
            "19",
            "--no-preview",
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "plants" in text and "LoD 19" in text and "total_s" in text
    # the field's own slope, readable: "slope_deg  median 0.4, p90 0.7, max 0.9"
    assert re.search(r"slope_deg +median [\d.]+, p90 [\d.]+, max [\d.]+", text)
    assert (out / "scenario.json").is_file() and not (out / "preview.png").exists()


def test_cli_config_file_and_bank(tmp_path: Path) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("field: {width: 8.0, length: 12.0}\nlayout: {headland: 2.0}\n")
    out = tmp_path / "bank"
    assert (
        main(
            [
                "scenario",
                "--config",
                str(cfg),
                "--count",
                "3",
                "--seed",
                "10",
                "--out",
                str(out),
                "--no-preview",
            ]
        )
        == 0
    )
    assert sorted(p.name for p in out.iterdir()) == [
        ".agrinav-output",
        "bank.yaml",
        "seed-000010",
        "seed-000011",
        "seed-000012",
    ]


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--set", "layout.row_spacin=1"], "layout.row_spacin: got 1; unknown key"),
        (["--set", "layout.row_spacing=-2"], "layout.row_spacing: got -2.0; allowed"),
        (["--set", "nonsense"], "--set: got 'nonsense'; allowed: key=value"),
        (["--dem", "/nope.tif"], "terrain.path: got '/nope.tif'; allowed: an existing GeoTIFF"),
        (["--mesh", "/nope.glb"], "--datum"),
        (["--datum", "1,2"], "--datum: got '1,2'"),
        (["--config", "/nope.yaml"], "--config"),
        (["--lod", "30"], "terrain.lod: got 30"),
        (["--count", "0"], "--count"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_no_output(
    tmp_path: Path, args: list[str], needle: str
) -> None:
    out = tmp_path / "never"
    proc = subprocess.run(
        [sys.executable, "-m", "baselines.cli", "scenario", "--out", str(out), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_config_reference_is_current() -> None:
    """docs/config.md is generated from the config classes: regenerate it after a change with
    `python -m baselines.configdoc`."""
    from baselines.configdoc import reference

    root = Path(__file__).resolve().parents[2]
    assert (root / "docs" / "config.md").read_text() == reference()


@pytest.mark.parametrize(
    "config,sets,name",
    [
        ("field: {width: 8.0, length: 12.0}\n", [], "default+north--farm"),
        ("name: mine\nfield: {width: 8.0, length: 12.0}\n", [], "mine"),
        ("field: {width: 8.0, length: 12.0}\n", ["--set", "name=set-by-hand"], "set-by-hand"),
    ],
)
def test_a_scenario_is_named_after_its_preset_and_files(
    tmp_path: Path, config: str, sets: list[str], name: str
) -> None:
    """A custom scenario is not called "default": its config file's stem follows the preset
    (one '-' for a run of them: names go into XML comments), unless it is named."""
    cfg = tmp_path / "north--farm.yaml"
    cfg.write_text(config + "layout: {headland: 2.0}\n")
    out = tmp_path / "scn"
    args = ["scenario", "--config", str(cfg), "--out", str(out), "--no-preview", *sets]
    assert main(args) == 0
    meta = json.loads((out / "scenario.json").read_text())
    assert meta["name"] == name.replace("--", "-") and meta["spec"]["name"] == meta["name"]


def test_a_config_files_relative_paths_are_its_folders(tmp_path: Path, monkeypatch) -> None:
    """``route: {waypoints: gps.yaml}`` in cfg/c.yaml names cfg/gps.yaml, whatever the working
    folder; on the command line a relative path is the working folder's."""
    from baselines.scenario_spec import spec_from_argv

    cfg = tmp_path / "cfg"
    cfg.mkdir()
    for folder in (cfg, tmp_path):
        (folder / "gps.yaml").write_text("waypoints: []\n")
    (cfg / "c.yaml").write_text("route: {waypoints: gps.yaml}\n")
    monkeypatch.chdir(tmp_path)
    spec = spec_from_argv(["--config", str(cfg / "c.yaml")])
    assert spec.route.waypoints == str((cfg / "gps.yaml").resolve())
    spec = spec_from_argv(["--config", str(cfg / "c.yaml"), "--waypoints", "gps.yaml"])
    assert spec.route.waypoints == str((tmp_path / "gps.yaml").resolve())


def test_a_bank_member_that_fails_names_its_seed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Seed 4's curve radius leaves the keyhole room, seed 5's does not: the error says which
    member (the first, seed 4, generated before the bank folder exists)."""
    argv = ["scenario", "--seed", "4", "--count", "2", "--no-preview", "--out", str(tmp_path / "b")]
    sets = ["layout.row_geometry=curved", "layout.curve_radius=[15,200]", "route.turn=keyhole"]
    sets.append("layout.headland=4.0")
    assert main([*argv, *(a for s in sets for a in ("--set", s))]) == 2
    err = capsys.readouterr().err
    assert "route.turn" in err and "(bank member seed 5)" in err, err
    assert not (tmp_path / "b").exists()


def test_a_full_disk_is_one_line_naming_the_output_and_what_to_do(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """The machine's error (here ENOSPC raised with no file name, as numpy's writers do) is
    exit 1 and one line: where, why and what to do, not ``[Errno 28]``; nothing is left."""
    import errno

    import numpy as np

    def full(*_a: object, **_k: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", full)
    out = tmp_path / "made" / "scn"
    assert main(["scenario", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (
        f"agrinav scenario: error: writing {out}: No space left on device; "
        "free space on that disk or write elsewhere (--out)"
    )
    assert list(tmp_path.iterdir()) == []


def test_an_os_error_with_a_file_names_that_file() -> None:
    import errno

    from baselines.cli import os_error

    exc = PermissionError(errno.EACCES, "Permission denied", "/data/x.csv")
    assert os_error(exc, "out") == (
        "/data/x.csv: Permission denied; no permission there: write elsewhere (--out) or fix "
        "the folder's permissions"
    )
    assert os_error(OSError(errno.EIO, "Input/output error")) == "Input/output error"
    # a message a command wrote (a dataset's "3 of 20 shards are kept ...") is passed on as is
    own = OSError(errno.ENOSPC, "writing the dataset in ds failed (No space left on device)")
    assert os_error(own, "ds") == "writing the dataset in ds failed (No space left on device)"


def test_a_flag_given_twice_is_refused(tmp_path: Path, capsys) -> None:
    """``--out a --out b`` used to write b only, ``--suite smoke --suite paper`` run paper:
    the last silently won. Lists (``--set``) still repeat."""
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["scenario", "--out", str(a), "--out", str(b)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("agrinav scenario: error: argument --out: given twice; allowed: once")
    assert not a.exists() and not b.exists()
    assert main(["bench", "--suite", "smoke", "--suite", "paper", "--out", str(a)]) == 2
    assert "argument --suite: given twice" in capsys.readouterr().err
    sets = ["--set", "layout.rows=4", "--set", "layout.plant_spacing=0.2"]
    assert main(["scenario", *sets, "--no-preview", "--out", str(a)]) == 0


def test_an_empty_out_is_refused_not_taken_for_the_current_folder(capsys) -> None:
    assert main(["scenario", "--out", ""]) == 2
    assert capsys.readouterr().err.strip() == (
        "agrinav scenario: error: --out: got ''; allowed: a folder path"
    )


def test_a_closed_stdout_pipe_ends_the_command_as_sigpipe_does(monkeypatch, capsys) -> None:
    """``agrinav run ... | head``: the reader went away; not "writing OUT: Broken pipe" (the
    output folder was whole) but SIGPIPE's status, silently."""
    import os

    from baselines.cli import scenario as scenario_cli

    def reader_gone(args: object) -> int:
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(scenario_cli, "run", reader_gone)
    stdout = os.dup(1)
    try:
        assert main(["scenario", "--out", "x"]) == 141
    finally:
        os.dup2(stdout, 1)  # the handler points stdout at /dev/null
        os.close(stdout)
    assert capsys.readouterr().err == ""


def test_ctrl_c_while_the_command_line_loads_is_one_line() -> None:
    """The console script imports the simulator's packages (≈ 1–2 s) inside its own Ctrl-C
    handler: an interrupt then was an 18-frame traceback."""
    import signal
    import time

    script = Path(sys.executable).parent / "agrinav"
    proc = subprocess.Popen(
        [str(script), "scenario", "--help"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        # a job started in the background inherits SIGINT ignored; a terminal's is not
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    time.sleep(0.3)  # python is up, the packages are still loading
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and err.strip() == "agrinav: interrupted", err


@pytest.mark.parametrize("flag", ["--dem", "--mesh", "--field", "--waypoints", "--config"])
def test_an_empty_file_flag_is_refused_not_taken_as_absent(
    tmp_path: Path, flag: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--dem "$DEM"`` with the variable unset built the scenario on the embedded DEM."""
    out = tmp_path / "never"
    assert main(["scenario", flag, "", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{flag}: got ''; allowed: a file path (it is empty)" in err, err
    assert not out.exists()
