"""Stones, litter and fallen stalks: placement, shapes, files."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import trimesh

from scenario_gen import InputError, generate, load, save
from scenario_gen.obstacles import OBSTACLE_KINDS, START_CLEAR, STONE_BURIED

from .helpers import small

SOME = {"obstacles": {"stone_density": 0.4, "litter_density": 0.1, "stalk_lodging": 0.05}}
RIDGED = {"furrows": {"enabled": True}}


@pytest.fixture(scope="module")
def scn():
    return generate(small(**SOME, **RIDGED), seed=3)


def test_every_kind_is_placed_and_counted(scn) -> None:
    counts = scn.obstacles.counts()
    assert set(counts) == set(OBSTACLE_KINDS) and all(counts[k] > 0 for k in OBSTACLE_KINDS)
    area = scn.field.area
    # Poisson counts: within 4 sigma of the densities' means
    for kind, density in (("stone", 0.4), ("litter", 0.1)):
        mean = density * area
        assert abs(counts[kind] - mean) < 4 * np.sqrt(mean) + 2, (kind, counts[kind], mean)


def test_off_by_default_and_other_streams_untouched() -> None:
    plain = generate(small(**RIDGED), seed=3)
    stones = generate(small(obstacles={"stone_density": 0.4}, **RIDGED), seed=3)
    assert len(plain.obstacles) == 0
    # stones draw from their own stream: plants, terrain and route keep their bits
    for a, b in zip(plain.plants.arrays().values(), stones.plants.arrays().values(), strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(plain.terrain.heights, stones.terrain.heights)
    assert np.array_equal(plain.route.xyz, stones.route.xyz)


def test_lodged_plants_leave_their_place_and_lie_from_it() -> None:
    plain = generate(small(**RIDGED), seed=3)
    lodged = generate(small(obstacles={"stalk_lodging": 0.1}, **RIDGED), seed=3)
    o = lodged.obstacles
    stalks = o.kind == "stalk"
    standing = {
        (round(x, 9), round(y, 9)) for x, y in zip(lodged.plants.x, lodged.plants.y, strict=True)
    }
    before = {
        (round(x, 9), round(y, 9)) for x, y in zip(plain.plants.x, plain.plants.y, strict=True)
    }
    gone = before - standing
    assert standing <= before and len(gone) >= stalks.sum() > 0
    # each stalk's base (its centre minus half its length along its yaw) is a plant that fell
    bx = o.x[stalks] - 0.5 * o.length[stalks] * np.cos(o.yaw[stalks])
    by = o.y[stalks] - 0.5 * o.length[stalks] * np.sin(o.yaw[stalks])
    gone_xy = np.array(sorted(gone))
    d = np.hypot(bx[:, None] - gone_xy[None, :, 0], by[:, None] - gone_xy[None, :, 1]).min(axis=1)
    assert d.max() < 1e-6
    # lying from the base: as long as 90 % of the plant, as thick as its stalk
    assert np.all(o.length[stalks] > 0.5 * lodged.plants.height.min())
    assert np.all(o.width[stalks] < 0.05)


def test_nothing_on_a_standing_stalk_or_at_the_start(scn) -> None:
    o = scn.obstacles
    crops = np.column_stack([scn.plants.x, scn.plants.y])[~scn.plants.is_weed]
    loose = o.kind != "stalk"
    half_diag = 0.5 * np.hypot(o.length, o.width)
    d = np.hypot(o.x[loose, None] - crops[None, :, 0], o.y[loose, None] - crops[None, :, 1])
    assert np.all(d.min(axis=1) > half_diag[loose])
    x0, y0 = scn.route.xyz[0, :2]
    assert np.all(np.hypot(o.x[loose] - x0, o.y[loose] - y0) > half_diag[loose] + START_CLEAR)


def test_meshes_are_closed_sized_and_rest_on_the_ground(scn) -> None:
    o = scn.obstacles
    for kind in OBSTACLE_KINDS:
        for i in np.flatnonzero(o.kind == kind)[:6]:
            v, f = o.local_mesh(int(i))
            m = trimesh.Trimesh(v, f, process=False)
            assert m.is_watertight and m.is_winding_consistent and m.volume > 0, kind
            size = v.max(axis=0) - np.array([0, 0, 0]) - v.min(axis=0) * np.array([1, 1, 0])
            assert np.allclose(size[:2], [o.length[i], o.width[i]], rtol=1e-6), kind
            assert v[:, 2].max() == pytest.approx(o.height[i], rel=1e-6), kind
            bottom = v[:, 2].min()
            if kind == "stone":  # partly buried
                full = o.height[i] / (1 - STONE_BURIED)
                assert bottom == pytest.approx(-STONE_BURIED * full, rel=1e-6)
            else:
                assert bottom == pytest.approx(0.0, abs=1e-12)
            # in ENU, the frame's origin is on the ground under the centre (a stalk's may be
            # above it: it rests on the ridges)
            ground = float(scn.terrain.height_at(o.x[i], o.y[i]))
            if kind == "stalk":
                assert o.z[i] >= ground - 1e-9
            else:
                assert o.z[i] == pytest.approx(ground, abs=1e-9)


def test_stalks_lie_on_the_ridges_not_in_them(scn) -> None:
    o = scn.obstacles
    for i in np.flatnonzero(o.kind == "stalk"):
        # the stalk's lowest line (local z = 0 along its axis) in ENU, densely sampled: the
        # ground is never above it, and touches it somewhere (it rests, it does not float)
        t = np.linspace(-0.5, 0.5, 301)[:, None] * o.length[i]
        line = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)]) @ o.rotation(int(i)).T
        line += [o.x[i], o.y[i], o.z[i]]
        gap = line[:, 2] - scn.terrain.height_at(line[:, 0], line[:, 1])
        assert gap.min() > -2e-3, (i, gap.min())  # the 1 cm sampling of a 0.12 m ridge
        assert gap.min() < 2e-3, (i, gap.min())


def test_round_trip_and_geojson(scn, tmp_path) -> None:
    save(scn, tmp_path / "s", preview=False)
    back = load(tmp_path / "s")
    a, b = scn.obstacles, back.obstacles
    assert list(a.kind) == list(b.kind)
    for k in ("x", "y", "z", "length", "width", "height"):
        assert np.allclose(getattr(a, k), getattr(b, k), atol=1e-5), k
    assert np.array_equal(a.shape, b.shape)
    gj = json.loads((tmp_path / "s" / "obstacles.geojson").read_text())
    assert len(gj["features"]) == len(a)
    kinds = [f["properties"]["kind"] for f in gj["features"]]
    assert kinds == list(a.kind)
    assert all(f["geometry"]["type"] == "Polygon" for f in gj["features"])
    meta = json.loads((tmp_path / "s" / "scenario.json").read_text())
    assert meta["counts"]["obstacles"] == a.counts()


def test_no_obstacles_no_layer(tmp_path) -> None:
    save(generate(small(), seed=0), tmp_path / "s", preview=False)
    assert not (tmp_path / "s" / "obstacles.geojson").exists()
    with open(tmp_path / "s" / "obstacles.csv") as f:
        assert len(list(csv.reader(f))) == 1  # the header only


@pytest.mark.parametrize(
    ("column", "value", "says"),
    [("kind", "boulder", "allowed: one of stone, litter, stalk"), ("height", "0", "(0, 30] m"),
     ("yaw", "40", "±2π"), ("shape", "1.5", "integer")],
)  # fmt: skip
def test_bad_obstacle_file_is_refused_by_field(scn, tmp_path, column, value, says) -> None:
    save(scn, tmp_path / "s", preview=False)
    path = tmp_path / "s" / "obstacles.csv"
    rows = list(csv.reader(path.open()))
    rows[3][rows[0].index(column)] = value
    with path.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    with pytest.raises(InputError) as e:
        load(tmp_path / "s")
    msg = str(e.value)
    assert "obstacles.csv: line 4" in msg and column in msg and says in msg


def test_bad_spec_is_refused() -> None:
    with pytest.raises(InputError, match=r"obstacles.stone_size.*low <= high"):
        generate(small(obstacles={"stone_size": [0.3, 0.1]}), seed=0)
    with pytest.raises(InputError, match=r"obstacles.stone_density.*at most 20,000"):
        generate(small(obstacles={"stone_density": 49}, field={"width": 30, "length": 40}), 0)
