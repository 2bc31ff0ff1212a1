"""Obstacles in the physics and the metrics: what a wheel meets, what stops the robot, what is
counted.

The physics checks put one obstacle in the robot's path on a flat plane (``FLAT``): the robot
starts on lane 3's centre facing along it (``STILL``) and drives straight at 0.5 m/s.
Tolerances come from the geometry (wheel radius, obstacle size) and the tyre's sinkage, not
from a recorded run.
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
import shapely

import scenario_gen as sg
from agrinav_gym.robot import RobotGeometry
from agrinav_gym.sim.contact import ObstacleContact, rects_overlap
from agrinav_gym.sim.obstacle_bodies import WINDOW_MARGIN
from scenario_gen.obstacles import Obstacles

from .helpers import FLAT, STILL, TINY, make

GEO = RobotGeometry.from_urdf()
R = GEO.wheel_radius
#: the crops never end these drives: only the obstacles are under test
CONFIG: dict[str, Any] = {"task": {**STILL["task"], "max_crops_hit": 10**6}}
LANE = {"lane": 3}
SPEED = 0.5  # m/s commanded (the action is SPEED / v_max)


@lru_cache(maxsize=1)
def _flat() -> sg.Scenario:
    return sg.generate(sg.preset("default").replace(FLAT), 0)


@lru_cache(maxsize=1)
def _start() -> tuple[float, float, float]:
    """The start pose on ``_flat()``'s lane 3 (the same at every reset: ``STILL``)."""
    env = make(scenario=_flat(), scenario_overrides=None, config=CONFIG)
    try:
        env.reset(seed=0, options=LANE)
        x, y, yaw = env.unwrapped.start
        return float(x), float(y), float(yaw)
    finally:
        env.close()


def _obstacles(*items: dict[str, Any]) -> Obstacles:
    """Obstacles placed relative to the start pose: ``ahead`` and ``left`` of it (m), turned
    ``turn`` from its heading (and ``roll``, ``pitch``: 0 unless given), on the plane."""
    x0, y0, yaw = _start()
    c, s = math.cos(yaw), math.sin(yaw)
    cols: dict[str, list[Any]] = {f.name: [] for f in dataclasses.fields(Obstacles)}
    for it in items:
        x = x0 + it["ahead"] * c - it.get("left", 0.0) * s
        y = y0 + it["ahead"] * s + it.get("left", 0.0) * c
        cols["kind"].append(it["kind"])
        cols["x"].append(x)
        cols["y"].append(y)
        cols["z"].append(float(_flat().terrain.height_at(x, y)))
        cols["roll"].append(it.get("roll", 0.0))
        cols["pitch"].append(it.get("pitch", 0.0))
        cols["yaw"].append(yaw + it.get("turn", 0.0))
        cols["length"].append(it["length"])
        cols["width"].append(it["width"])
        cols["height"].append(it["height"])
        cols["shape"].append(it.get("shape", 7))
    return Obstacles(
        np.array(cols["kind"], "<U6"),
        *(np.array(cols[k], float) for k in ("x", "y", "z", "roll", "pitch", "yaw")),
        *(np.array(cols[k], float) for k in ("length", "width", "height")),
        np.array(cols["shape"], np.int64),
    )


def _with(obstacles: Obstacles) -> sg.Scenario:
    return dataclasses.replace(_flat(), obstacles=obstacles)


@dataclasses.dataclass
class Drive:
    ahead: list[float]  # base_link's travel along the start heading, per step
    z: list[float]  # base height
    tilt: list[float]  # max(|roll|, |pitch|), rad
    wheel_z: list[list[float]]  # wheel centre heights above the plane (fl, fr, bl, br)
    contacts: list[set[tuple[int, int]]]  # (robot link, other body) pairs pybullet reports
    info: dict[str, Any]
    env: Any


def _drive(scn: sg.Scenario, steps: int, config: dict[str, Any] | None = None) -> Drive:
    env = make(scenario=scn, scenario_overrides=None, config=config or CONFIG)
    u = env.unwrapped
    env.reset(seed=0, options=LANE)
    x0, y0, yaw = _start()
    c, s = math.cos(yaw), math.sin(yaw)
    ground = float(_flat().terrain.height_at(x0, y0))  # the plane is level
    w = u.world
    out = Drive([], [], [], [], [], {}, env)
    for _ in range(steps):
        _, _, term, _, out.info = env.step(np.array([SPEED / u.cfg.robot.v_max, 0.0], np.float32))
        st = u.state
        out.ahead.append(float((st.pos[0] - x0) * c + (st.pos[1] - y0) * s))
        out.z.append(float(st.pos[2]))
        out.tilt.append(max(abs(float(st.rpy[0])), abs(float(st.rpy[1]))))
        out.wheel_z.append(
            [p.getLinkState(w.robot, j, physicsClientId=w.client)[0][2] - ground for j in w.wheels]
        )
        out.contacts.append(
            {(c_[3], c_[2]) for c_ in p.getContactPoints(bodyA=w.robot, physicsClientId=w.client)}
        )
        if term:
            break
    return out


def _flat_wheel_z() -> float:
    """A wheel centre's height over the plane while driving on bare ground: the radius less
    the tyre's sinkage (its load over the vertical stiffness)."""
    d = _drive(_flat(), 10)
    d.env.close()
    return float(np.mean(d.wheel_z[-1]))


# ---------------------------------------------------------------------- contact groups
def test_a_wheel_meets_an_obstacle_but_never_the_heightfield() -> None:
    """Collision groups: on bare ground pybullet reports no wheel contact at all (the tyre
    model is the wheels' only contact with the soil); a wheel rolling onto a stone gets one
    with the stone's body."""
    stone = _obstacles(
        dict(kind="stone", ahead=1.0, left=0.5 * GEO.track, length=0.08, width=0.08, height=0.03)
    )
    d = _drive(_with(stone), 60)
    try:
        w = d.env.unwrapped.world
        assert w.obstacles is not None and len(w.obstacles.bodies) == 1
        (body,) = w.obstacles.bodies.values()
        terrain = w.patch.body
        wheels = set(w.wheels)
        on_stone = [k for k, cs in enumerate(d.contacts) if any(b == body for _, b in cs)]
        assert on_stone, "no contact with the stone"
        # the front-left wheel (index 0) meets it first, then the back-left one
        met = {link for cs in d.contacts for link, b in cs if b == body}
        assert met <= wheels and w.wheels[0] in met and w.wheels[2] in met
        assert not any((link, terrain) in cs for cs in d.contacts for link in wheels)
        # the chassis rides 12 cm up: it meets neither the plane nor the 3 cm stone
        assert not any(link == -1 for cs in d.contacts for link, _ in cs)
    finally:
        d.env.close()


def test_fields_without_obstacles_drive_as_before() -> None:
    """The wheels' collision group changes nothing where there are no obstacles: a weaving
    drive over the default (furrowed, rough) tiny field ends where the code before obstacles
    left it (recorded on main at 432f143; any contact the wheels gained would move it by
    millimetres or more)."""
    config = {"task": {**STILL["task"], "max_crops_hit": 10**6, "corridor": 5.0}}
    env = make(scenario_overrides=TINY, config=config)
    try:
        env.reset(seed=3)
        for k in range(80):
            _, _, term, _, info = env.step(np.array([0.6, 0.1 if k < 40 else -0.1], np.float32))
            assert not term
        s = env.unwrapped.state
        got = [*s.pos.tolist(), *s.rpy.tolist(), *s.wheels]
    finally:
        env.close()
    before = [
        float.fromhex(h)
        for h in (
            "-0x1.3bccc602e6c35p+1",
            "0x1.a2fedf76f0128p-1",
            "0x1.beca1597451d7p-4",
            "-0x1.8606a03c412efp-8",
            "-0x1.1597d2316d99ep-6",
            "0x1.d44fc3bb5530bp-9",
            "0x1.884b9de5984c1p+2",
            "0x1.31e31d36c64abp+2",
            "0x1.884b8b4810435p+2",
            "0x1.31e30e3f6aef7p+2",
        )
    ]
    # the same bits here; a nanometre allows another libm's last bits, not a change of physics
    assert got == pytest.approx(before, rel=0, abs=1e-9)
    assert info["obstacles_hit"] == 0 and info["crops_hit"] == 7


def test_obstacles_out_of_reach_are_no_bodies_and_change_no_bit() -> None:
    """Obstacles beyond the window are not in pybullet at all: a drive past a field whose only
    stones lie 3 m to the side is the same, bit for bit, as the drive without them."""
    far = _obstacles(
        *(
            dict(kind="stone", ahead=a, left=3.0, length=0.1, width=0.1, height=0.05)
            for a in (0.5, 1.5, 2.5)
        )
    )
    runs = []
    for scn in (_flat(), _with(far)):
        d = _drive(scn, 40)
        w = d.env.unwrapped.world
        runs.append((d.ahead, d.z, d.wheel_z, None if w.obstacles is None else w.obstacles.bodies))
        d.env.close()
    assert runs[0][:3] == runs[1][:3]
    assert runs[0][3] is None and runs[1][3] == {}  # the world knew them, made no body


# ---------------------------------------------------------------------- what the robot meets
def test_a_fallen_stalk_is_driven_over() -> None:
    """A 2 cm stalk across the lane: each wheel is lifted by the stalk's diameter (plus the
    sinkage it has in the soil and not on the stalk) as it rolls over, and the robot goes on at
    its speed."""
    dia = 0.02
    stalk = _obstacles(
        dict(kind="stalk", ahead=1.0, turn=math.pi / 2, length=1.5, width=dia, height=dia)
    )
    flat_z = _flat_wheel_z()
    d = _drive(_with(stalk), 90)
    try:
        wz = np.array(d.wheel_z)
        lift = wz.max(axis=0) - flat_z
        expected = dia + (R - flat_z)  # rigid on the stalk's top, sunk in the soil before
        assert lift == pytest.approx([expected] * 4, abs=0.15 * dia)
        # progress goes on: 0.7 m ahead of the stalk at 0.5 m/s, the stalk crossing included
        ahead = np.array(d.ahead)
        assert ahead[-1] > 1.0 + 0.5 * GEO.wheelbase + 0.7
        crossing = (ahead > 1.0 - 0.5 * GEO.wheelbase - R) & (ahead < 1.0 + 0.5 * GEO.wheelbase + R)
        dt = d.env.unwrapped.dt
        speed = (ahead[crossing][-1] - ahead[crossing][0]) / (dt * (crossing.sum() - 1))
        assert speed > 0.85 * SPEED
        assert d.info["obstacles_hit"] == 1
        assert d.info["metrics"]["obstacles_hit_by_kind"] == {"stone": 0, "litter": 0, "stalk": 1}
        assert d.env.unwrapped.obstacles_hit_ids == frozenset({0})
    finally:
        d.env.close()


def test_a_small_stone_lifts_the_chassis_briefly() -> None:
    """A 3 cm stone under the left wheels: the rigid chassis lifts at that corner — its base
    rises about half the stone's height (a corner raised h on a rigid frame lifts the centre
    h/2) and tilts by at least h over the wheel diagonal — then settles back and drives on."""
    h = 0.03
    stone = _obstacles(
        dict(kind="stone", ahead=1.0, left=0.5 * GEO.track, length=0.08, width=0.08, height=h)
    )
    d = _drive(_with(stone), 90)
    try:
        z, tilt = np.array(d.z), np.array(d.tilt)
        z0 = z[:20].mean()
        assert 0.35 * h < z.max() - z0 < 0.75 * h
        diagonal = math.hypot(GEO.wheelbase, GEO.track)
        assert 0.8 * math.atan(h / diagonal) < tilt.max() < 1.5 * math.atan(h / GEO.track)
        # back on four wheels after it: level (the plane), at the height it had
        assert tilt[-5:].max() < math.radians(0.3)
        assert abs(z[-5:].mean() - z0) < 0.1 * h
        assert d.ahead[-1] > 1.0 + 0.5 * GEO.wheelbase + 0.5
    finally:
        d.env.close()


@pytest.mark.parametrize(
    "where",
    [
        # across the whole robot: both front wheels meet it first (they reach farther ahead)
        dict(length=0.3, width=0.8, front=0.5 * GEO.wheelbase + R),
        # between the wheels: only the chassis (12 cm above the ground) meets it
        dict(length=0.25, width=0.25, front=0.5 * GEO.chassis[0]),
    ],
    ids=["boulder", "under-chassis"],
)
def test_a_stone_taller_than_the_wheel_stops_the_robot(where: dict[str, float]) -> None:
    """A stone 0.25 m high (over twice the 0.11 m wheel radius: a wheel's contact is above its
    axle, the force pushes back, never up) stops the robot where it meets it; the wheels spin,
    the progress checker ends the episode: obstacles themselves never do."""
    h = 0.25
    size = {k: where[k] for k in ("length", "width")}
    stone = _obstacles(dict(kind="stone", ahead=1.0, height=h, **size))
    config = {"task": {**CONFIG["task"], "progress_time": 3.0}}
    flat_z = _flat_wheel_z()
    d = _drive(_with(stone), 200, config)
    try:
        assert d.info.get("termination") == "progress"
        ahead = np.array(d.ahead)
        near_face = 1.0 - 0.5 * where["length"]
        # what meets it (the wheel spheres' or the chassis' front) never passes the stone's
        # face (by more than the stone's rounding and roughness)
        assert ahead.max() + where["front"] < near_face + 0.05
        # stalled: the last 2 s moved less than a centimetre forward
        assert ahead[-1] - ahead[-41] < 0.01
        # no wheel got on it: none rose by half its radius
        assert np.array(d.wheel_z).max() - flat_z < 0.5 * R
        assert d.info["obstacles_hit"] == 1
    finally:
        d.env.close()


def test_put_down_on_a_stone_it_rests_on_it() -> None:
    """A reset that puts a wheel on a stone (lanes start anywhere) stands it on the stone: the
    robot settles, at rest, tilted by about the stone's height over a wheel spacing, not thrown
    by the penetration recovery."""
    from agrinav_gym.sim.world import World

    h = 0.06
    x0, y0, yaw = _start()
    c, s = math.cos(yaw), math.sin(yaw)
    fx, fy = 0.5 * GEO.wheelbase, 0.5 * GEO.track  # under the front-left wheel
    stone = _obstacles(
        dict(kind="stone", ahead=fx, left=fy, length=0.12, width=0.12, height=h, shape=3)
    )
    env = make(scenario=_with(stone), scenario_overrides=None, config=CONFIG)
    try:
        env.reset(seed=0, options=LANE)
        u = env.unwrapped
        w: World = u.world
        assert (x0, y0) == pytest.approx(u.start[:2])
        lin, ang = p.getBaseVelocity(w.robot, physicsClientId=w.client)
        assert np.linalg.norm(lin) < 1e-3 and np.linalg.norm(ang) < 1e-3
        fl = p.getLinkState(w.robot, w.wheels[0], physicsClientId=w.client)[0][2]
        others = [p.getLinkState(w.robot, j, physicsClientId=w.client)[0][2] for j in w.wheels[1:]]
        ground = float(_flat().terrain.height_at(x0 + fx * c, y0 + fx * s))
        # on the stone's top (not sunk in the soil), within its roughness
        assert fl - ground == pytest.approx(h + R, abs=0.3 * h)
        assert min(others) < fl - 0.5 * h
        tilt = max(abs(float(u.state.rpy[0])), abs(float(u.state.rpy[1])))
        assert math.atan(0.5 * h / GEO.track) < tilt < math.atan(1.5 * h / GEO.wheelbase)
    finally:
        env.close()


# ---------------------------------------------------------------------- bodies and episodes
def test_obstacle_bodies_follow_the_robot_and_the_scenario() -> None:
    """Only obstacles within reach of the robot are bodies, posed as the scenario places them;
    another scenario on the same terrain brings its own obstacles (the world is not rebuilt),
    one without obstacles none."""
    row = _obstacles(
        *(
            dict(kind="litter", ahead=a, length=0.2, width=0.1, height=0.02, turn=0.3, roll=0.05)
            for a in np.arange(1.0, 12.0, 0.5)
        )
    )
    env = make(scenario=_with(row), scenario_overrides=None, config=CONFIG)
    try:
        u = env.unwrapped
        env.reset(seed=0, options=LANE)
        w = u.world
        assert w.obstacles is not None
        bodies = dict(w.obstacles.bodies)
        x0, y0, _ = _start()
        reach = w.obstacles.reach
        for i in range(len(row)):
            gap = math.hypot(row.x[i] - x0, row.y[i] - y0) - w.obstacles._half[i]
            assert (i in bodies) == (gap <= reach + WINDOW_MARGIN)
        assert 0 < len(bodies) < len(row)
        # each body where the scenario puts it, turned as R = Rz·Ry·Rx says
        for i, b in bodies.items():
            pos, quat = p.getBasePositionAndOrientation(b, physicsClientId=w.client)
            assert pos == pytest.approx((row.x[i], row.y[i], row.z[i]), abs=1e-9)
            rot = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
            assert rot == pytest.approx(row.rotation(i), abs=1e-9)
        for _ in range(80):  # 4 s straight over the litter: the window moves along
            env.step(np.array([0.5, 0.0], np.float32))
        moved = set(w.obstacles.bodies)
        assert moved != set(bodies) and len(moved) < len(row)
        terrain_body = w.patch.body
        # the same terrain, other obstacles: swapped without rebuilding the world
        env.reset(seed=0, options={**LANE, "scenario": _flat()})
        assert w.patch.body == terrain_body and w.obstacles is None
        assert p.getNumBodies(physicsClientId=w.client) == 2  # the terrain and the robot
    finally:
        env.close()


def test_an_episode_on_a_stony_field_is_the_same_whatever_came_before() -> None:
    """The obstacle window is made afresh at each reset: the same reset seed gives the same
    trajectory, bit for bit, after another episode elsewhere on the field or at the same
    start."""
    spec = sg.preset("default").replace({**TINY, "obstacles": {"stone_density": 1.0}})
    scn = sg.generate(spec, 1)
    assert len(scn.obstacles) > 50
    config = {"task": {**CONFIG["task"], "corridor": 5.0}}
    env = make(scenario=scn, scenario_overrides=None, config=config)

    def run(seed: int, lane: int, steps: int = 80) -> list[float]:
        env.reset(seed=seed, options={"lane": lane})
        for k in range(steps):
            env.step(np.array([0.8, 0.2 * math.sin(0.1 * k)], np.float32))
        s = env.unwrapped.state
        return [*s.pos.tolist(), *s.rpy.tolist(), *s.wheels]

    try:
        first = run(5, 0)
        hit = env.unwrapped.obstacles_hit_ids
        run(6, 3)
        assert run(5, 0) == first
        # a short episode at the same start leaves its window's bodies there for the next
        run(5, 0, steps=1)
        assert run(5, 0) == first
        assert env.unwrapped.obstacles_hit_ids == hit and hit  # it drove over stones
    finally:
        env.close()


# ---------------------------------------------------------------------- the metric
def _robot_polygons(x: float, y: float, yaw: float) -> list[shapely.Polygon]:
    c, s = math.cos(yaw), math.sin(yaw)
    out = []
    for cx, cy, hx, hy in GEO.contact_rects:
        pts = [(cx + a * hx, cy + b * hy) for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
        out.append(shapely.Polygon([(x + c * u - s * v, y + s * u + c * v) for u, v in pts]))
    return out


def test_obstacle_contact_is_the_exact_rectangle_overlap() -> None:
    """The separating-axis test against shapely's polygon intersection, at 3,000 random robot
    poses over random obstacles (near misses included: the poses are drawn close)."""
    rng = np.random.default_rng(11)
    n = 60
    obs = Obstacles(
        rng.choice(["stone", "litter", "stalk"], n).astype("<U6"),
        rng.uniform(0, 6, n),
        rng.uniform(0, 6, n),
        np.zeros(n),
        np.zeros(n),
        np.zeros(n),
        rng.uniform(-math.pi, math.pi, n),
        rng.uniform(0.02, 1.5, n),
        rng.uniform(0.01, 0.3, n),
        rng.uniform(0.01, 0.2, n),
        np.zeros(n, np.int64),
    )
    contact = ObstacleContact.from_scenario(dataclasses.replace(_flat(), obstacles=obs), GEO)
    feet = [shapely.Polygon(f) for f in obs.footprints()]
    touched = 0
    for _ in range(3000):
        x, y, yaw = rng.uniform(0, 6), rng.uniform(0, 6), rng.uniform(-math.pi, math.pi)
        robot = shapely.union_all(_robot_polygons(x, y, yaw))
        want = [i for i in range(n) if feet[i].intersects(robot)]
        assert contact.touching(x, y, yaw) == want
        touched += bool(want)
    assert touched > 300  # the poses do meet obstacles


def test_rects_overlap_counts_touching_and_separates_a_gap() -> None:
    # two unit squares side by side: touching overlaps, a micrometre apart does not
    assert rects_overlap(1.0, 0.0, 0.5, 0.5, 1.0, 0.0, 0.5, 0.5)
    assert not rects_overlap(1.0 + 1e-6, 0.0, 0.5, 0.5, 1.0, 0.0, 0.5, 0.5)
    # a diamond (square at 45°) whose corner reaches past the other's edge is found only by
    # the axes of both: its bounding circle overlaps, its edge normals separate
    d = math.sqrt(0.5)
    assert not rects_overlap(1.2, 1.2, 0.5, 0.5, d, d, 0.5, 0.5)
    assert rects_overlap(0.5 + d - 0.01, 0.0, 0.5, 0.5, d, d, 0.5, 0.5)


def test_metrics_count_each_obstacle_once_per_kind() -> None:
    from agrinav_gym.metrics import EpisodeMetrics

    m = EpisodeMetrics(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([True, True]))
    m.update(0.5, 0.1, 0.5)
    r = m.result(2, ["stone", "stalk", "stone"])
    assert r["crops_hit"] == 2 and r["obstacles_hit"] == 3
    assert r["obstacles_hit_by_kind"] == {"stone": 2, "litter": 0, "stalk": 1}
    assert m.result(0)["obstacles_hit_by_kind"] == {"stone": 0, "litter": 0, "stalk": 0}
    with pytest.raises(KeyError):
        m.result(0, ["boulder"])


# ---------------------------------------------------------------------- randomized fields
def test_randomize_draws_fields_with_and_without_stones() -> None:
    """``obstacles.*`` are scenario keys like any spec field: drawn per reset."""
    env = gym.make(
        "AgriNav/FurrowFollow-v3",
        scenario_overrides=TINY,
        randomize={"obstacles.stone_density": {"choices": [0.0, 0.5]}},
    )
    ranged = gym.make(
        "AgriNav/FurrowFollow-v3",
        scenario_overrides=TINY,
        randomize={"obstacles.stone_density": [0.0, 0.5], "obstacles.stalk_lodging": [0.0, 0.1]},
    )
    try:
        counts = []
        for seed in range(6):
            env.reset(seed=seed)
            scn = env.unwrapped.scenario
            density = scn.spec.obstacles.stone_density
            counts.append((density, scn.obstacles.counts()["stone"]))
            world = env.unwrapped.world
            assert (world.obstacles is None) == (len(scn.obstacles) == 0)
        assert {d for d, _ in counts} == {0.0, 0.5}
        assert all((n == 0) == (d == 0.0) for d, n in counts)
        drawn = set()
        for seed in range(4):
            ranged.reset(seed=seed)
            scn = ranged.unwrapped.scenario
            drawn.add((scn.spec.obstacles.stone_density, len(scn.obstacles)))
        assert len(drawn) == 4 and all(0.0 <= d <= 0.5 for d, _ in drawn)
    finally:
        env.close()
        ranged.close()


def test_a_world_full_of_shapes_rebuilds_itself(monkeypatch: pytest.MonkeyPatch) -> None:
    """pybullet cannot free a collision shape a body used: past ``SHAPE_LIMIT`` the world resets
    the simulation at the next reset (same terrain) and starts its shapes afresh."""
    import agrinav_gym.sim.world as world_mod

    row = _obstacles(
        *(
            dict(kind="stone", ahead=a, length=0.1, width=0.08, height=0.04, shape=seed)
            for seed, a in enumerate((1.0, 1.3, 1.6))
        ),
        # the same stone again: its shape is shared, not made twice
        dict(kind="stone", ahead=1.3, left=-0.235, length=0.1, width=0.08, height=0.04, shape=0),
    )
    # counted from here: placing the row may build an env of its own (``_start``, cached), whose
    # resets are not this world's
    resets = []
    real = p.resetSimulation
    monkeypatch.setattr(p, "resetSimulation", lambda **kw: (resets.append(1), real(**kw))[1])
    monkeypatch.setattr(world_mod, "SHAPE_LIMIT", 3)
    env = make(scenario=_with(row), scenario_overrides=None, config=CONFIG)
    try:
        env.reset(seed=0, options=LANE)
        w = env.unwrapped.world
        assert len(resets) == 1 and len(w._shapes) == 3  # the first build; three shapes made
        env.reset(seed=0, options=LANE)
        assert len(resets) == 2 and len(w._shapes) == 3  # rebuilt, the window made again
        assert w.obstacles is not None and sorted(w.obstacles.bodies) == [0, 1, 2, 3]
        for _ in range(80):  # and it drives over them as before
            env.step(np.array([0.5, 0.0], np.float32))
        assert env.unwrapped.obstacles_hit_ids == frozenset({0, 1, 2, 3})
    finally:
        env.close()
