"""Plant geometry for the sensors: prototypes, placements, tiles, Embree."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from agrinav_gym.render.embree import Caster, Scene, device
from agrinav_gym.render.mesh_scene import MeshScene, convex_hull, refine_ground
from agrinav_gym.render.plant_meshes import (
    PlantMeshes,
    growth_node,
    node_growth,
    rotation_rpy,
)
from scenario_gen import CATALOG, Terrain, generate, preset

from .helpers import TINY


def test_rotation_is_urdf_rpy() -> None:
    rng = np.random.default_rng(0)
    rpy = rng.uniform(-math.pi, math.pi, (20, 3))
    ours = rotation_rpy(rpy[:, 0], rpy[:, 1], rpy[:, 2])
    ref = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()  # R = Rz(yaw)·Ry(pitch)·Rx(roll)
    assert np.allclose(ours, ref, atol=1e-12)


def test_every_catalog_stage_is_a_growth_node() -> None:
    for name, sp in CATALOG.items():
        n = sp.mesh_intervals
        growth = sp.growth_of_stage(np.arange(1, sp.stages + 1))
        nodes = growth_node(name, growth)
        assert np.allclose([node_growth(name, int(k)) for k in nodes], growth), name
        assert n % (sp.stages - 1) == 0


def test_plants_share_prototypes_and_cost_bytes_per_plant() -> None:
    scn = generate(
        preset("default", **{**TINY, "layout": {"headland": 2.0, "weed_density": 2.0}}), 0
    )
    pm = PlantMeshes.from_scenario(scn)
    crops = ~scn.plants.is_weed
    # all crops share one growth: one prototype; weeds (random growth) at most 7 nodes
    assert len(np.unique(pm.proto[crops])) == 1
    assert len(pm.prototypes) <= 1 + CATALOG["weed"].mesh_intervals + 1
    assert pm.per_plant_bytes() == 6
    # a plant's transform puts its prototype where the scenario says, at its height
    i = int(np.flatnonzero(crops)[3])
    v = pm.world_vertices(i)
    assert v[:, 2].max() - scn.plants.z[i] == pytest.approx(scn.plants.height[i], rel=0.05)
    xfm = pm.transforms(np.array([i]), np.array([1.0, 2.0, 3.0]))[0]
    pr = pm.prototypes[int(pm.proto[i])]
    moved = pr.vertices @ xfm[:, :3].T + xfm[:, 3] + np.array([1.0, 2.0, 3.0])
    assert np.allclose(moved, v, atol=1e-4)


def test_embree_instances_name_their_plant_and_match_a_flat_mesh() -> None:
    """Instanced plants hit where the same geometry copied into one mesh is hit."""
    scn = generate(preset("default", **TINY), 0)
    pm = PlantMeshes.from_scenario(scn)
    dev = device()
    proto = Scene(dev, "high")
    pr = pm.prototypes[0]
    proto.attach_triangles(0, pr.vertices, pr.faces)
    idx = np.arange(40)
    top, flat = Scene(dev), Scene(dev)
    origin = np.array([scn.plants.x.mean(), scn.plants.y.mean(), 0.0])
    xfm = pm.transforms(idx, origin)
    for i in idx:
        top.attach_instance(int(i), proto, xfm[i])
    verts = np.vstack([pm.world_vertices(int(i)) - origin for i in idx]).astype(np.float32)
    faces = np.vstack([pr.faces + k * len(pr.vertices) for k in range(len(idx))])
    flat.attach_triangles(0, verts, faces)
    rng = np.random.default_rng(1)
    start = [scn.plants.x[0] - origin[0], scn.plants.y[0] - origin[1] - 0.5, 0.7]
    o = np.array(start, np.float32)
    d = rng.normal(size=(2000, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = Caster(dev)
    a, b = c.intersect(top, o, d), c.intersect(flat, o, d)
    hit = np.isfinite(b.t)
    assert hit.sum() > 100
    assert np.array_equal(np.isfinite(a.t), hit)
    assert np.allclose(a.t[hit], b.t[hit], atol=1e-4)
    assert np.array_equal(a.inst[hit], b.prim[hit] // len(pr.faces))  # the plant's index


def test_tiles_cover_the_view_and_cost_does_not_follow_the_field() -> None:
    scn = generate(preset("default", field={"width": 30.0, "length": 40.0}), 0)
    scene = MeshScene.from_scenario(scn)
    x, y = float(scn.plants.x.mean()), float(scn.plants.y.mean())
    scene.view(np.array([[x, y], [x + 6, y - 5], [x + 6, y + 5]]))
    n = scene.attached_tiles
    assert 0 < n < scene.nx * scene.ny / 4
    attached = {i for key in scene._attached for i in scene._cache[key].plants}
    near = np.hypot(scn.plants.x - x - 3, scn.plants.y - y) < 2.0
    assert set(np.flatnonzero(near)) <= attached  # everything in the view is loaded
    far = np.hypot(scn.plants.x - x, scn.plants.y - y) > 16.0
    assert not (set(np.flatnonzero(far)) & attached)
    # a small move keeps the same tiles
    built = scene.tiles_built
    scene.view(np.array([[x + 0.1, y], [x + 6.1, y - 5], [x + 6.1, y + 5]]))
    assert scene.tiles_built == built and scene.attached_tiles == n


def test_terrain_hits_lie_on_the_bilinear_surface() -> None:
    scn = generate(preset("hillside", **TINY), 0)
    t = scn.terrain
    scene = MeshScene(t)
    x0, y0 = float(np.mean(t.xs)), float(np.mean(t.ys))
    o = np.array([x0, y0, float(t.height_at(x0, y0)) + 0.7])
    rng = np.random.default_rng(0)
    az, el = rng.uniform(-math.pi, math.pi, 3000), rng.uniform(-0.6, -0.05, 3000)
    d = np.column_stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
    corners = np.array([[12, 12], [-12, 12], [12, -12], [-12, -12]])
    scene.view(np.vstack([o[:2], o[:2] + corners]))
    hits = scene.cast(o, d, 0.0, 12.0)
    ok = np.isfinite(hits.t)
    assert ok.mean() > 0.5  # the rest leave the terrain or go beyond 12 m
    p = o + d[ok] * hits.t[ok, None]
    assert np.abs(p[:, 2] - t.height_at(p[:, 0], p[:, 1])).max() < 1e-5
    # the first crossing: a dense march along each ray finds none before it
    k = np.flatnonzero(ok)[:200]
    s = np.linspace(0.0, 1.0, 400)[None, :] * hits.t[k, None]
    q = o + d[k, None, :] * s[..., None]
    above = q[..., 2] - t.height_at(q[..., 0], q[..., 1])
    assert (above[:, :-2] > -1e-6).all()


def test_refine_ground_moves_a_point_onto_the_surface() -> None:
    h = np.add.outer(np.linspace(0, 0.3, 20) ** 2, np.sin(np.linspace(0, 3, 20)) * 0.1)
    t = Terrain(h, 0.0, 0.0, 0.5)
    o = np.array([1.0, 1.0, 3.0])
    d = np.array([[0.6, 0.5, -0.62]])
    d /= np.linalg.norm(d)
    s = np.linspace(0, 10, 200001)
    p = o + d[0] * s[:, None]
    first = s[np.argmax(p[:, 2] - t.height_at(p[:, 0], p[:, 1]) <= 0)]
    refined = refine_ground(t, o, d, np.array([first + 0.004]))
    assert refined[0] == pytest.approx(first, abs=1e-4)


def test_convex_hull_is_counter_clockwise_and_tight() -> None:
    pts = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, 1], [0.5, 1.5]], float)
    hull = convex_hull(pts)
    assert len(hull) == 4
    area = 0.5 * np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
    assert area == pytest.approx(4.0)
