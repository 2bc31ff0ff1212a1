"""Bad input to the env API: one InputError naming the field, never a traceback from inside."""

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from agrinav_gym import InputError
from agrinav_gym.robot import RobotGeometry

from .helpers import TINY

ID = "AgriNav/FurrowFollow-v3"
ID_DEPTH = "AgriNav/FurrowFollowDepth-v3"


@pytest.mark.parametrize(
    "kwargs,field",
    [
        ({"config": "fast"}, "config"),
        ({"config": ["robot"]}, "config"),
        ({"config": {1: {}}}, "config"),
        ({"config": {"robot": "fast"}}, "config.robot"),
        ({"config": {"reward": {"speed": {"weight": 1}}}}, "config.reward.speed"),
        ({"config": {"reward": {"cte": {"weight": "big"}}}}, "config.reward.cte.weight"),
        ({"randomize": "crop.stage"}, "randomize"),
        ({"randomize": {"crop.stage": [3, 1]}}, "randomize.crop.stage"),
        # choices the generator refuses whatever else is drawn: refused, not redrawn
        ({"randomize": {"terrain.source": {"choices": ["mesh", "embedded"]}}}, "randomize.terrain"),
        ({"randomize": {"crop.model": {"choices": [None, "no/such.dae"]}}}, "randomize.crop"),
        ({"randomize": {"crop.stage": [1, 6]}}, "randomize.crop.stage"),
        ({"randomize": {"crop.stage": [1.5, 3]}}, "randomize.crop.stage"),
        ({"randomize": {"crop": [1, 2]}}, "randomize.crop"),
        ({"randomize": {"gnss.mode": {"choices": ["rtk_fixed", "dgps"]}}}, "randomize.gnss.mode"),
        ({"randomize": {"gnss.mode": [0, 1]}}, "randomize.gnss.mode"),
        ({"randomize": {"lighting.soil_rgb": [0.5, 0.6]}}, "randomize.lighting.soil_rgb"),
        (
            {"randomize": {"lighting.soil_rgb": [[0.5, 0.4], [0.6, 0.5, 0.4]]}},
            "randomize.lighting.soil_rgb",
        ),
        (
            {"randomize": {"lighting.sun_elevation_deg": [10, 400]}},
            "randomize.lighting.sun_elevation_deg",
        ),
        (
            {"randomize": {"crop.species": {"choices": ["cabbage"]}, "crop.stage": [1, 5]}},
            "randomize",
        ),
        ({"scenario_seeds": [5, 5]}, "scenario_seeds"),
        ({"scenario_seed": -1}, "scenario_seed"),
        ({"scenario_seed": 2**64}, "scenario_seed"),
        ({"scenario": 42}, "scenario"),
        ({"scenario_overrides": "wide"}, "scenario_overrides"),
        ({"observations": ["gps", "gps"]}, "observations"),
        ({"observations": []}, "observations"),
        ({"bank": "/no/such/bank"}, "bank"),
        ({"scenario": "/no/such/folder"}, "scenario"),
        ({"nosuch": 1}, "env kwargs"),  # a typo in a kwargs file: not a TypeError traceback
        # a reward term given as 0 / False / [] is a slip, not the default weight of 1
        ({"config": {"reward": {"cte": 0}}}, "config.reward.cte"),
        ({"config": {"reward": {"cte": False}}}, "config.reward.cte"),
        ({"config": {"reward": {"cte": []}}}, "config.reward.cte"),
        # one field set twice, dotted and nested: which wins would be the keys' order
        ({"config": {"robot.v_max": 1.2, "robot": {"v_max": 0.5}}}, "robot.v_max"),
        # thresholds the fix-mode chain would leave without effect
        ({"config": {"gnss": {"fix": {"float_sky": 0.9, "fixed_sky": 0.1}}}}, "config.gnss"),
        ({"config": {"gnss": {"fix": {"carrier_db": 50.0, "code_db": 1.0}}}}, "config.gnss"),
        ({"bank": 5}, "bank"),
        ({"observations": 5}, "observations"),
        ({"observations": [["gps"]]}, "observations"),
        ({"observations": {"gps": False}}, "observations"),  # its keys would have been taken
        ({"scenario": ""}, "scenario"),
        # the depth camera draws them: without it they would silently never appear in info
        ({"config": {"camera": {"rgb": True}}}, "config.camera.rgb"),
        ({"config": {"camera": {"segmentation": True}}}, "config.camera.segmentation"),
    ],
)
def test_bad_constructor_arguments(kwargs: dict[str, Any], field: str) -> None:
    kwargs.setdefault("scenario_overrides", TINY) if "scenario" not in kwargs else None
    with pytest.raises(InputError) as info:
        gym.make(ID, **kwargs).close()
    assert info.value.field.startswith(field), info.value


def test_a_range_error_names_the_range_given_not_a_sampled_value() -> None:
    with pytest.raises(InputError) as info:
        gym.make(ID, scenario_overrides=TINY, randomize={"layout.row_spacing": [0.5, 80.0]})
    assert info.value.value == [0.5, 80.0]


@pytest.fixture
def env() -> Any:
    e = gym.make(ID, scenario_overrides=TINY).unwrapped
    yield e
    e.close()


def test_step_before_reset(env: Any) -> None:
    with pytest.raises(InputError, match="reset"):
        env.step(np.zeros(2, np.float32))


@pytest.mark.parametrize(
    "action",
    [
        "forward",
        {"v": 1.0},
        [1.0],
        [[1.0, 0.0, 0.0]],
        [[0.5, 0.0]],  # a batch of one was flattened silently
        np.zeros((2, 1), np.float32),
        [np.nan, 0.0],
        [np.inf, 0.0],
        None,
        object(),
        ["0.5", "0"],  # strings were coerced to numbers
        [0.5 + 1j, 0.0],  # complex lost its imaginary part silently
    ],
)
def test_bad_actions(env: Any, action: Any) -> None:
    env.reset(seed=0)
    with pytest.raises(InputError) as info:
        env.step(action)
    assert info.value.field == "action"


def test_step_after_termination_needs_a_reset(env: Any) -> None:
    env.reset(seed=0)
    terminated = False
    for _ in range(2000):  # full speed, turning: out of the lane within seconds
        _, _, terminated, _, _ = env.step(np.array([1.0, 1.0], np.float32))
        if terminated:
            break
    assert terminated
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(2, np.float32))
    env.reset(seed=1)
    env.step(np.zeros(2, np.float32))  # a new episode steps again


def test_step_after_the_envs_own_truncation_needs_a_reset() -> None:
    """The route's clock (task.seconds_per_metre) truncates: the episode has ended, as after a
    termination (the robot drove on before)."""
    env = gym.make(ID, scenario_overrides=TINY, config={"task": {"seconds_per_metre": 0.1}})
    try:
        env.reset(seed=0)
        truncated = False
        for _ in range(200):
            _, _, terminated, truncated, _ = env.step(np.array([0.2, 0.0], np.float32))
            assert not terminated
            if truncated:
                break
        assert truncated
        with pytest.raises(gym.error.ResetNeeded):
            env.unwrapped.step(np.zeros(2, np.float32))
        env.reset(seed=1)
        env.step(np.zeros(2, np.float32))
    finally:
        env.close()


@pytest.mark.parametrize(
    "options,field",
    [
        ("lane 2", "options"),
        ({"lane": 1.5}, "options.lane"),
        ({"lane": "2"}, "options.lane"),
        ({"lane": 99}, "options.lane"),
        ({"lanes": 2}, "options"),
        ({"scenario": 3.14}, "options.scenario"),
        ({"scenario": "/no/such/scenario"}, "options.scenario"),
        ({"scenario": "nope"}, "options.scenario"),
    ],
)
def test_bad_reset_options(env: Any, options: Any, field: str) -> None:
    with pytest.raises(InputError) as info:
        env.reset(seed=0, options=options)
    assert info.value.field == field


@pytest.mark.parametrize("seed", [-1, 1.5, "0", True])
def test_bad_reset_seeds_are_refused_cleanly(env: Any, seed: Any) -> None:
    with pytest.raises(InputError) as info:
        env.reset(seed=seed)
    assert info.value.field == "seed"


def test_huge_seeds_are_honoured(env: Any) -> None:
    a, _ = env.reset(seed=2**64 + 5)
    b, _ = env.reset(seed=np.uint64(7))
    c, _ = env.reset(seed=2**64 + 5)
    assert all(np.array_equal(a[k], c[k]) for k in a) and b.keys() == a.keys()


def test_an_env_dropped_without_close_gives_its_physics_client_back() -> None:
    """Each pybullet client holds tens of MB: a forgotten env kept its one until exit."""
    import gc

    import pybullet as p

    from .helpers import make

    env = make()
    env.reset(seed=0)
    client = env.unwrapped.world.client
    assert p.isConnected(physicsClientId=client)
    del env
    gc.collect()
    assert not p.isConnected(physicsClientId=client)


def test_use_after_close(env: Any) -> None:
    env.reset(seed=0)
    env.close()
    env.close()  # closing twice is allowed
    for call in (lambda: env.reset(seed=0), lambda: env.step(np.zeros(2, np.float32)), env.render):
        with pytest.raises(InputError, match="close"):
            call()


def test_a_route_too_short_to_drive_is_refused_not_a_success(tmp_path: Any) -> None:
    """A degenerate route used to end at once as a success at 0 % completion. (Scenarios
    refuse routes shorter than the default's 1.3 m themselves: a 2 m one against a 1.5 m
    success tolerance, which needs 2.5 m.)"""
    import yaml

    from scenario_gen import generate, preset

    scn = generate(preset("default", **TINY), 0)
    (a, _b) = scn.lanes[0]
    lat, lon, _ = scn.geo.enu_to_geodetic([a[0], a[0] + 2.0], [a[1], a[1]], 0.0)
    wps = [{"latitude": float(la), "longitude": float(lo)} for la, lo in zip(lat, lon, strict=True)]
    path = tmp_path / "w.yaml"
    path.write_text(yaml.safe_dump({"waypoints": wps}))
    env = gym.make(
        "AgriNav/FieldRoute-v3",
        scenario_overrides={**TINY, "route": {"waypoints": str(path)}},
        config={"task": {"success_tolerance": 1.5}},
    )
    try:
        with pytest.raises(InputError, match="route of at least 2.5 m"):
            env.reset(seed=0)
    finally:
        env.close()


def test_a_scenario_path_is_named_for_what_is_wrong_with_it(tmp_path: Any) -> None:
    with pytest.raises(InputError, match="no such folder"):
        gym.make(ID, scenario=str(tmp_path / "missing"))
    with pytest.raises(InputError, match="a folder without scenario.json"):
        gym.make(ID, scenario=tmp_path)


def test_one_observation_name_is_one_observation() -> None:
    env = gym.make(ID, observations="gps", scenario_overrides=TINY)
    try:
        obs, _ = env.reset(seed=0)
        assert list(obs) == ["gps"]
    finally:
        env.close()


def test_a_physics_rate_too_low_for_the_soil_names_the_rate_it_needs() -> None:
    # the default stiffness is what refuses a low physics_hz: the rate the user changed is
    # named, with what would pass
    config: dict[str, Any] = {"robot": {"physics_hz": 40, "control_hz": 10}}
    with pytest.raises(InputError) as info:
        gym.make(ID, config=config).close()
    assert info.value.field == "config.robot.physics_hz" and info.value.value == 40
    assert "vertical_stiffness 60000" in str(info.value) and "at least 97" in str(info.value)
    # above it the corner damping is what refuses, and names the rate it needs in turn
    config["robot"]["physics_hz"] = 100
    with pytest.raises(InputError) as info:
        gym.make(ID, config=config).close()
    assert info.value.field == "config.robot.physics_hz" and info.value.value == 100
    assert "damping_ratio 0.3" in str(info.value) and "at least 148" in str(info.value)
    config["robot"]["physics_hz"] = 150  # what the messages asked for (a multiple of 10)
    gym.make(ID, config=config, scenario_overrides=TINY).close()
    # a soil value the user changed is named, with the rate it would need
    stiff = {"robot": {"physics_hz": 120}, "soil": {"vertical_stiffness": 1.5e5}}
    with pytest.raises(InputError) as info:
        gym.make(ID, config=stiff).close()
    assert info.value.field == "config.soil.vertical_stiffness"
    assert "physics_hz >= 152" in str(info.value)  # √(1.5e5 / 6.5) = 151.9
    soft = {"soil": {"damping_ratio": 0.1}}
    with pytest.raises(InputError) as info:
        gym.make(ID, config=soft).close()
    assert info.value.field == "config.soil.damping_ratio"
    # a stiffness the springs integrate but the default damping cannot hold still: the
    # stiffness is named, with the most it may be (ζ = 0.65·ω·dt: ω = 0.3 / 0.65 · 240 Hz)
    stiffer = {"soil": {"vertical_stiffness": 2e5}}
    with pytest.raises(InputError) as info:
        gym.make(ID, config=stiffer).close()
    assert info.value.field == "config.soil.vertical_stiffness" and info.value.value == 2e5
    corner = 0.25 * RobotGeometry.from_urdf().mass
    assert f"at most {corner * (0.3 / 0.65 * 240) ** 2:.0f} N/m" in str(info.value)
    soil = {"soil": {"vertical_stiffness": 0.99 * corner * (0.3 / 0.65 * 240) ** 2}}
    gym.make(ID, config=soil, scenario_overrides=TINY).close()


def test_the_camera_rate_is_checked_only_where_there_is_a_camera() -> None:
    """At a 10 Hz control rate the default 20 Hz camera cannot be: refused where the env
    observes depth, not where it has no camera (it used to be, in every env)."""
    config = {"robot": {"physics_hz": 240, "control_hz": 10}}
    gym.make(ID, config=config, scenario_overrides=TINY).close()
    with pytest.raises(InputError) as info:
        gym.make(ID_DEPTH, config=config, scenario_overrides=TINY).close()
    assert info.value.field == "config.camera.rate_hz" and "robot.control_hz (10)" in str(
        info.value
    )
    config["camera"] = {"rate_hz": 5}
    gym.make(ID_DEPTH, config=config, scenario_overrides=TINY).close()


def test_a_plane_too_steep_for_the_tyres_to_hold_the_robot_is_refused() -> None:
    """Past atan(μ) (31.0° at the default μ 0.6) the robot slides down from a standstill
    (tens of metres while it settles): no episode, so one error naming the slope and the
    friction; a grippier soil holds it."""
    plane = {**TINY, "terrain": {"source": "plane", "slope_deg": 31.0}}
    with pytest.raises(InputError) as info:
        gym.make(ID, scenario_overrides=plane)
    assert info.value.field == "terrain.slope_deg"
    assert "below 31.0°" in str(info.value) and "soil.friction 0.6" in str(info.value)
    gym.make(ID, scenario_overrides=plane, config={"soil": {"friction": 0.7}}).close()
    # a drawn slope is checked where it is drawn
    env = gym.make(
        ID,
        scenario_overrides={**TINY, "terrain": {"source": "plane"}},
        randomize={"terrain.slope_deg": [0.0, 60.0]},
    )
    try:
        with pytest.raises(InputError, match="terrain.slope_deg"):
            for seed in range(40):
                env.reset(seed=seed)
    finally:
        env.close()


def _tilted_dem(path: Any, slope_deg: float) -> str:
    """A 4 m UTM GeoTIFF of a plain rising ``slope_deg`` eastward."""
    import rasterio
    from rasterio.transform import from_origin

    n = 60
    z = 300.0 + np.tan(np.radians(slope_deg)) * np.broadcast_to(np.arange(n) * 4.0, (n, n))
    with rasterio.open(
        path, "w", driver="GTiff", height=n, width=n, count=1, dtype="float32",
        crs="EPSG:32616", transform=from_origin(500_000.0, 4_000_000.0, 4.0, 4.0),
    ) as ds:  # fmt: skip
        ds.write(z.astype(np.float32), 1)
    return str(path)


def test_a_dem_too_steep_under_the_start_is_refused_at_reset(tmp_path: Any) -> None:
    """The plane's limit on a DEM: a 57° site picked by latitude and longitude slid the robot
    73 m while it settled and gave a -21,586 reward on the first step. The ground under the
    four wheels at the start is measured; a gentler DEM drives."""
    for slope, refused in ((40.0, True), (8.0, False)):
        terrain = {"source": "dem", "path": _tilted_dem(tmp_path / f"{slope}.tif", slope)}
        env = gym.make(
            ID, scenario_overrides={**TINY, "terrain": {**TINY.get("terrain", {}), **terrain}}
        )
        try:
            if refused:
                with pytest.raises(InputError) as info:
                    env.reset(seed=0)
                assert info.value.field == "terrain" and "under the start" in str(info.value)
                assert "below 31.0°" in str(info.value)
            else:
                _, i = env.reset(seed=0)
                assert abs(i["cte"]) < 0.1
        finally:
            env.close()


def test_a_scenario_override_may_name_the_field() -> None:
    env = gym.make(ID, scenario_overrides={**TINY, "name": "north-block"})
    try:
        assert env.unwrapped.scenario.spec.name == "north-block"
    finally:
        env.close()


def test_an_episodes_numbers_before_reset_are_one_error() -> None:
    env = gym.make(ID, scenario_overrides=TINY)
    u = env.unwrapped
    try:
        for name in ("trajectory", "crops_hit_ids", "obstacles_hit_ids", "arc"):
            with pytest.raises(InputError, match="reset"):
                getattr(u, name)
        with pytest.raises(InputError, match="reset"):
            u.episode_metrics()
        env.reset(seed=0)
        assert u.trajectory.shape == (1, 2) and u.crops_hit_ids == frozenset()
    finally:
        env.close()


def test_a_bank_or_a_file_as_the_scenario_says_what_it_is(tmp_path: Any) -> None:
    import scenario_gen as sg

    bank = tmp_path / "bank"
    bank.mkdir()
    sg.save(sg.generate(sg.preset("default", **TINY), 0), bank / "seed-000000", preview=False)
    (bank / "bank.yaml").write_text("members: [seed-000000]\n")
    with pytest.raises(InputError, match="is a bank of scenarios") as info:
        gym.make(ID, scenario=str(bank))
    assert str(bank / "seed-000000") in str(info.value)
    afile = tmp_path / "field.yaml"
    afile.write_text("x: 1\n")
    with pytest.raises(InputError, match="is a file"):
        gym.make(ID, scenario=str(afile))
