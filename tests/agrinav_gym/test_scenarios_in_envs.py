from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym
import scenario_gen as sg
from scenario_gen import ScenarioError

from .helpers import TINY, make


def test_register_scenario_from_a_directory(tmp_path: Path) -> None:
    scn = sg.generate(sg.preset("early-corn", **TINY), seed=5)
    sg.save(scn, tmp_path / "s")
    a = agrinav_gym.register_scenario("TinyDir", tmp_path / "s")
    b = agrinav_gym.register_scenario("TinyRoute", tmp_path / "s", task="FieldRoute")
    assert (a, b) == ("AgriNav/TinyDir-v3", "AgriNav/TinyRoute-v3")  # the task's version
    assert gym.spec(b).entry_point.endswith("make_field_route")
    for env_id in (a, b):
        gym.spec(env_id).to_json()  # serialisable: Minari and zoo tools rely on it
        env = gym.make(env_id)
        try:
            env.reset(seed=0)
            env.step(np.array([0.5, 0.0], np.float32))
            assert env.unwrapped.scenario.spec.crop.stage == 1
        finally:
            env.close()
    with pytest.raises(ScenarioError, match="scenario.json"):
        agrinav_gym.register_scenario("Nope", tmp_path / "missing")


def test_register_scenario_refuses_objects_bad_tasks_and_built_in_names(tmp_path: Path) -> None:
    scn = sg.generate(sg.preset("early-corn", **TINY), seed=5)
    sg.save(scn, tmp_path / "s")
    with pytest.raises(ScenarioError, match="save"):
        agrinav_gym.register_scenario("TinyObject", scn)  # type: ignore[arg-type]
    with pytest.raises(ScenarioError) as info:
        agrinav_gym.register_scenario("Tiny", tmp_path / "s", task="route")
    assert info.value.field == "task" and "FieldRoute" in str(info.value)
    before = gym.spec("AgriNav/FurrowFollow-v3")
    for name in ("FurrowFollow", "FieldRoute", "FurrowFollowDepth"):
        with pytest.raises(ScenarioError, match="built-in"):
            agrinav_gym.register_scenario(name, tmp_path / "s")
    assert gym.spec("AgriNav/FurrowFollow-v3") is before
    assert gym.spec("AgriNav/FurrowFollow-v3").kwargs == {}
    # what gym.make would refuse is refused at registration, nothing registered
    for kwargs, field in (
        ({"colour": "red"}, "kwargs"),
        ({"config": {"robot": {"v_max": 99.0}}}, "config.robot.v_max"),
        ({"config": {"robot": {"v_max": float("nan")}}}, "config.robot.v_max"),
        ({"scenario_seeds": [float("nan")]}, "kwargs"),  # no NaN in the JSON spec
        # refused only once an env is built: it is, once, at registration
        ({"observations": ["lidar"]}, "observations"),
        ({"render_mode": "foo"}, "render_mode"),
        ({"scenario": "default"}, "kwargs.scenario"),
    ):
        with pytest.raises(ScenarioError) as info:
            agrinav_gym.register_scenario("TinyBad", tmp_path / "s", **kwargs)
        assert info.value.field == field, info.value
        assert "AgriNav/TinyBad-v3" not in gym.registry
    # a refused re-registration leaves the earlier one in place; building the env to check
    # it does not show the user the fixed-field notice meant for their own envs
    import warnings

    from agrinav_gym.scenarios import FixedFieldWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error", FixedFieldWarning)
        good = agrinav_gym.register_scenario("TinyKept", tmp_path / "s")
    kept = gym.spec(good)
    with pytest.raises(ScenarioError):
        agrinav_gym.register_scenario("TinyKept", tmp_path / "s", observations=["lidar"])
    assert gym.spec(good) is kept


@pytest.mark.parametrize("env_id", list(agrinav_gym.ENV_IDS))
def test_every_registered_env_spec_serialises(env_id: str) -> None:
    assert env_id in gym.spec(env_id).to_json()


def test_scenario_bank_samples_every_scenario(tmp_path: Path) -> None:
    from baselines.cli import main

    assert (
        main(
            [
                "scenario",
                "--preset",
                "default",
                "--count",
                "3",
                "--out",
                str(tmp_path / "bank"),
                "--no-preview",
                "--set",
                "field.width=6",
                "--set",
                "field.length=14",
                "--set",
                "layout.headland=2",
            ]
        )
        == 0
    )
    env_id = agrinav_gym.register_scenario_bank("TinyBank", tmp_path / "bank")
    env = gym.make(env_id)
    try:
        seeds = set()
        for i in range(12):
            env.reset(seed=i)
            seeds.add(env.unwrapped.scenario.seed)
        assert seeds == {0, 1, 2}
    finally:
        env.close()
    with pytest.raises(ScenarioError, match="no scenario"):
        agrinav_gym.register_scenario_bank("Empty", tmp_path)


def test_randomize_draws_new_scenarios_and_env_params() -> None:
    env = make(
        randomize={"crop.stage": [1, 5], "gnss.mode": {"choices": ["rtk_fixed", "standalone"]}}
    )
    try:
        stages, modes = set(), set()
        for i in range(8):
            env.reset(seed=i)
            stages.add(env.unwrapped.scenario.spec.crop.stage)
            modes.add(env.unwrapped.sensors.gnss.cfg.mode)
        assert len(stages) >= 3 and modes == {"rtk_fixed", "standalone"}
    finally:
        env.close()


def test_former_randomize_key_names_still_work_with_a_warning() -> None:
    with pytest.warns(DeprecationWarning, match="randomize.gnss_mode is now randomize.gnss.mode"):
        env = make(randomize={"gnss_mode": {"choices": ["standalone"]}})
    try:
        env.reset(seed=0)
        assert env.unwrapped.sensors.gnss.cfg.mode == "standalone"
    finally:
        env.close()
    with pytest.raises(ScenarioError, match="given twice"):
        make(randomize={"gnss_mode": {"choices": ["standalone"]}, "gnss.mode": [0, 1]})


def test_lighting_is_a_config_section_the_cameras_use() -> None:
    """``config.lighting`` sets the sun the RGB is shaded with; randomizing it overrides it."""
    rgb = {"camera": {"rgb": True, "width": 32, "height": 24}}
    frames = []
    for elevation in (15.0, 85.0):
        env = make(
            observations=["depth"],
            config={**rgb, "lighting": {"sun_elevation_deg": elevation}},
        )
        try:
            _, info = env.reset(seed=0)
            frames.append(info["rgb"].astype(float).mean())
        finally:
            env.close()
    assert frames[1] > frames[0] + 5  # a high sun lights the ground more (Lambert: sin el)


def test_reset_options_switch_scenario_and_lane() -> None:
    env = make()
    try:
        env.reset(seed=0, options={"lane": 2})
        lane = env.unwrapped.scenario.lanes[2]
        assert np.allclose(env.unwrapped.route.xy[-1], lane[1])
        other = sg.generate(sg.preset("mature-corn", **TINY), seed=1)
        env.reset(seed=0, options={"scenario": other})
        assert env.unwrapped.scenario is other
        env.reset(seed=1)  # a fixed field env keeps the switched scenario (its docstring)
        assert env.unwrapped.scenario is other
        with pytest.raises(ScenarioError, match="options"):
            env.reset(options={"lanes": 1})
        with pytest.raises(ScenarioError, match="options.lane"):
            env.reset(options={"lane": 999})
    finally:
        env.close()


def test_a_failed_reset_leaves_the_env_as_before_and_the_episode_ended() -> None:
    """The scenario option was taken, and the world rebuilt, before the lane was checked: the
    failed reset's field stayed for later resets and step() drove on in it."""
    env = make()
    try:
        env.reset(seed=0)
        before = env.unwrapped.scenario
        for _ in range(5):
            env.step(np.array([0.5, 0.0], np.float32))
        other = sg.generate(sg.preset("mature-corn", **TINY), seed=1)
        lanes = len(other.lanes)
        with pytest.raises(ScenarioError, match="options.lane"):
            env.reset(seed=3, options={"scenario": other, "lane": lanes + 5})
        assert env.unwrapped.scenario is before
        with pytest.raises(gym.error.ResetNeeded, match="reset failed"):
            env.step(np.array([0.5, 0.0], np.float32))
        # the stream is as before the failed call: an unseeded reset draws what it would have
        obs, _ = env.reset()
        twin = make()
        try:
            twin.reset(seed=0)
            for _ in range(5):
                twin.step(np.array([0.5, 0.0], np.float32))
            expected, _ = twin.reset()
        finally:
            twin.close()
        assert env.unwrapped.scenario is before
        assert all(np.array_equal(obs[k], expected[k]) for k in obs)
    finally:
        env.close()


@pytest.mark.parametrize(
    "kwargs,field",
    [
        ({"config": {"robot": {"v_maxx": 1.0}}}, "config.robot.v_maxx"),
        ({"config": {"robot": {"physics_hz": 250}}}, "config.robot.physics_hz"),
        # too slow for the default soil's spring-damper: the rate is named, not the soil
        ({"config": {"robot": {"physics_hz": 100}}}, "config.robot.physics_hz"),
        ({"config": {"gnss": {"rate_hz": 3}}}, "config.gnss.rate_hz"),
        ({"observations": ["lidar"]}, "observations"),
        ({"render_mode": "ascii"}, "render_mode"),
        ({"scenario": "no-such-preset"}, "scenario"),
        ({"randomize": {"crop.stag": [1, 2]}}, "randomize.crop.stag"),
        ({"randomize": {"crop.stage": "all"}}, "randomize.crop.stage"),
    ],
)
def test_bad_env_arguments(kwargs: dict, field: str) -> None:
    import warnings

    with pytest.raises(ScenarioError) as info, warnings.catch_warnings():
        # gym.make warns about an unlisted render mode before the env refuses it
        warnings.filterwarnings("ignore", message=".*render_mode='ascii'")
        make(**kwargs)
    assert info.value.field == field


@pytest.mark.parametrize(
    ("ranges", "field"),
    [
        # stage 5 exists for corn but not for cabbage: only the pair is invalid
        ({"crop.species": {"choices": ["corn", "cabbage"]}, "crop.stage": [1, 5]}, "crop."),
        # 3 × 0.17 m of jitter passes half of 1.2 m rows, not half of 0.9 m ones
        ({"layout.jitter_lateral": [0.0, 0.17], "layout.row_spacing": [0.9, 1.2]}, "layout."),
    ],
)
def test_randomization_is_checked_where_two_ranges_meet(ranges: dict, field: str) -> None:
    from agrinav_gym.scenarios import Randomization
    from scenario_gen.errors import InputError

    base = sg.ScenarioSpec().replace({"layout.row_spacing": 1.2, "crop.species": "corn"})
    extra = {"layout.weed_density": [0.0, 2.0], "terrain.margin": [6.0, 10.0]}
    with pytest.raises(InputError) as exc:
        Randomization({**ranges, **extra}, base)
    assert exc.value.field.startswith(f"randomize.{field}")
    # each range alone is fine
    for key, value in ranges.items():
        Randomization({key: value, **extra}, base)


@pytest.mark.parametrize(
    ("over", "field"),
    [
        ({"terrain.source": "plane", "terrain.site": "latlon"}, "site"),
        ({"terrain.site": "flattest", "terrain.lat": 36.5}, "lat"),
        ({"terrain.site": "flattest", "terrain.max_slope_deg": 5.0}, "max_slope_deg"),
        ({"terrain.source": "embedded", "terrain.path": "x.tif"}, "path"),
        ({"terrain.source": "embedded", "terrain.slope_deg": 5.0}, "slope_deg"),
        ({"terrain.source": "embedded", "terrain.aspect_deg": 5.0}, "aspect_deg"),
        ({"terrain.source": "plane", "terrain.up_axis": "y"}, "up_axis"),
        ({"terrain.source": "embedded", "terrain.fill_max_pixels": 3}, "fill_max_pixels"),
        ({"terrain.site": "steepest", "field.geojson": "field.geojson"}, "site"),
    ],
)
def test_a_terrain_field_its_source_does_not_read_is_refused(
    over: dict[str, Any], field: str
) -> None:
    """Set and silently ignored (the site moved nowhere), now refused in the user's spec;
    a randomization may still draw a site and a slope bound together."""
    from scenario_gen.errors import InputError
    from scenario_gen.generate import check_fields_used

    with pytest.raises(InputError) as exc:
        check_fields_used(sg.ScenarioSpec().replace(over))
    assert exc.value.field == f"terrain.{field}"
    if "field.geojson" not in over:  # the env refuses the same overrides
        section = {k.split(".")[1]: v for k, v in over.items()}
        with pytest.raises(InputError) as exc:
            make(scenario_overrides={"terrain": section})
        assert exc.value.field == f"terrain.{field}"
    rand = {"terrain.site": {"choices": ["flattest", "steepest"]}, "terrain.max_slope_deg": [2, 8]}
    make(randomize=rand).close()


def test_coupled_fields_cover_every_cross_field_check() -> None:
    # check_spec's verdicts depend only on the fields COUPLED_FIELDS groups: an invalid spec
    # for each of its checks names a field of one group
    from scenario_gen.errors import InputError
    from scenario_gen.generate import COUPLED_FIELDS, check_spec

    grouped = set().union(*COUPLED_FIELDS)
    bad = [
        {"crop.species": "cabbage", "crop.stage": 5},
        {"terrain.source": "embedded", "terrain.datum": [47.0, 8.0, 400.0]},
        {"layout.row_spacing": 0.6, "layout.jitter_lateral": 0.2},
        {"layout.plant_spacing": 0.1, "layout.jitter_longitudinal": 0.05},
    ]
    for over in bad:
        with pytest.raises(InputError) as exc:
            check_spec(sg.ScenarioSpec().replace(over))
        assert exc.value.field in grouped and set(over) <= grouped


@pytest.mark.parametrize(
    "listing,needle",
    [
        ("scenarios: [a]\n" + "#" * (2 << 20) + "\n", "at most"),  # sized before it is read
        ("scenarios: [../../elsewhere]\n", "inside the bank"),
        ("scenarios: [/etc]\n", "inside the bank"),
        ("- a\n", "mapping"),
    ],
)
def test_a_bad_bank_listing_is_one_clear_error(tmp_path: Path, listing: str, needle: str) -> None:
    from agrinav_gym.scenarios import Bank

    (tmp_path / "bank.yaml").write_text(listing)
    with pytest.raises(ScenarioError, match=needle):
        Bank(tmp_path)


@pytest.mark.parametrize(
    "edit,field",
    [
        (lambda p: p.x.__setitem__(0, np.nan), "scenario.plants.x"),
        (lambda p: p.species.__setitem__(0, "banana"), "scenario.plants.species"),
        (lambda p: p.height.__setitem__(0, -1.0), "scenario.plants.height"),
    ],
)
def test_a_scenario_object_is_checked_as_load_checks_a_folder(edit, field: str) -> None:  # type: ignore[no-untyped-def]
    import dataclasses

    scn = sg.generate(sg.preset("default", **TINY), 0)
    p = scn.plants
    plants = dataclasses.replace(
        p, x=p.x.copy(), height=p.height.copy(), species=p.species.astype(object).copy()
    )
    edit(plants)
    with pytest.raises(ScenarioError) as e:
        gym.make("AgriNav/FurrowFollow-v3", scenario=dataclasses.replace(scn, plants=plants))
    assert e.value.field == field


#: contour rows on small fields whose slope window is drawn: some draws are too flat for
#: contour rows, or leave no lane between their rows, and the generator refuses them
CONTOUR = {
    "field": {"width": 8.0, "length": 12.0},
    "layout": {"row_geometry": "contour"},
    "terrain": {"site": "steepest"},
    "route": {"lanes": 1},
}


def test_a_refused_draw_is_drawn_again_from_the_same_stream() -> None:
    from agrinav_gym.scenarios import RefusedDrawWarning, ScenarioSource

    def draws() -> tuple[list[float], int]:
        src = ScenarioSource(
            "paper-p1", CONTOUR, 0, (0, 10**6), randomize={"terrain.max_slope_deg": [0.3, 6.0]}
        )
        rng = np.random.default_rng(0)
        slopes = [src.sample(rng, src.first)[0].spec.terrain.max_slope_deg for _ in range(4)]
        return slopes, src.redraws

    with pytest.warns(RefusedDrawWarning, match="drawn again"):
        slopes, redraws = draws()
    assert redraws > 0  # without redrawing, this reset would have raised
    with pytest.warns(RefusedDrawWarning):
        assert draws() == (slopes, redraws)  # the same stream, the same fields


def test_ranges_the_generator_always_refuses_fail_naming_the_last_reason() -> None:
    from agrinav_gym.scenarios import MAX_REDRAWS, RefusedDrawWarning, ScenarioSource

    # the base field (6° window) is fine; no drawn window (≤ 0.2°) suits contour rows
    over = {**CONTOUR, "terrain": {"site": "steepest", "max_slope_deg": 6.0}}
    src = ScenarioSource("paper-p1", over, randomize={"terrain.max_slope_deg": [0.1, 0.2]})
    with pytest.warns(RefusedDrawWarning), pytest.raises(ScenarioError) as e:
        src.sample(np.random.default_rng(0), src.first)
    msg = str(e.value)
    # it names the range the user gave (the only randomized key), not a drawn value
    assert e.value.field == "randomize.terrain.max_slope_deg" and e.value.value == "[0.1, 0.2]"
    assert f"{MAX_REDRAWS + 1} draws in a row" in msg
    assert "were refused, the last: terrain." in msg or "the last: layout." in msg
