from __future__ import annotations

from pathlib import Path

import pytest

from scenario_gen import Scenario, generate, load, save
from scenario_gen.export import ExportOptions, export

from ..helpers import plane, small
from .tools import build_sdf_check


@pytest.fixture(scope="session")
def sdf_check() -> Path:
    return build_sdf_check()


@pytest.fixture(scope="session")
def hill(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, Path]:
    """A 20° slope with weeds: large roll/pitch make a rotation-convention slip visible.

    Tiny on purpose: libsdformat spends ≈60 ms per <include> (benchmarks/bench_export.py).
    """
    spec = plane(
        20.0,
        30.0,
        field={"width": 3.5, "length": 4.5},
        layout={"weed_density": 1.0, "headland": 1.0, "plant_spacing": 0.4},
        terrain={"margin": 3.0},
        route={"lead_in": 1.0},
    )
    scn = generate(spec, seed=7)
    out = tmp_path_factory.mktemp("hill") / "scn"
    save(scn, out, preview=False)
    return scn, out


@pytest.fixture(scope="session")
def dem(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, Path]:
    """The default preset on a small field of the embedded DEM (a source CRS, EPSG:4326)."""
    scn = generate(small(), seed=3)
    out = tmp_path_factory.mktemp("dem") / "scn"
    save(scn, out, preview=False)
    return scn, out


@pytest.fixture(scope="session")
def nav2_bundle(dem, tmp_path_factory) -> tuple[Scenario, Path]:
    """The dem scenario exported --to nav2 with the CLI's robot (env defaults, dwb:furrow)."""
    from baselines.nav2_robot import nav2_options

    _, src = dem
    out = tmp_path_factory.mktemp("nav2") / "out"
    export(src, "nav2", out, ExportOptions.from_dict(nav2_options(plants="tiles")))
    return load(src), out


#: obstacles on the hill field: seed 7 places 8 stones, 5 litter items and 2 fallen stalks
OBSTACLES = {"stone_density": 0.6, "litter_density": 0.4, "stalk_lodging": 0.15}


@pytest.fixture(scope="session")
def obstacle_hill(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, Path]:
    """The ``hill`` field with a few obstacles of each kind, on the same 20° slope (a pose's
    roll and pitch are large there, so a convention slip shows)."""
    spec = plane(
        20.0,
        30.0,
        field={"width": 3.5, "length": 4.5},
        layout={"weed_density": 1.0, "headland": 1.0, "plant_spacing": 0.4},
        terrain={"margin": 3.0},
        route={"lead_in": 1.0},
        obstacles=OBSTACLES,
    )
    scn = generate(spec, seed=7)
    assert all(n >= 2 for n in scn.obstacles.counts().values()), scn.obstacles.counts()
    out = tmp_path_factory.mktemp("obstacle_hill") / "scn"
    save(scn, out, preview=False)
    return load(out), out
