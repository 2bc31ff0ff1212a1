"""The benchmark protocol: held-out seeds, and fields the PPO training split never drew."""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

import agrinav_gym
from baselines.bench import geometry
from baselines.hyperparams import load
from baselines.suites import EVAL_SCENARIO_SEEDS, EVAL_SEED, SUITES, suite


@pytest.mark.parametrize("name", SUITES)
def test_every_suite_evaluates_on_held_out_seeds(name: str) -> None:
    for case in suite(name):
        kw = case.env_kwargs()
        assert kw["scenario_seed"] >= EVAL_SEED
        if case.randomize:
            _, setup = load(case.env_id)
            lo, hi = kw["scenario_seeds"]
            tlo, thi = setup.train_seeds
            assert (lo, hi) == tuple(setup.eval_seeds) == EVAL_SCENARIO_SEEDS
            assert hi <= tlo or thi <= lo


def test_unseen_suite_draws_the_training_ranges() -> None:
    (case,) = suite("unseen")
    _, setup = load(case.env_id)
    train = setup.env_kwargs["randomize"]
    assert case.randomize == {k: v for k, v in train.items() if "." in k}
    geometry_keys = {"field.angle_deg", "field.length", "route.turn_offset"}
    assert geometry_keys <= set(case.randomize)


def _fields(kwargs: dict, seeds: range) -> list[tuple]:
    env = gym.make("AgriNav/FieldRoute-v3", **kwargs)
    try:
        out = []
        for s in seeds:
            env.reset(seed=s)
            g = geometry(env.unwrapped.scenario)
            out.append((g["scenario_seed"], g["row_direction_deg"], g["row_length_m"]))
        return out
    finally:
        env.close()


def test_a_fields_geometry_carries_its_own_slope_beside_the_drawn_cap() -> None:
    """The held-out table shows the slope the robot drove (a tilted plane: exact), not only the
    DEM window's cap that was drawn."""
    from scenario_gen import generate, preset

    spec = preset("default", field={"width": 10.0, "length": 14.0}, layout={"headland": 2.0})
    tilted = spec.replace({"terrain": {"source": "plane", "slope_deg": 7.0, "margin": 4.0}})
    g = geometry(generate(tilted, seed=0))
    assert g["field_slope_deg"] == pytest.approx(7.0, abs=0.05)
    assert g["max_slope_deg"] == spec.terrain.max_slope_deg  # the cap, unchanged


def test_no_evaluation_field_is_a_training_field() -> None:
    (case,) = suite("unseen")
    _, setup = load(case.env_id)
    kw = case.env_kwargs()
    evaluated = _fields(kw, range(EVAL_SEED, EVAL_SEED + 3))
    train_kw = {**kw, "scenario_seeds": list(setup.train_seeds)}
    trained = _fields(train_kw, range(0, 4))  # the first episode of each of 4 training workers
    assert len(set(evaluated)) == 3  # each seed its own field
    lo, hi = setup.train_seeds
    for seed, direction, length in evaluated:
        assert not lo <= seed < hi
        assert all(abs(direction - d) > 0.05 or abs(length - n) > 0.05 for _, d, n in trained)


@pytest.mark.parametrize("env_id", agrinav_gym.ENV_IDS)
def test_train_validation_and_test_seeds_are_three_disjoint_ranges(env_id: str) -> None:
    _, setup = load(env_id)
    ranges = sorted([setup.train_seeds, setup.val_seeds, setup.eval_seeds])
    assert all(hi <= lo for (_, hi), (lo, _) in itertools.pairwise(ranges))


@pytest.mark.parametrize(
    "split,value,other",
    [
        ("val_seeds", [1_000_000_500, 1_000_000_600], "eval_seeds"),  # validation on test fields
        ("val_seeds", [10, 20], "train_seeds"),
        ("eval_seeds", [5, 6], "train_seeds"),
    ],
)
def test_an_overlapping_split_is_refused_when_loading(split: str, value: list, other: str) -> None:
    from baselines.hyperparams import EnvSetup, check_splits
    from scenario_gen.errors import InputError
    from scenario_gen.schema import from_mapping

    setup = from_mapping(EnvSetup, {split: value}, "envs.yml X.")
    with pytest.raises(InputError) as e:
        check_splits(setup, "envs.yml X.")
    assert split in e.value.field or other in e.value.field
    assert other in str(e.value) or split in str(e.value)


def test_every_ood_case_lies_outside_the_training_ranges() -> None:
    """Held out means out of distribution: each ood case's value of its axis is outside what
    any FieldRoute training field was drawn from (the training preset's value where the
    training does not draw it)."""
    from scenario_gen import preset

    _, setup = load("AgriNav/FieldRoute-v3")
    train = setup.env_kwargs["randomize"]
    spec = preset(setup.env_kwargs["scenario"])

    def outside(key: str, value: float) -> bool:
        if key in train and isinstance(train[key], list):
            lo, hi = train[key]
            return not lo <= value <= hi
        section, name = key.split(".")
        return value != getattr(getattr(spec, section), name)

    cases = {c.group: c for c in suite("ood")}
    assert outside("furrows.depth", cases["ridged 12 cm"].overrides["furrows"]["depth"])
    for group in ("rows 0.8 m", "rows 1.2 m"):
        assert outside("layout.row_spacing", cases[group].overrides["layout"]["row_spacing"])
    in_row = cases["maize 0.18 m in-row"].overrides["layout"]["plant_spacing"]
    assert outside("layout.plant_spacing", in_row)
    lo, _ = cases["slope 9-12 deg"].randomize["terrain.max_slope_deg"]
    assert lo > train["terrain.max_slope_deg"][1]
    assert cases["RTK float"].config["gnss"]["mode"] == "rtk_float"
    for group, shape in (("curved rows R 15-30 m", "curved"),
                         ("contour rows, slope 4-8 deg", "contour")):  # fmt: skip
        assert outside("layout.row_geometry", cases[group].overrides["layout"]["row_geometry"])
        assert cases[group].overrides["layout"]["row_geometry"] == shape
    obstacles = cases["stones 0.3/m², 5 % lodged"].overrides["obstacles"]
    assert outside("obstacles.stone_density", obstacles["stone_density"])
    assert outside("obstacles.stalk_lodging", obstacles["stalk_lodging"])
    dem = cases["second real DEM (BC interior, 25 m)"].overrides["terrain"]
    assert (dem["source"], spec.terrain.source) == ("dem", "embedded")
    for case in cases.values():  # every other axis drawn as in training, from the eval seeds
        assert case.env_kwargs()["scenario_seeds"] == list(EVAL_SCENARIO_SEEDS)


def test_the_second_dem_plants_every_test_field_far_from_any_training_terrain() -> None:
    """The held-out DEM is the file its licence note describes, and its fields lie thousands
    of kilometres from the embedded DEM every training field is cut from."""
    import hashlib
    import re

    import numpy as np
    from pyproj import Geod

    from baselines.suites import heldout_dem
    from scenario_gen.dem import load_embedded

    path = Path(heldout_dem())
    note = (path.parent / "README.md").read_text()
    digest = re.search(r"SHA-256\s+`([0-9a-f]{64})`", note)
    assert digest and hashlib.sha256(path.read_bytes()).hexdigest() == digest.group(1)
    assert "Apache License" in (path.parent / "LICENSE").read_text()

    home = load_embedded()
    rows, cols = home.shape
    corners = home.pixel_to_crs(np.array([0.0, cols]), np.array([0.0, rows]))
    lon, lat = home.to_lonlat().transform(*corners)
    (case,) = [c for c in suite("ood") if c.overrides.get("terrain", {}).get("source") == "dem"]
    env = gym.make(case.env_id, **case.env_kwargs())
    try:
        for seed in (EVAL_SEED, EVAL_SEED + 1):
            env.reset(seed=seed)
            scn = env.unwrapped.scenario
            assert scn.info["dem"] == path.name
            assert 54.58 < scn.geo.lat < 54.72 and -122.22 < scn.geo.lon < -121.98
            dist = Geod(ellps="WGS84").inv(
                [scn.geo.lon] * 4, [scn.geo.lat] * 4, [lon[0], lon[1], lon[0], lon[1]],
                [lat[0], lat[0], lat[1], lat[1]],
            )[2]  # fmt: skip
            assert min(dist) > 3.0e6  # metres
    finally:
        env.close()


def test_a_chosen_case_keeps_its_seeds_and_an_unknown_one_is_named() -> None:
    from baselines.bench import _chosen_cases
    from scenario_gen.errors import InputError

    cases = suite("ood")
    last = cases[-1].group
    # the jobs' seeds follow from the index in the whole suite, which choosing keeps
    assert _chosen_cases(cases, [last], "ood") == [len(cases) - 1]
    assert _chosen_cases(cases, None, "ood") == list(range(len(cases)))
    with pytest.raises(InputError) as e:
        _chosen_cases(cases, ["rows 0.9 m"], "ood")
    assert "--cases" in str(e.value) and "rows 0.9 m" in str(e.value) and last in str(e.value)


def test_the_paper_suite_drives_the_seed_robots_four_waypoints() -> None:
    """33 m along a lane, across the headland, 31 m back: the legs of the shipped waypoint
    file, through the datum, as the route every policy is scored on."""
    import numpy as np

    case = suite("paper")[0]
    # Nav2's waypoint follower (a goal per waypoint) and its default tree's recoveries
    assert case.config["task"]["waypoint_goals"] and case.config["task"]["recoveries"]
    env = gym.make(case.env_id, **case.env_kwargs())
    try:
        env.reset(seed=EVAL_SEED)
        route = env.unwrapped.scenario.route
        turn = np.flatnonzero(
            np.abs(np.diff(np.unwrap(np.arctan2(*np.diff(route.xy, axis=0).T[::-1])))) > 0.5
        )
        corners = route.xy[np.r_[0, turn + 1, len(route.xy) - 1]]
        legs = np.hypot(*np.diff(corners, axis=0).T)
        np.testing.assert_allclose(legs, [33.0, 6.0, 31.0], atol=1e-3)
        assert {"furrow", "headland"} == set(route.segment)
    finally:
        env.close()


def test_the_papers_ridged_case_drives_the_early_fields_and_seeds_on_ridges() -> None:
    """Paired with early corn: the same field, plants and reset seeds, only the ground ridged
    under the rows (the source paper's heightmap furrows)."""
    import numpy as np

    from baselines.bench import episode_seed
    from baselines.suites import PAPER_RIDGED

    cases = suite("paper")
    flat, ridged = cases[0], next(c for c in cases if c.group == PAPER_RIDGED)
    assert [c.group for c in cases[:2]] == ["corn-early", "corn-intermediate"]  # published
    assert episode_seed(cases.index(ridged), ridged, 3) == episode_seed(0, flat, 3)
    assert {k: v for k, v in ridged.overrides.items() if k != "furrows"} == flat.overrides
    a, b = flat.field(), ridged.field()
    np.testing.assert_array_equal(a.plants.x, b.plants.x)
    np.testing.assert_array_equal(a.route.xy, b.route.xy)
    assert not a.spec.furrows.enabled and b.spec.furrows.depth == 0.12
    across = a.rows.to_enu(np.zeros(9), np.linspace(-0.5, 0.5, 9) * a.rows.spacing)
    relief = b.terrain.height_at(*across) - a.terrain.height_at(*across)
    assert np.ptp(relief) > 0.1  # a ridge and a furrow between two rows


def test_published_sensitivity_rows_keep_their_places() -> None:
    """A case's index sets its episodes' seeds: rows are appended, never inserted, so every
    table already published (benchmark.md) reproduces."""
    published = [
        "default soil", "soil friction 0.4", "soil friction 0.8", "soil shear modulus 0.01 m",
        "soil shear modulus 0.05 m", "tread 0.15 m", "tread 0.25 m",
        "canopy 2.5 m, foliage 0.4 dB/m", "canopy 2.5 m, foliage 2 dB/m",
        "multipath slips every 120 s", "no multipath slips",
        "ground yields: sandy loam 15 % (LLL)", "ground yields: dry sand (LLL)",
        "proxy camera fitted on flat lanes", "multipath slips every 40 s",
    ]  # fmt: skip
    assert [c.group for c in suite("sensitivity")][: len(published)] == published


def test_sensitivity_cases_drive_the_same_fields_and_seeds_as_their_reference(
    tmp_path: Path,
) -> None:
    """Paired: a soil (or foliage) case differs from its kind's first case only in the value
    it sets, so the difference between their rows is that value's effect."""
    from baselines.cli import main

    cases = suite("sensitivity")
    soil = [c for c in cases if "soil" in c.config]
    assert len(soil) >= 3 and {c.seeds_of for c in soil} == {cases.index(soil[0])}
    # the multipath and camera cases: the default row's fields and seeds, only their value set
    slips = [c for c in cases if "multipath_mtbf_s" in c.config.get("gnss", {}).get("fix", {})]
    camera = [c for c in cases if "camera" in c.config]
    assert len(slips) == 3 and len(camera) == 1
    for c, key in [(c, "gnss") for c in slips] + [(c, "camera") for c in camera]:
        assert c.seeds_of == 0
        assert (c.overrides, c.randomize, c.env_id) == (
            cases[0].overrides,
            cases[0].randomize,
            cases[0].env_id,
        )
        # the reference row sets the soil to its defaults ({}), this row leaves it at them
        assert cases[0].config["soil"] == {}
        assert {k: v for k, v in c.config.items() if k != key} == {
            k: v for k, v in cases[0].config.items() if k not in (key, "soil")
        }
    out = tmp_path / "sens"
    picked = f"{soil[0].group};{soil[1].group}"
    code = main(
        ["bench", "--suite", "sensitivity", "--cases", picked, "--policies", "blind",
         "--seeds", "2", "--out", str(out)]
    )  # fmt: skip
    assert code == 0
    records = json.loads((out / "results.json").read_text())
    by_case: dict[str, list[Any]] = {}
    for r in records:
        by_case.setdefault(r["scenario"], []).append((r["seed"], r["geometry"]))
    first, second = by_case[soil[0].group], by_case[soil[1].group]
    assert first == second and len({g["scenario_seed"] for _, g in first}) == 2


@pytest.mark.parametrize("name", ["paper", "unseen", "ood", "long", "sensitivity"])
def test_the_navigation_suites_localise_as_a_nav2_user_does(name: str) -> None:
    """robot_localization set up as its documentation asks (the gps transform, lagged fixes
    smoothed, a GPS gate) drives every case; the env's row says so."""
    from baselines.bench import _make_env
    from baselines.suites import RL_USER_SETUP

    cases = suite(name)
    for case in cases:
        loc = case.config["localisation"]
        assert loc == {"kind": "robot_localization", "robot_localization": RL_USER_SETUP}
    env = _make_env(cases[0])
    try:
        env.reset(seed=0)
        label = env.unwrapped.conditions()["localisation"]
    finally:
        env.close()
    assert label.startswith("robot_localization (gps lever arm, smooth_lagged_data 1 s")
    assert "gps gate 5σ" in label


def test_the_oracle_is_the_localisation_suites_reference_and_says_it_is_an_upper_bound() -> None:
    from baselines.bench import _make_env

    cases = {c.group: c for c in suite("localisation")}
    for group in ("RTK fixed", "RTK float", "canopy 2.5 m"):
        assert cases[group].config["localisation"] == {"kind": "ekf"}
    env = _make_env(cases["canopy 2.5 m"])
    try:
        env.reset(seed=0)
        assert env.unwrapped.conditions()["localisation"].startswith("ekf (oracle, an upper bound)")
    finally:
        env.close()


def test_drift_cases_move_the_plants_and_nothing_else() -> None:
    """Paired: each `drift` case drives the first one's fields and seeds; its plants stray from
    the logged rows by at most its amplitude, and the route (the logged line) stays put."""
    import numpy as np

    from agrinav_gym.metrics import planted_lane_rmse
    from baselines.bench import episode_seed

    cases = suite("drift")
    assert [c.seeds_of for c in cases] == [None, 0, 0]
    # each case's records carry the error from the lanes as planted, the reference's too
    assert all(c.planted for c in cases)
    assert not any(c.planted for c in suite("unseen") + suite("paper"))
    fields = []
    for i, c in enumerate(cases):
        kw = c.env_kwargs()
        kw["config"] = {**kw["config"], "camera": {"model": "proxy"}}  # fields, not pictures
        env = gym.make(c.env_id, **kw)
        try:
            env.reset(seed=episode_seed(i, c, 0))
            u = env.unwrapped
            amp = u.scenario.spec.layout.drift_amplitude
            p = u.scenario.plants
            fields.append((amp, np.column_stack([p.x, p.y]), u.route.xy.copy()))
            # the route is the logged line: measured from the lanes as planted it is off by
            # the drift (at most the amplitude), on the logged rows by nothing
            on_route = planted_lane_rmse(u.route.xy, u.scenario)
            assert on_route is not None and on_route <= amp + 1e-9
            assert (on_route < 1e-9) == (amp == 0.0)
        finally:
            env.close()
    (a0, plants0, route0), *drifted = fields
    assert a0 == 0.0
    for amp, plants, route in drifted:
        assert amp > 0 and np.array_equal(route, route0)
        assert plants.shape == plants0.shape
        moved = np.hypot(*(plants - plants0).T)
        # sideways only, within the amplitude (plus rounding); most plants move
        assert moved.max() <= amp + 1e-9 and np.median(moved) > 0.1 * amp
