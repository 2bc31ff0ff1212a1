"""Crop and obstacle contact: which stalks and obstacles the robot's wheels and chassis touch
(analytic, no bodies; the obstacles' bodies are for the physics, ``sim/obstacle_bodies.py``).

Model: each crop is a vertical stalk, a circle of the catalog's stem diameter at its growth
(scaled with the plant's height), at its position; the robot is its URDF collision footprint
seen from above — the chassis box and the four wheels as rectangles in base_link — ignoring
tilt. A crop is hit when its stalk circle overlaps any rectangle. Leaves brush the robot without
counting (they bend); weeds never count. A KD-tree of the crops finds the dozen candidates.
Obstacles (``ObstacleContact``) are rectangles too: the same footprint against each obstacle's
footprint rectangle, by an exact separating-axis test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from scenario_gen import Scenario
from scenario_gen.crops import scaled_by_height
from scenario_gen.obstacles import Obstacles

from ..robot import RobotGeometry

#: m: how far the robot may move before the crops near it are asked for again
NEAR_MARGIN = 0.25


@dataclass(frozen=True, eq=False)
class CropContact:
    tree: cKDTree  # crops only
    index: NDArray[np.int64]  # plant index of each tree point
    xy: list[list[float]]  # per plant (plain lists: a dozen candidates are faster in Python)
    radius: list[float]  # stalk radius per plant, 0 for weeds
    max_radius: float
    rects: tuple[tuple[float, float, float, float], ...]  # (cx, cy, half_x, half_y) in base_link
    half_width: float  # farthest footprint edge from the centreline, m
    reach: float  # farthest footprint corner from base_link, m
    #: the crops near where the robot last asked the KD-tree: (x, y, [(plant, x, y), ...])
    _near: tuple[float, float, list[tuple[int, float, float]]] | None = field(
        default=None, repr=False
    )

    @classmethod
    def from_scenario(cls, scn: Scenario, robot: RobotGeometry) -> CropContact:
        p = scn.plants
        radius = scaled_by_height(p.species, p.stage, p.height, lambda sp, g: sp.stem_radius(g))
        radius[p.is_weed] = 0.0
        index = np.flatnonzero(~p.is_weed)
        xy = np.column_stack([p.x, p.y])
        tree = cKDTree(xy[index] if len(index) else np.zeros((1, 2)))
        rects = robot.contact_rects
        return cls(
            tree,
            index,
            xy.tolist(),
            radius.tolist(),
            float(radius.max()) if len(radius) else 0.0,
            rects,
            max(abs(cy) + hy for _, cy, _, hy in rects),
            max(math.hypot(abs(cx) + hx, abs(cy) + hy) for cx, cy, hx, hy in rects),
        )

    def touching(self, x: float, y: float, yaw: float) -> list[int]:
        """Plant indices of the crops whose stalk touches the footprint at (x, y, yaw), in
        index order.

        The KD-tree is asked for the crops within ``NEAR_MARGIN`` more than the footprint's
        reach, and the answer is kept while the robot stays within that margin of where it
        was asked (a robot moves centimetres a step); each step tests only those within
        reach."""
        if len(self.index) == 0:
            return []
        reach = self.reach + self.max_radius
        near = self._near
        if near is None or math.hypot(x - near[0], y - near[1]) > NEAR_MARGIN:
            found = self.tree.query_ball_point((x, y), reach + NEAR_MARGIN)
            idx = self.index
            plants = sorted(int(idx[j]) for j in found)
            near = (x, y, [(i, self.xy[i][0], self.xy[i][1]) for i in plants])
            object.__setattr__(self, "_near", near)
        c, s = math.cos(yaw), math.sin(yaw)
        r2 = reach * reach
        hits = []
        for i, px, py in near[2]:
            dx, dy = px - x, py - y
            if dx * dx + dy * dy > r2:
                continue
            bx, by = c * dx + s * dy, -s * dx + c * dy  # stalk in base_link
            r = self.radius[i]
            for cx, cy, hx, hy in self.rects:
                fx = max(abs(bx - cx) - hx, 0.0)
                fy = max(abs(by - cy) - hy, 0.0)
                if fx * fx + fy * fy <= r * r:
                    hits.append(i)
                    break
        return hits


def rects_overlap(
    dx: float,
    dy: float,
    hx: float,
    hy: float,
    ux: float,
    uy: float,
    hl: float,
    hw: float,
) -> bool:
    """Whether two rectangles overlap (touching counts), by the separating-axis theorem.

    The first is axis-aligned, half sizes (``hx``, ``hy``); the second's centre is (``dx``,
    ``dy``) from the first's, its length axis the unit vector (``ux``, ``uy``), half length
    ``hl`` and half width ``hw``. Two convex polygons are disjoint iff some edge normal of one
    of them separates their projections; a rectangle has two edge directions, so four axes
    decide it exactly."""
    vx, vy = -uy, ux  # the second's width axis
    aux, auy, avx, avy = abs(ux), abs(uy), abs(vx), abs(vy)
    if abs(dx) > hx + hl * aux + hw * avx:
        return False
    if abs(dy) > hy + hl * auy + hw * avy:
        return False
    if abs(dx * ux + dy * uy) > hl + hx * aux + hy * auy:
        return False
    return abs(dx * vx + dy * vy) <= hw + hx * avx + hy * avy


#: an obstacle's footprint as the overlap test reads it: centre, unit length axis, half length,
#: half width
Box = tuple[float, float, float, float, float, float]


def footprint_boxes(o: Obstacles) -> list[Box]:
    """Each obstacle's ``Box`` (plain floats: a few candidates are faster in Python)."""
    return list(
        zip(
            np.asarray(o.x, float).tolist(),
            np.asarray(o.y, float).tolist(),
            np.cos(o.yaw).tolist(),
            np.sin(o.yaw).tolist(),
            (0.5 * np.asarray(o.length, float)).tolist(),
            (0.5 * np.asarray(o.width, float)).tolist(),
            strict=True,
        )
    )


@dataclass(frozen=True, eq=False)
class ObstacleContact:
    """Which obstacles (stones, litter, fallen stalks) the robot's footprint touches.

    The same footprint as ``CropContact`` — the chassis box and the four wheels as rectangles
    in base_link, tilt ignored — against each obstacle's footprint rectangle seen from above
    (``Obstacles.footprints``: length × width turned by its yaw). An obstacle is touched when
    the rectangles overlap (exact separating-axis test), whatever its height: a stone that
    passes under the chassis between the wheels was driven over. A KD-tree of the obstacles'
    centres finds the candidates, asked again only after the robot has moved ``NEAR_MARGIN``."""

    tree: cKDTree | None  # None without obstacles: every query is answered at once
    box: list[Box]  # per obstacle
    half_diagonal: list[float]
    max_half_diagonal: float
    rects: tuple[tuple[float, float, float, float], ...]  # (cx, cy, half_x, half_y) in base_link
    reach: float  # farthest footprint corner from base_link, m
    _near: tuple[float, float, list[int]] | None = field(default=None, repr=False)

    @classmethod
    def from_scenario(cls, scn: Scenario, robot: RobotGeometry) -> ObstacleContact:
        o = scn.obstacles
        rects = robot.contact_rects
        reach = max(math.hypot(abs(cx) + hx, abs(cy) + hy) for cx, cy, hx, hy in rects)
        if len(o) == 0:
            return cls(None, [], [], 0.0, rects, reach)
        box = footprint_boxes(o)
        diag = 0.5 * np.hypot(np.asarray(o.length, float), np.asarray(o.width, float))
        tree = cKDTree(np.column_stack([o.x, o.y]))
        return cls(tree, box, diag.tolist(), float(diag.max()), rects, reach)

    def touching(self, x: float, y: float, yaw: float) -> list[int]:
        """Indices (rows of obstacles.csv) of the obstacles whose footprint overlaps the
        robot's at (x, y, yaw), in index order."""
        if self.tree is None:
            return []
        near = self._near
        if near is None or math.hypot(x - near[0], y - near[1]) > NEAR_MARGIN:
            r = self.reach + self.max_half_diagonal + NEAR_MARGIN
            near = (x, y, sorted(int(i) for i in self.tree.query_ball_point((x, y), r)))
            object.__setattr__(self, "_near", near)
        c, s = math.cos(yaw), math.sin(yaw)
        hits = []
        for i in near[2]:
            ox, oy, ux, uy, hl, hw = self.box[i]
            dx, dy = ox - x, oy - y
            reach = self.reach + self.half_diagonal[i]
            if dx * dx + dy * dy > reach * reach:
                continue
            # the obstacle in base_link: centre and length axis turned by −yaw
            bx, by = c * dx + s * dy, -s * dx + c * dy
            bux, buy = c * ux + s * uy, -s * ux + c * uy
            for cx, cy, hx, hy in self.rects:
                if rects_overlap(bx - cx, by - cy, hx, hy, bux, buy, hl, hw):
                    hits.append(i)
                    break
        return hits
