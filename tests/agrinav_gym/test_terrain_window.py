"""The physics ground's window (``sim.world.TerrainPatch``): it always holds the ground the
chassis can reach, it is the terrain where it lies, and it moves as seldom as its size says."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from agrinav_gym.sim.world import TerrainPatch
from scenario_gen import Terrain

REACH = 0.57  # the Summit-XL's reach from base_link (World._reach)
STEP = 0.1  # the most a control step moves the robot (2 m/s at 20 Hz)


@pytest.fixture()
def client():
    cid = p.connect(p.DIRECT)
    yield cid
    p.disconnect(cid)


def _terrain(spacing: float, size: float = 120.0, seed: int = 0) -> Terrain:
    n = int(size / spacing) + 1
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:n, 0:n] * spacing
    h = 0.5 * np.sin(xx / 7.0) + 0.3 * np.cos(yy / 5.0) + rng.normal(0, 0.01, (n, n))
    return Terrain(h, x0=-10.0, y0=25.0, spacing=spacing)


def _extent(w: TerrainPatch) -> tuple[float, float, float, float]:
    t, s = w.terrain, w.terrain.spacing
    x0, y0 = t.x0 + w.j0 * s, t.y0 + w.i0 * s
    return x0, x0 + (w.nx - 1) * s, y0, y0 + (w.ny - 1) * s


def _drive(w: TerrainPatch, start, heading_of, n: int):
    """Follow a path of n control steps; yield (x, y, moved) after each."""
    x, y = start
    for k in range(n):
        h = heading_of(k)
        x, y = x + STEP * math.cos(h), y + STEP * math.sin(h)
        yield x, y, w.follow(x, y, heading=h)


@pytest.mark.parametrize("row_angle", [None, 0.0, math.pi / 2, 0.6])
@pytest.mark.parametrize("spacing", [0.12, 0.5, 2.0])
def test_window_holds_the_chassis_reach_and_keeps_the_pins_beyond_it(client, row_angle, spacing):
    t = _terrain(spacing)
    w = TerrainPatch(client, t, 0.8, row_angle, REACH)
    cx, cy = t.x0 + 60.0, t.y0 + 60.0

    # lanes along the rows with U-turns, then a wander: whatever the path, after every follow
    # the ground within the reach (and a step more) is in the window, the pinned corners not
    def heading(k: int) -> float:
        base = row_angle or 0.0
        if k < 1200:
            lane, at = divmod(k, 300)
            return base + (math.pi if lane % 2 else 0.0) + (math.pi / 2 if at >= 290 else 0.0)
        return base + 0.01 * k + math.sin(0.05 * k)

    for x, y, _ in _drive(w, (cx - 15.0, cy), heading, 2400):
        x0, x1, y0, y1 = _extent(w)
        r = REACH + STEP
        assert x0 <= x - r and x + r <= x1 and y0 <= y - r and y + r <= y1
        for px, py in ((x0, y0), (x1, y1)):
            assert math.hypot(px - x, py - y) > w.margin


@pytest.mark.parametrize("row_angle", [None, 0.0, 0.6])
def test_window_is_the_terrain_where_it_lies(client, row_angle):
    """Rays down onto the heightfield body at grid nodes hit the terrain's own heights."""
    t = _terrain(0.12)
    w = TerrainPatch(client, t, 0.8, row_angle, REACH)
    rng = np.random.default_rng(1)
    checked = 0
    for *_, moved in _drive(w, (t.x0 + 40.0, t.y0 + 40.0), lambda k: 0.3 + 0.002 * k, 600):
        if not moved:
            continue
        checked += 1
        # nodes inside the window, away from its pinned corners
        i = w.i0 + rng.integers(2, w.ny - 2, 20)
        j = w.j0 + rng.integers(2, w.nx - 2, 20)
        px, py = t.x0 + j * t.spacing, t.y0 + i * t.spacing
        hits = p.rayTestBatch(
            [[a, b, 100.0] for a, b in zip(px, py, strict=True)],
            [[a, b, -100.0] for a, b in zip(px, py, strict=True)],
            physicsClientId=client,
        )
        z = np.array([h[3][2] for h in hits])
        assert all(h[0] == w.body for h in hits)
        # pybullet stores heightfield samples as float32
        np.testing.assert_allclose(z, t.heights[i, j], atol=1e-5)
    assert checked >= 2  # the drive crossed windows: the checks above ran on moved ones


@pytest.mark.parametrize(("row_angle", "heading"), [(0.0, 0.0), (None, 0.6), (0.6, 0.6)])
def test_window_moves_as_seldom_as_its_size_allows(client, row_angle, heading):
    """Driving straight, a refill comes every L - 2·margin - 1 metres of the heading's reach
    across the window (its travel before the robot nears the leading edge again)."""
    t = _terrain(0.12)
    w = TerrainPatch(client, t, 0.8, row_angle, REACH)
    s = t.spacing
    hx, hy = 0.5 * (w.nx - 1) * s, 0.5 * (w.ny - 1) * s
    c, sn = abs(math.cos(heading)), abs(math.sin(heading))
    along = min((hx - w.margin) / max(c, 1e-9), (hy - w.margin) / max(sn, 1e-9))
    back = w.margin + 1.0 + s
    ahead = max(0.0, min((hx - back) / max(c, 1e-9), (hy - back) / max(sn, 1e-9)))
    travel = along + ahead  # from margin + 1 m behind the trailing edge to margin before the lead
    n = 900  # 90 m
    moves = sum(m for *_, m in _drive(w, (t.x0 + 10.0, t.y0 + 10.0), lambda k: heading, n))
    # whole-cell snapping costs at most a cell of travel a move
    assert moves <= math.ceil(n * STEP / (travel - 2 * s)) + 1
    assert moves >= math.floor(n * STEP / (travel + 2 * s)) - 1
