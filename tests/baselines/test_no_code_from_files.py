"""Files and flags name data, never code: an env id of the form ``module:Id`` (which
``gym.make`` would import) or an id outside AgriNav is refused before anything is imported or
written, and ``--force`` replaces only folders agrinav wrote."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from agrinav_gym import check_env_id, register_scenario
from baselines.cli import main
from scenario_gen.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
EVIL = "from pathlib import Path\nPath('PWNED').write_text('ran')\n"


@pytest.mark.parametrize(
    "env_id",
    [
        "evilmod:Anything",
        "CartPole-v1",
        "AgriNav/FurrowFollow-v0",
        "AgriNav/FurrowFollow-v2",
        "AgriNav/Nope-v1",
        3,
        "",
    ],
)
def test_only_agrinav_env_ids_pass(env_id: object) -> None:
    with pytest.raises(InputError) as e:
        check_env_id(env_id, "spec.env")
    assert e.value.field == "spec.env" and "AgriNav/FurrowFollow-v3" in str(e.value)


def test_this_packages_module_prefix_passes() -> None:
    """The form SB3's subprocess workers need (gym.make imports ``agrinav_gym`` first), and
    only that module: the README recommends it beside ``make_vec``."""
    assert check_env_id("agrinav_gym:AgriNav/FieldRoute-v3") == "AgriNav/FieldRoute-v3"
    with pytest.raises(InputError):
        check_env_id("agrinav_gym.evil:AgriNav/FieldRoute-v3")


def test_user_registered_scenarios_pass(tmp_path: Path) -> None:
    from scenario_gen import generate, preset, save

    save(generate(preset("default"), seed=0), tmp_path / "scn")
    env_id = register_scenario("MyOwnField", tmp_path / "scn")
    assert check_env_id(env_id) == env_id


@pytest.mark.parametrize(
    "argv",
    [
        ["dataset", "perception", "--spec", "spec.yaml", "--frames", "1"],
        ["dataset", "perception", "--set", "env=evilmod:Anything", "--frames", "1"],
        ["dataset", "trajectories", "--env", "evilmod:Anything", "--policy", "rpp"],
        ["run", "--env", "evilmod:Anything", "--policy", "rpp"],
    ],
)
def test_a_module_in_the_current_folder_is_never_imported(tmp_path: Path, argv: list[str]) -> None:
    (tmp_path / "evilmod.py").write_text(EVIL)
    (tmp_path / "spec.yaml").write_text("env: 'evilmod:Anything'\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MPLBACKEND": "Agg"}
    r = subprocess.run(
        [sys.executable, "-m", "baselines.cli", *argv, "--out", "out"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2, r.stderr
    assert "evilmod:Anything" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "PWNED").exists() and not (tmp_path / "out").exists()


def test_force_on_the_current_folder_deletes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.txt").write_text("mine")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "theirs.txt").write_text("theirs")  # a user's folder, not agrinav's
    for out in (".", "other"):
        assert main(["scenario", "--preset", "default", "--out", out, "--force"]) == 2
        err = capsys.readouterr().err
        assert "--force" in err or "never replaced" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt", "other"]
