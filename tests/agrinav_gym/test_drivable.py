"""The default envs are drivable: realistic crop contact, starts in the lane, controllers finish."""

import math

import gymnasium as gym
import numpy as np
import pytest

import agrinav_gym
import scenario_gen as sg
from agrinav_gym.robot import RobotGeometry
from agrinav_gym.sim.contact import CropContact


@pytest.mark.parametrize("env_id", list(agrinav_gym.ENV_IDS))
def test_default_scenario_starts_clear_of_the_crop(env_id: str) -> None:
    """Standing still at the perturbed start never touches a stalk (the first wave's default
    touched one on the first step in most episodes)."""
    env = gym.make(env_id, observations=["odom"])
    try:
        for seed in range(8):
            env.reset(seed=seed)
            for _ in range(5):
                _, _, term, _, info = env.step(np.zeros(2, np.float32))
            assert info["crops_hit"] == 0 and not term, (seed, info.get("termination"))
    finally:
        env.close()


def test_a_corridor_narrower_than_the_lane_holds_the_start_inside_it() -> None:
    """A start offset drawn wider than a user's narrow corridor would end every episode at its
    first step: the offset is held to half the corridor as it is to half the lane's room."""
    corridor = 0.02
    config = {"task": {"corridor": corridor, "start_lateral_std": 0.5}}
    env = gym.make("AgriNav/FurrowFollow-v3", observations=["odom"], config=config)
    try:
        for seed in range(6):
            env.reset(seed=seed)
            _, _, term, _, info = env.step(np.zeros(2, np.float32))
            assert not term, (seed, info.get("termination"))
            assert abs(info["cte"]) <= 0.5 * corridor + 0.005, (seed, info["cte"])  # + settling
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["AgriNav/FurrowFollow-v3", "AgriNav/FieldRoute-v3"])
def test_pure_pursuit_drives_the_default_scenario_without_touching_a_crop(env_id: str) -> None:
    from policies import make_policy

    env = gym.make(env_id, observations=["gps", "imu", "odom", "route"])
    try:
        pi = make_policy("rpp", env)
        obs, _ = env.reset(seed=10**9)
        pi.reset()
        while True:
            obs, _, term, trunc, info = env.step(pi.act(obs))
            if term or trunc:
                break
        assert info.get("termination") == "success"
        assert info["metrics"]["crops_hit"] == 0 and info["metrics"]["completion"] >= 95.0
    finally:
        env.close()


def test_shipped_field_route_ppo_drives_a_held_out_field_through_its_u_turn() -> None:
    """The shipped FieldRoute PPO (cloned from RPP, then PPO) on a field geometry from the
    evaluation seeds, as `agrinav train` set up its training: it finishes the route, U-turn
    included, without touching a crop (the from-scratch v1 model stalled in the headland)."""
    from baselines import hyperparams
    from policies import make_policy

    _, setup = hyperparams.load("AgriNav/FieldRoute-v3")
    env = gym.make(
        "AgriNav/FieldRoute-v3", **setup.env_kwargs, scenario_seeds=list(setup.eval_seeds)
    )
    try:
        pi = make_policy("ppo:shipped", env)
        obs, _ = env.reset(seed=setup.eval_seeds[0] + 5)  # a field no part of training drove
        pi.reset()
        while True:
            obs, _, term, trunc, info = env.step(pi.act(obs))
            if term or trunc:
                break
        assert info.get("termination") == "success", info.get("termination")
        assert info["metrics"]["crops_hit"] == 0
    finally:
        env.close()


def _contact_with_one_stalk(x: float, y: float, species: str = "corn", stage: int = 3):
    scn = sg.generate(
        sg.preset(
            "default",
            field={"width": 4.0, "length": 6.0},
            layout={"headland": 1.0},
            terrain={"source": "plane", "margin": 2.0},
            crop={"species": species, "stage": stage, "height_std": 0.0},
        ),
        seed=0,
    )
    p = scn.plants
    one = type(p)(
        np.array([x]),
        np.array([y]),
        np.zeros(1),
        np.zeros(1),
        np.zeros(1),
        np.zeros(1),
        p.height[:1],
        p.species[:1],
        p.stage[:1],
        np.zeros(1, np.int64),
    )
    return CropContact.from_scenario(
        type(scn)(**{**scn.__dict__, "plants": one}), RobotGeometry.from_urdf()
    )


def test_contact_is_wheels_and_chassis_against_the_catalog_stalk() -> None:
    geo = RobotGeometry.from_urdf()
    sp = sg.CATALOG["corn"]
    r = float(sp.stem_radius(sp.growth_of_stage(3)))
    assert 0.009 <= r <= 0.0125  # a V10 maize stalk is 2-2.5 cm across
    wheel_edge = 0.5 * geo.track + 0.5 * geo.wheel_width  # 0.31 m from the centreline
    # beside the front wheel: touching at (edge + r - 1 mm), clear at (edge + r + 1 mm)
    assert _contact_with_one_stalk(geo.wheelbase / 2, wheel_edge + r - 1e-3).touching(0, 0, 0) == [
        0
    ]
    assert _contact_with_one_stalk(geo.wheelbase / 2, wheel_edge + r + 1e-3).touching(0, 0, 0) == []
    # between the wheels (x = 0) only the narrower chassis reaches sideways
    chassis_edge = 0.5 * geo.chassis[1]
    assert _contact_with_one_stalk(0.0, chassis_edge + r - 1e-3).touching(0, 0, 0) == [0]
    assert _contact_with_one_stalk(0.0, wheel_edge - 0.02).touching(0, 0, 0) == []
    # the footprint turns with the robot: the same stalk ahead of a robot turned 90°
    c = _contact_with_one_stalk(0.0, 0.30)
    assert c.touching(0, 0, 0) == [] and c.touching(0, 0, math.pi / 2) == [0]
