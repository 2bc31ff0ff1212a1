"""Crop contact: which stalks the robot's wheels and chassis touch (analytic, no bodies).

Model: each crop is a vertical stalk, a circle of the catalog's stem diameter at its growth
(scaled with the plant's height), at its position; the robot is its URDF collision footprint
seen from above — the chassis box and the four wheels as rectangles in base_link — ignoring
tilt. A crop is hit when its stalk circle overlaps any rectangle. Leaves brush the robot without
counting (they bend); weeds never count. A KD-tree of the crops finds the dozen candidates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from scenario_gen import Scenario
from scenario_gen.crops import scaled_by_height

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
