"""Obstacles (stones, litter, fallen stalks) in both cameras, the chase view and the labels.

A stone is put on a plane field with no plants, in front of the robot; what each camera reads
at the pixel looking at it is checked against the geometry: the mesh camera against the ray's
own intersection with the stone's triangles, the proxy camera against its stand-in cylinder,
and both against the stone's footprint (what a vertical cylinder around it can and cannot
reach). Fields whose obstacles are out of view render bit for bit as without them.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
import shapely

from agrinav_gym.chase_view import ChaseView
from agrinav_gym.config import EnvConfig, RenderConfig
from agrinav_gym.render import native, shading
from agrinav_gym.render.classes import CLASS_NAMES, OBSTACLE, SemanticClass
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.render.obstacle_meshes import LITTER_RGB, obstacle_colour
from agrinav_gym.render.proxy_plants import PlantField, obstacle_cylinders
from agrinav_gym.robot import RobotGeometry, RobotState, robot_interface
from agrinav_gym.sensors.camera import FieldView
from agrinav_gym.sensors.depth import PROXY_RGB, DepthCamera
from agrinav_gym.sensors.mesh_camera import RGB_FAR, MeshCamera
from scenario_gen import Scenario, generate
from scenario_gen.model import Plants
from scenario_gen.obstacles import LITTER, STALK, STONE, Obstacles

from ..scenario_gen.helpers import plane
from .helpers import lane_pose, mesh_camera

needs_kernels = pytest.mark.skipif(not native.available(), reason="compiled kernels not built")
W, H = 128, 96
#: Embree intersects in float32 (~1 µm around the field's centre): how far its depth may be
#: from the exact intersection, with margin (test_native: 2·10⁻⁵ m measured)
EMBREE_DEPTH = 1e-4


def obstacles(
    rows: list[tuple[str, float, float, float, tuple[float, float, float]]], scn: Scenario
) -> Obstacles:
    """Obstacles (kind, x, y, yaw, (length, width, height)) flat on ``scn``'s plane terrain."""
    n = len(rows)
    x = np.array([r[1] for r in rows])
    y = np.array([r[2] for r in rows])
    zero = np.zeros(n)
    return Obstacles(
        kind=np.array([r[0] for r in rows], "<U6"),
        x=x,
        y=y,
        z=np.asarray(scn.terrain.height_at(x, y), float).reshape(n),
        roll=zero,
        pitch=zero,
        yaw=np.array([r[3] for r in rows]),
        length=np.array([r[4][0] for r in rows]),
        width=np.array([r[4][1] for r in rows]),
        height=np.array([r[4][2] for r in rows]),
        shape=np.arange(7, 7 + n, dtype=np.int64),
    )


def no_plants(p: Plants) -> Plants:
    return Plants(**{k: v[:0] for k, v in p.arrays().items()})


@pytest.fixture(scope="module")
def bare() -> Scenario:
    """A plane field without plants (the stone alone in view)."""
    scn = generate(plane(), 0)
    return dataclasses.replace(scn, plants=no_plants(scn.plants))


def ahead(scn: Scenario, dist: float, k: int = 40) -> tuple[Any, Any, Any]:
    """The lane pose at route point ``k`` and the point ``dist`` m ahead of base_link."""
    rot, pos = lane_pose(scn, k)
    return rot, pos, pos[:2] + dist * rot[:2, 0]


def cameras(renderer: str = "auto") -> tuple[DepthCamera, MeshCamera]:
    cfg = EnvConfig.from_dict({"camera": {"width": W, "height": H, "renderer": renderer}})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    return DepthCamera(cfg.camera, model), MeshCamera(cfg.camera, model)


def pixel_of(cam: MeshCamera, rot: Any, pos: Any, p: Any) -> tuple[int, int]:
    """The pixel (row, column) whose centre is nearest the image of world point ``p``."""
    m = cam.model
    o = pos + rot @ np.asarray(m.position)
    q = (rot @ m.rotation).T @ (p - o)  # camera body: x forward, y left, z up
    u, v = m.cx - m.fx * q[1] / q[0], m.cy - m.fy * q[2] / q[0]
    return round(v), round(u)


def ray_mesh(o: Any, d: Any, v: Any, f: Any) -> float:
    """Nearest intersection (Möller–Trumbore, float64) of the ray o + t·d with a mesh."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2 = b - a, c - a
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        w = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    ok = (np.abs(det) > 1e-15) & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 0)
    return float(t[ok].min()) if ok.any() else math.inf


def ray_cylinder(o: Any, d: Any, c: Any, r: float, z0: float, z1: float) -> float:
    """Nearest intersection of the ray with a vertical capped cylinder (wall or top cap), the
    ray's origin outside it."""
    ox, oy = o[0] - c[0], o[1] - c[1]
    a = d[0] ** 2 + d[1] ** 2
    b = ox * d[0] + oy * d[1]
    disc = b * b - a * (ox * ox + oy * oy - r * r)
    best = math.inf
    if disc >= 0 and a > 0:
        t = (-b - math.sqrt(disc)) / a
        if t > 0 and z0 <= o[2] + t * d[2] <= z1:
            best = t
    if d[2] < 0:
        t = (z1 - o[2]) / d[2]
        px, py = ox + t * d[0], oy + t * d[1]
        if t > 0 and px * px + py * py <= r * r:
            best = min(best, t)
    return best


def ray_disc(o: Any, d: Any, c: Any, r: float) -> float:
    """The ray length at which its ground track enters a disc of radius ``r`` about ``c``
    (``r`` = 0: where it passes nearest ``c``)."""
    ox, oy = o[0] - c[0], o[1] - c[1]
    a = d[0] ** 2 + d[1] ** 2
    b = ox * d[0] + oy * d[1]
    if r == 0:
        return -b / a
    return (-b - math.sqrt(b * b - a * (ox * ox + oy * oy - r * r))) / a


# ---------------------------------------------------------------------- the class
def test_obstacle_is_appended_to_the_classes() -> None:
    # stored values never change meaning: the five earlier classes keep theirs
    assert [int(c) for c in SemanticClass] == list(range(6))
    assert OBSTACLE == 5 and CLASS_NAMES[OBSTACLE] == "obstacle"
    assert len(PROXY_RGB) == len(SemanticClass)  # the proxy's colours cover every class


# ---------------------------------------------------------------------- a stone in view
STONE_SIZE = (0.24, 0.16, 0.12)


@pytest.fixture(scope="module")
def stone_scene(bare: Scenario) -> tuple[Scenario, Any, Any]:
    rot, pos, xy = ahead(bare, 1.9)
    scn = dataclasses.replace(bare, obstacles=obstacles([(STONE, *xy, 0.4, STONE_SIZE)], bare))
    return scn, rot, pos


def _stone_pixel(scn: Scenario, cam: MeshCamera, rot: Any, pos: Any) -> tuple[int, int, Any, Any]:
    """The pixel aimed at the stone's axis at half its height, its ray's origin and direction."""
    o = scn.obstacles
    p = np.array([o.x[0], o.y[0], o.z[0] + 0.5 * o.height[0]])
    row, col = pixel_of(cam, rot, pos, p)
    assert 0 <= row < H and 0 <= col < W
    origin, d = cam.rays.world(rot, pos)
    return row, col, origin, np.asarray(d[row * W + col], np.float64)


def _footprint_bounds(scn: Scenario, origin: Any, d: Any) -> tuple[float, float]:
    """Ray lengths between which the stone's near face must lie: where the ray enters the disc
    of its farthest footprint point (the stone is within it) and where it passes nearest the
    stone's axis (there it is within half a pixel, ≈ 1.3 cm, of the axis at about half the
    stone's height: inside a stone 16 cm wide)."""
    o = scn.obstacles
    v, _ = o.mesh(0)
    c = np.array([o.x[0], o.y[0]])
    r_out = float(np.hypot(v[:, 0] - c[0], v[:, 1] - c[1]).max())
    t_in = ray_disc(origin, d, c, r_out)
    t_axis = ray_disc(origin, d, c, 0.0)
    return t_in, t_axis


def test_the_mesh_camera_sees_a_stone_at_its_near_face(
    stone_scene: tuple[Scenario, Any, Any], renderer: str
) -> None:
    scn, rot, pos = stone_scene
    _, cam = cameras(renderer)
    f = cam.render(rot, pos, FieldView(scn), None, labels=True)
    row, col, origin, d = _stone_pixel(scn, cam, rot, pos)
    t = ray_mesh(origin, d, *scn.obstacles.mesh(0))
    fwd = cam.rays.forward[row * W + col]
    assert float(f.depth[row, col]) == pytest.approx(t * fwd, abs=EMBREE_DEPTH)
    t_in, t_axis = _footprint_bounds(scn, origin, d)
    assert t_in <= t <= t_axis
    assert f.label[row, col] == OBSTACLE and f.instance[row, col] == 0
    # every obstacle pixel names the stone, and the stone is more than a pixel or two
    on = f.label == OBSTACLE
    assert on.sum() > 30 and (f.instance[on] == 0).all()
    assert (f.instance[~on] == -1).all()  # no plants: nothing else has an instance


def test_the_proxy_camera_sees_a_stone_at_its_stand_in(
    stone_scene: tuple[Scenario, Any, Any], kernels: str
) -> None:
    scn, rot, pos = stone_scene
    proxy, mesh = cameras()
    f = proxy.render(rot, pos, FieldView(scn), None, labels=True)
    row, col, origin, d = _stone_pixel(scn, mesh, rot, pos)
    xy, z0, z1, r, owner = obstacle_cylinders(scn.obstacles)
    assert len(r) == 1 and owner[0] == 0
    t = ray_cylinder(origin, d, xy[0], float(r[0]), float(z0[0]), float(z1[0]))
    fwd = mesh.rays.forward[row * W + col]
    tol = 1e-6 if kernels == "compiled" else EMBREE_DEPTH  # exact double cast / Embree
    assert float(f.depth[row, col]) == pytest.approx(t * fwd, abs=tol)
    t_in, t_axis = _footprint_bounds(scn, origin, d)
    assert t_in <= t <= t_axis  # the stand-in's wall lies within the stone's footprint
    assert f.label[row, col] == OBSTACLE
    assert (f.label == OBSTACLE).sum() > 30


def test_stand_ins_follow_each_obstacles_footprint_and_length(bare: Scenario) -> None:
    """A stone's and litter's cylinder has its footprint's area; a stalk's chain spans its
    length at a spacing no more than its diameter, each link its radius."""
    _, _, xy = ahead(bare, 2.0)
    obs = obstacles(
        [
            (STONE, xy[0], xy[1], 0.3, STONE_SIZE),
            (LITTER, xy[0] + 1, xy[1], 1.1, (0.3, 0.2, 0.05)),
            (STALK, xy[0], xy[1] + 1, 0.7, (1.3, 0.024, 0.024)),
        ],
        bare,
    )
    c, z0, z1, r, owner = obstacle_cylinders(obs)

    for i in (0, 1):
        v, _ = obs.mesh(i)
        k = np.flatnonzero(owner == i)
        assert len(k) == 1
        area = shapely.MultiPoint(v[:, :2]).convex_hull.area
        assert math.pi * r[k[0]] ** 2 == pytest.approx(area, rel=1e-9)
        assert z0[k[0]] == pytest.approx(v[:, 2].min()) and z1[k[0]] == pytest.approx(v[:, 2].max())
    assert r[1] ** 2 == pytest.approx(0.3 * 0.2 / math.pi)  # a box's footprint: its rectangle
    k = np.flatnonzero(owner == 2)
    links = c[k]
    step = np.hypot(*np.diff(links, axis=0).T)
    assert (step <= 0.024 + 1e-12).all() and (r[k] == 0.012).all()
    assert np.hypot(*(links[-1] - links[0])) == pytest.approx(1.3)
    assert (z1[k] - z0[k]) == pytest.approx(np.full(len(k), 0.024))
    scn = dataclasses.replace(bare, obstacles=obs)
    field = PlantField.from_scenario(scn)
    assert (field.obstacle[field.is_obstacle] == owner).all()
    assert field.is_obstacle.sum() == len(owner) and field.n_plants == 0


# ---------------------------------------------------------------------- no obstacles in view
@pytest.fixture(scope="module")
def maize_with_and_without() -> tuple[Scenario, Scenario]:
    """A field with crops, and the same field with a stone, litter and a stalk behind the
    robot (out of every camera's view)."""
    scn = generate(plane(crop={"stage": 4}), 0)
    rot, _, xy = ahead(scn, -1.6)
    side = rot[:2, 1]
    rows = [
        (STONE, *xy, 0.2, STONE_SIZE),
        (LITTER, *(xy + 0.5 * side), 0.9, (0.2, 0.1, 0.03)),
        (STALK, *(xy - 0.3 * rot[:2, 0]), 1.6, (1.0, 0.02, 0.02)),
    ]
    return scn, dataclasses.replace(scn, obstacles=obstacles(rows, scn))


def test_obstacles_out_of_view_change_no_pixel(
    maize_with_and_without: tuple[Scenario, Scenario], renderer: str, kernels: str
) -> None:
    """Both cameras' frames (noisy depth, labels, instances, colour) are bit for bit those of
    the field without obstacles, and those of its copy with ``Obstacles.empty()``."""
    scn, with_obs = maize_with_and_without
    empty = dataclasses.replace(with_obs, obstacles=Obstacles.empty())
    rot, pos = lane_pose(scn, 40)
    if renderer == "raster" and kernels == "reference":
        pytest.skip("the rasteriser is the kernels")
    proxy, mesh = cameras(renderer)
    for cam in (proxy, mesh):
        frames = [
            cam.render(rot, pos, FieldView(s), np.random.default_rng(3), rgb=True, labels=True)
            for s in (scn, with_obs, empty)
        ]
        for f in frames[1:]:
            for name in ("depth", "label", "rgb", "instance", "rgb_label", "rgb_instance"):
                a, b = getattr(frames[0], name), getattr(f, name)
                assert (a is None and b is None) or np.array_equal(a, b), name
        assert (frames[0].label != OBSTACLE).all()


# ---------------------------------------------------------------------- colour and chase view
def test_litter_is_drawn_in_its_plastic_colour(bare: Scenario, renderer: str) -> None:
    """Each pixel is the item's palette colour lit (ambient to full sun) and hazed by its
    distance (shading.lambert, shading.haze): within those bounds, and nearer in hue to its own
    palette colour than to any other."""
    rot, pos, xy = ahead(bare, 1.8)
    scn = dataclasses.replace(
        bare, obstacles=obstacles([(LITTER, *xy, 0.5, (0.3, 0.25, 0.06))], bare)
    )
    _, cam = cameras(renderer)
    f = cam.render(rot, pos, FieldView(scn), None, rgb=True, labels=True)
    on = f.rgb_label == OBSTACLE
    assert on.sum() > 30 and (f.rgb_instance[on] == 0).all()
    albedo = obstacle_colour(scn.obstacles, 0, 1)[0] / 255.0
    k = int(np.argmin(np.abs(LITTER_RGB - albedo).sum(axis=1)))
    assert np.allclose(albedo, LITTER_RGB[k], atol=0.5 / 255)
    # haze: the blend towards the horizon over the item's range of distances
    v, _ = scn.obstacles.mesh(0)
    dist = np.linalg.norm(v - (pos + rot @ np.asarray(cam.color.position)), axis=1)
    far = RGB_FAR * cam.cfg.max_range
    a_lo, a_hi = dist.min() / (3 * far), dist.max() / (3 * far)
    rgb = f.rgb[on].astype(float) / 255.0
    lo = albedo * shading.AMBIENT * (1 - a_hi) + shading.SKY_HORIZON * a_lo
    hi = albedo * (1 - a_lo) + shading.SKY_HORIZON * a_hi
    assert (rgb >= lo - 1 / 255).all() and (rgb <= hi + 1 / 255).all()
    hue = rgb.mean(axis=0) / rgb.mean(axis=0).sum()
    palette = LITTER_RGB / LITTER_RGB.sum(axis=1, keepdims=True)
    assert int(np.argmin(np.abs(palette - hue).sum(axis=1))) == k


def test_the_chase_view_draws_an_obstacle_where_it_projects(bare: Scenario, kernels: str) -> None:
    """Against the same field without it, only pixels inside the obstacle's projected box
    change (Lambert shading casts no shadows), in the chase view and the camera inset."""
    rot, pos, xy = ahead(bare, 1.5)
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    scn = dataclasses.replace(
        bare, obstacles=obstacles([(LITTER, *xy, 0.5, (0.35, 0.25, 0.1))], bare)
    )
    cfg = EnvConfig.from_dict({"render": {"width": 320, "height": 240}})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    s = RobotState(pos, rot, np.array([0.0, 0.0, yaw]), np.zeros(3), np.zeros(3), [])
    frames = []
    for field in (bare, scn):
        view = ChaseView(RenderConfig(320, 240), model, cfg.camera)
        frames.append(view.render(MeshScene.from_scenario(field), s).astype(int))
    changed = np.abs(frames[1] - frames[0]).max(axis=2) > 0
    rows, cols = np.nonzero(changed)
    assert changed.sum() > 50
    # the chase camera follows the heading: project the item's corners into it
    m = view.chase.model
    o = pos + rot @ np.asarray(m.position)
    v, _ = scn.obstacles.mesh(0)
    q = (v - o) @ (rot @ m.rotation)
    u = m.cx - m.fx * q[:, 1] / q[:, 0]
    w = m.cy - m.fy * q[:, 2] / q[:, 0]
    ih, iw = view.inset.model.height, view.inset.model.width
    main = ~((rows < ih + 2) & (cols >= 320 - iw - 2))  # the inset and its white rule apart
    assert main.sum() > 20
    # pixel centres whose rays meet the item lie within its vertices' projected box
    assert u.min() - 0.5 <= cols[main].min() and cols[main].max() <= u.max() + 0.5
    assert w.min() - 0.5 <= rows[main].min() and rows[main].max() <= w.max() + 0.5
    assert (~main).sum() > 0  # and the robot's camera, in the inset, sees it too


# ---------------------------------------------------------------------- the two renderers
@pytest.fixture(scope="module")
def cluttered() -> Scenario:
    """Young maize with stones, litter and lodged stalks everywhere (generated)."""
    over = {
        "crop": {"stage": 2},
        "obstacles": {"stone_density": 3.0, "litter_density": 0.5, "stalk_lodging": 0.15},
    }
    return generate(plane(**over), 0)


@needs_kernels
def test_the_rasteriser_draws_obstacles_as_the_rays_see_them(cluttered: Scenario) -> None:
    """As test_native holds the renderers to each other on plants: where both see the same
    surface the same depth to Embree's precision, the same class and instance but at ties,
    the same colours but rounding."""
    rot, pos = lane_pose(cluttered, 30)
    scene = MeshScene.from_scenario(cluttered)
    frames = {}
    for r in ("raster", "raycast"):
        cam = mesh_camera(848, 480, r)
        frames[r] = cam.draw(rot, pos, scene, None, rgb=True, labels=True, stereo=False)
    r, e = frames["raster"], frames["raycast"]
    n = r.depth.size
    on = r.label == OBSTACLE
    assert on.sum() > 2000 and len(np.unique(r.instance[on])) >= 5  # many obstacles in view
    ties = (r.instance != e.instance) | (r.label != e.label)
    assert ties.sum() <= 1e-4 * n and ((r.depth > 0) != (e.depth > 0)).sum() <= 1e-4 * n
    same = (r.depth > 0) & (e.depth > 0) & ~ties & on
    assert np.abs(r.depth[same] - e.depth[same]).max() < EMBREE_DEPTH
    colour_ties = (r.rgb_instance != e.rgb_instance) | (r.rgb_label != e.rgb_label)
    assert colour_ties.sum() <= 1e-4 * n
    diff = np.abs(r.rgb.astype(int) - e.rgb.astype(int)).max(axis=2)[~colour_ties]
    assert (diff > 2).mean() < 1e-4
