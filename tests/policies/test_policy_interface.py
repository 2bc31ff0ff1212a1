import math
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym  # noqa: F401
from agrinav_gym.interface import OBSERVATION_KEYS
from policies import POLICIES, make_policy

from ..fields import TINY, drive

ALL = list(OBSERVATION_KEYS)


@pytest.mark.parametrize("name", [n for n in POLICIES if n != "ppo"])
def test_every_policy_acts_in_the_action_space(name: str) -> None:
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY, observations=ALL)
    try:
        pi = make_policy(name, env)
        obs, _ = env.reset(seed=0)
        pi.reset()
        for _ in range(5):
            a = pi.act(obs)
            assert env.action_space.contains(a), (name, a)
            obs, *_ = env.step(a)
    finally:
        env.close()


def test_missing_observation_and_unknown_policy_are_clear_errors() -> None:
    env = gym.make("AgriNav/FurrowFollowDepth-v3", scenario_overrides=TINY)
    try:
        with pytest.raises(ValueError, match="needs observations"):
            make_policy("rpp", env)
        with pytest.raises(ValueError, match="allowed"):
            make_policy("mpc", env)
        with pytest.raises(ValueError, match="empty ':' argument"):
            make_policy("dwb:", env)
        # no name at all: the policies are listed, not "allowed:  or :ARG"
        with pytest.raises(ValueError, match="allowed: dwb, rpp"):
            make_policy(":", env)
        with pytest.raises(ValueError, match="checkpoint"):
            make_policy("ppo", env)
    finally:
        env.close()


FLAT_1M = {
    "field": {"width": 5.0, "length": 12.0},
    "layout": {"row_spacing": 1.0, "headland": 2.5},
    "terrain": {"source": "plane", "margin": 4.0},
    "furrows": {"enabled": False, "roughness": 0.0},
}


@pytest.mark.parametrize(
    "name,env_id,rmse,max_cte",
    [
        ("stanley", "AgriNav/FurrowFollow-v3", 0.03, 0.05),
        # untuned (the paper's gains), Stanley cuts the U-turn by 0.1 m RMSE: no U-turn row
        # a straight lane: within the RTK GNSS + IMU heading noise of the estimated pose
        *[(n, "AgriNav/FurrowFollow-v3", 0.03, 0.05) for n in ("dwb", "rpp")],
        # the zigzag's headland U-turn (0.5 m radius) is the hard part for a path follower:
        # pure pursuit cuts it by up to half its 0.9 m maximum lookahead
        *[(n, "AgriNav/FieldRoute-v3", 0.08, 0.45) for n in ("dwb", "rpp")],
    ],
)
def test_classical_controllers_follow_straight_and_curved_paths(
    name: str, env_id: str, rmse: float, max_cte: float
) -> None:
    env = gym.make(env_id, scenario_overrides=FLAT_1M, observations=["gps", "imu", "odom", "route"])
    try:
        info = drive(env, make_policy(name, env), seed=0).info
        m = info["metrics"]
        assert info["is_success"], info.get("termination")
        assert m["rmse"] < rmse and m["max"] < max_cte and m["crops_hit"] == 0
    finally:
        env.close()


def test_rpp_with_reversing_drives_a_three_point_turn() -> None:
    """Nav2's allow_reversing: the lookahead stops at the cusp, the carrot behind the robot
    reverses it; without it RPP cannot drive the turn's reversing leg."""
    from policies.rpp import first_cusp

    over = {
        **FLAT_1M,
        "field": {"width": 5.0, "length": 16.0},
        "layout": {"row_spacing": 1.0, "headland": 4.0},
        "route": {"turn": "three_point"},
    }
    env = gym.make(
        "AgriNav/FieldRoute-v3",
        scenario_overrides=over,
        observations=["gps", "imu", "odom", "route"],
    )
    try:
        speeds: list[float] = []
        pol = make_policy("rpp", env, allow_reversing=True)

        def act(obs):  # type: ignore[no-untyped-def]
            a = pol.act(obs)
            speeds.append(float(a[0]))
            return a

        pol.reset()
        info = drive(env, act, seed=0).info
        assert info["is_success"], info.get("termination")
        assert info["metrics"]["crops_hit"] == 0 and info["metrics"]["max"] < 0.3
        assert min(speeds) < -0.1  # it reversed
        blocked = drive(env, make_policy("rpp", env), seed=0).info
        assert not blocked["is_success"] and blocked["metrics"]["completion"] < 60
    finally:
        env.close()
    assert first_cusp(np.array([[0.0, 0], [1, 0], [2, 0], [1.5, 0.1]])) == 2
    assert first_cusp(np.array([[0.0, 0], [1, 0], [2, 0.5]])) is None


def test_depth_follower_finds_the_lane() -> None:
    """The follower's single-frame lane estimate on eight fields of 1 m maize rows at stage 2,
    against the true lane centre 1 m ahead (where the camera sees the rows; its view starts
    0.5 m out): its mean error is below the 9.2 cm it has over the perception dataset's
    randomized fields (docs/datasets.md), which are harder than these flat ones."""
    env = gym.make(
        "AgriNav/FurrowFollowDepth-v3", scenario_overrides={**FLAT_1M, "crop": {"stage": 2}}
    )
    try:
        pi = make_policy("depth", env)
        offsets, headings = [], []
        for seed in range(8):
            obs, info = env.reset(seed=seed)
            est = pi.lane(obs["depth"][0])
            assert est is not None
            offset, heading = est
            # the true lane centre in the robot frame: offset -cte, direction -heading error
            true_heading = -info["heading_error"]
            ahead = 1.0
            truth = -info["cte"] + math.tan(true_heading) * ahead
            offsets.append(abs(offset + math.tan(heading) * ahead - truth))
            headings.append(abs(heading - true_heading))
        assert float(np.mean(offsets)) < 0.092, offsets
        assert float(np.mean(headings)) < 0.2, headings
    finally:
        env.close()


def _mean_offset(integral_time: float | None) -> float:
    """Mean signed cross-track error over the second half of a lane across a 10° side slope:
    gravity pulls the robot down the slope all the way, a steady disturbance. A soft
    proportional gain (k 0.5) lets it show as an offset of centimetres."""
    side = {**FLAT_1M, "terrain": {**FLAT_1M["terrain"], "slope_deg": 10.0, "aspect_deg": 0.0}}
    side["field"] = {"width": 5.0, "length": 20.0}
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=side, observations=["route"])
    try:
        run = drive(env, make_policy("stanley", env, k=0.5, integral_time=integral_time), seed=0)
        assert run.success, run.info.get("termination")
        ctes = run.ctes
        return sum(ctes[len(ctes) // 2 :]) / (len(ctes) - len(ctes) // 2)
    finally:
        env.close()


def test_stanleys_integral_removes_the_steady_offset_of_a_side_slope() -> None:
    without, with_integral = _mean_offset(None), _mean_offset(6.0)
    assert abs(without) > 0.005  # the slope leaves a steady offset without integral action
    assert abs(with_integral) < 0.5 * abs(without), (without, with_integral)


@pytest.mark.parametrize("name", ["rpp", "stanley", "dwb"])
def test_tuned_parameters_are_shipped_and_loaded(name: str) -> None:
    """``NAME:tuned`` is the tuning budget's result shipped with the package: the file the
    search wrote, loaded as the controller's parameters (DWB's on top of Nav2's defaults)."""
    import yaml

    from baselines.tune import SEARCH
    from policies import tuned_file
    from policies.dwb.params import DWBParams

    chosen = yaml.safe_load(tuned_file(name).read_text())
    env = gym.make("AgriNav/FieldRoute-v3", observations=list(OBSERVATION_KEYS))
    try:
        pol = make_policy(f"{name}:tuned", env)
        assert "tuned" in pol.describe() or name != "dwb"
    finally:
        env.close()
    if name == "dwb":
        got, furrow = DWBParams.load("tuned"), DWBParams.load("furrow")
        fp = chosen["FollowPath"]
        for key, (lo, hi) in SEARCH["dwb"].items():  # each searched value, within its range
            critic = key.split(".")[1]
            value = fp[critic]["scale"] if isinstance(fp[critic], dict) else fp[critic]
            assert lo <= value <= hi, key
        assert got.FollowPath.max_vel_x == pytest.approx(fp["max_vel_x"])
        assert got.local_costmap == furrow.local_costmap  # the search changed no costmap value
    else:
        for key, value in chosen.items():
            lo, hi = SEARCH[name][key]
            assert lo <= value <= hi, key


BENCHMARK_PARAMS = sorted(
    p
    for p in (Path(__file__).parents[2] / "benchmarks").glob("*.yaml")
    if p.name.split("_")[0] in ("dwb", "rpp", "stanley")
)


@pytest.mark.parametrize("path", BENCHMARK_PARAMS, ids=lambda p: p.name)
def test_every_shipped_controller_file_loads_as_its_controller(path: Path) -> None:
    """The parameter files benchmark.md's commands name (``NAME:benchmarks/FILE.yaml``) build
    their controller: a key the controller no longer has would stop a published command."""
    name = path.name.split("_")[0]
    env = gym.make("AgriNav/FieldRoute-v3", observations=list(OBSERVATION_KEYS))
    try:
        pol = make_policy(f"{name}:{path}", env)
        assert pol.describe()
    finally:
        env.close()


@pytest.mark.parametrize("name", ["rpp", "stanley"])
def test_every_searched_value_is_one_the_controller_accepts(name: str) -> None:
    from baselines.tune import SEARCH

    table = POLICIES[name].PARAMS
    for key, (lo, hi) in SEARCH[name].items():
        assert table[key].ok(lo) and table[key].ok(hi), key


@pytest.mark.parametrize(
    "name,text,needle",
    [
        ("rpp", "min_lookahead: -0.5\n", "min_lookahead: got -0.5"),
        ("rpp", "desired_linear_vel: 0\n", "desired_linear_vel: got 0"),
        ("rpp", "lookahead_time: null\n", "lookahead_time: got None"),
        ("rpp", "desired_linear_vel: true\n", "desired_linear_vel: got True"),
        ("rpp", "lookahead_time: " + "1" * 400 + "\n", "lookahead_time"),
        ("rpp", "min_lookahead: 1.0\n", "at most max_lookahead (0.9)"),  # the default max
        ("rpp", "robot: 1\n", "unknown parameters"),
        ("rpp", "1.5: 2\n", "unknown parameters"),
        ("rpp", "allow_reversing: 1\n", "allow_reversing: got 1"),
        ("stanley", "integral_time: 0\n", "integral_time: got 0"),
        ("stanley", "k: -2.5\n", "k: got -2.5"),
        ("stanley", "k_soft: 0\n", "k_soft: got 0"),
        # the parameter's own range, not a generic "number, true/false or null" it refuses
        ("rpp", "desired_linear_vel: fast\n", "desired_linear_vel: got 'fast'; allowed: a number"),
        # another controller's file: its names are unknown here (not "a number" for a section)
        ("stanley", "FollowPath: {PathAlign: {scale: 32}}\n", "unknown parameters"),
        ("rpp", "", "holds no parameters"),
        # the file and the line, not the file's first characters (the path may be shortened)
        (
            "rpp",
            "desired_linear_vel: [1\n",
            "not valid YAML (while parsing a flow sequence, line 2",
        ),
    ],
)
def test_a_parameter_file_outside_the_ranges_is_refused_before_any_env(
    tmp_path: Path, name: str, text: str, needle: str
) -> None:
    from policies import check_policy_spec
    from scenario_gen.errors import InputError

    path = tmp_path / "p.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        check_policy_spec(f"{name}:{path}")
    assert needle in str(info.value) and len(str(info.value).splitlines()) == 1


def test_stanley_without_integral_action_takes_null() -> None:
    from policies import POLICIES

    assert POLICIES["stanley"].PARAMS["integral_time"].ok(None)


def test_keywords_outside_the_ranges_are_refused_as_files_are() -> None:
    from scenario_gen.errors import InputError

    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)
    try:
        with pytest.raises(InputError, match="max_lookahead: got -1"):
            make_policy("rpp", env, max_lookahead=-1.0)
        with pytest.raises(InputError, match="min_lookahead"):
            make_policy("rpp", env, min_lookahead=0.6, max_lookahead=0.4)
    finally:
        env.close()


@pytest.mark.parametrize(
    "follow,field",
    [
        ({"min_vel_x": 0.8, "max_vel_x": 0.3}, "dwb.FollowPath.min_vel_x"),
        ({"max_vel_x": 0.0}, "dwb.FollowPath.max_vel_x"),
        ({"acc_lim_x": 0.0}, "dwb.FollowPath.acc_lim_x"),
    ],
)
def test_a_dwb_window_the_robot_cannot_move_in_is_refused(follow: dict, field: str) -> None:
    from policies.dwb.params import DWBParams
    from scenario_gen.errors import InputError

    with pytest.raises(InputError) as info:
        DWBParams.load({"FollowPath": follow})
    assert info.value.field == field


def test_a_parameter_files_suffix_is_read_in_any_case(tmp_path: Path) -> None:
    from policies import check_policy_spec

    path = tmp_path / "BEST.YAML"
    path.write_text("desired_linear_vel: 0.4\n")
    assert check_policy_spec(f"rpp:{path}") == ("rpp", str(path))


def test_a_speed_past_the_robots_is_noted_not_clipped_silently(tmp_path: Path) -> None:
    import yaml

    from scenario_gen.errors import Notice

    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)
    try:
        v_max = env.unwrapped.interface.v_max
        for name in ("rpp", "stanley"):
            with pytest.warns(Notice, match=rf"{name} desired_linear_vel 2.5 m/s is above"):
                make_policy(name, env, desired_linear_vel=2.5)
        dwb = tmp_path / "fast.yaml"
        dwb.write_text(yaml.safe_dump({"FollowPath": {"max_vel_x": 2.0 * v_max}}))
        with pytest.warns(Notice, match=r"dwb FollowPath\.max_vel_x .* clips the command"):
            make_policy(f"dwb:{dwb}", env)
        with warnings.catch_warnings():
            warnings.simplefilter("error", Notice)  # at the robot's own limit: nothing to say
            make_policy("rpp", env, desired_linear_vel=v_max)
    finally:
        env.close()


def test_a_description_names_every_parameter_off_its_default() -> None:
    """Two RPP rows of different parameter files both read "0.8 m/s, lookahead 0.3-0.9 m":
    the benchmark's conditions could not tell them apart."""
    env = gym.make("AgriNav/FurrowFollow-v3", scenario_overrides=TINY)
    try:
        plain = make_policy("rpp", env).describe()
        assert ";" not in plain
        rpp = make_policy("rpp", env, min_radius=3.0, approach_dist=2.0).describe()
        assert rpp.endswith("; min_radius 3, approach_dist 2)")
        st = make_policy("stanley", env, k_soft=0.5, integral_limit=0.2).describe()
        assert st.endswith("; k_soft 0.5, integral_limit 0.2)")
    finally:
        env.close()
