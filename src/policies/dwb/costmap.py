"""Nav2's local costmap from the depth camera: a rolling voxel layer and the inflation layer.

Cells hold Nav2's costs (0 free … 252 inflated, 253 inscribed, 254 lethal). The voxel layer
keeps Nav2's semantics: points between min and max obstacle height (within the obstacle range)
mark their voxel, a column with a marked voxel is lethal, rays from the camera to those same
points clear the voxels they cross (shortened by two cells, as Nav2 does, so the point's own
voxel survives), the window rolls with the robot in whole cells and keeps what left the
camera's view, and the cells under the footprint are cleared. Inflation gives every cell
``computeCost`` of its distance to the nearest lethal cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from scenario_gen.arrays import FloatArray

from .params import InflationLayerParams, VoxelLayerParams

FREE, INSCRIBED, LETHAL, NO_INFORMATION = 0, 253, 254, 255


# ----------------------------------------------------------------------------- footprint
def rectangle_footprint(length: float, width: float) -> FloatArray:
    """The robot's rectangle (centred on base_link) as Nav2's footprint polygon."""
    hx, hy = length / 2, width / 2
    return np.array([[hx, hy], [hx, -hy], [-hx, -hy], [-hx, hy]])


def pad_footprint(footprint: FloatArray, padding: float) -> FloatArray:
    """nav2_costmap_2d::padFootprint: every coordinate moved ``padding`` away from 0."""
    fp = np.asarray(footprint, np.float64)
    return fp + np.sign(fp) * padding


def _distance_to_line(px: float, py: float, a: FloatArray, b: FloatArray) -> float:
    c, d = b - a
    t = ((px - a[0]) * c + (py - a[1]) * d) / (c * c + d * d)
    q = a if t < 0 else b if t > 1 else a + t * np.array([c, d])
    return math.hypot(px - q[0], py - q[1])


def footprint_radii(footprint: FloatArray) -> tuple[float, float]:
    """(inscribed, circumscribed) radius as calculateMinAndMaxDistances computes them."""
    lo, hi = math.inf, 0.0
    n = len(footprint)
    for i in range(n):
        a, b = footprint[i], footprint[(i + 1) % n]
        vertex = math.hypot(a[0], a[1])
        edge = _distance_to_line(0.0, 0.0, a, b)
        lo, hi = min(lo, vertex, edge), max(hi, vertex, edge)
    return lo, hi


def inside_polygon(px: FloatArray, py: FloatArray, poly: FloatArray) -> NDArray[np.bool_]:
    """Points inside a convex or concave polygon (even-odd rule)."""
    inside = np.zeros(px.shape, bool)
    n = len(poly)
    for i in range(n):
        x0, y0 = poly[i]
        x1, y1 = poly[(i + 1) % n]
        crosses = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (px < xc)
    return inside


# ----------------------------------------------------------------------------- grid
@dataclass
class Grid:
    """A Costmap2D's geometry: origin (world coordinates of cell (0, 0)'s corner) and size.
    Arrays are indexed [mx, my]."""

    origin_x: float
    origin_y: float
    size_x: int
    size_y: int
    resolution: float

    def world_to_map(
        self, wx: FloatArray, wy: FloatArray
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
        """Costmap2D::worldToMap for arrays: cell indices and whether they are on the map."""
        fx = (wx - self.origin_x) / self.resolution
        fy = (wy - self.origin_y) / self.resolution
        ok = (wx >= self.origin_x) & (wy >= self.origin_y)
        mx = np.where(ok, fx, 0).astype(np.int64)
        my = np.where(ok, fy, 0).astype(np.int64)
        ok &= (mx < self.size_x) & (my < self.size_y)
        return mx, my, ok

    def cell_centres(self) -> tuple[FloatArray, FloatArray]:
        cx = self.origin_x + (np.arange(self.size_x) + 0.5) * self.resolution
        cy = self.origin_y + (np.arange(self.size_y) + 0.5) * self.resolution
        return np.meshgrid(cx, cy, indexing="ij")

    def shift(self, new_origin_x: float, new_origin_y: float) -> tuple[int, int]:
        """Costmap2D::updateOrigin's whole-cell move: returns the shift in cells."""
        cox = int((new_origin_x - self.origin_x) / self.resolution)
        coy = int((new_origin_y - self.origin_y) / self.resolution)
        self.origin_x += cox * self.resolution
        self.origin_y += coy * self.resolution
        return cox, coy


def shift_array(a: NDArray[Any], cox: int, coy: int, fill: object) -> NDArray[Any]:
    """A grid's contents after its origin moved by (cox, coy) cells; new cells hold ``fill``."""
    out = np.full_like(a, fill)
    sx, sy = a.shape[:2]
    x0, x1 = max(cox, 0), min(cox + sx, sx)
    y0, y1 = max(coy, 0), min(coy + sy, sy)
    if x1 > x0 and y1 > y0:
        out[x0 - cox : x1 - cox, y0 - coy : y1 - coy] = a[x0:x1, y0:y1]
    return out


# ----------------------------------------------------------------------------- inflation
def compute_cost(
    distance_cells: FloatArray, resolution: float, inscribed: float, scaling: float
) -> NDArray[np.uint8]:
    """InflationLayer::computeCost on distances in cells (0 lethal, ≤ inscribed 253, then
    252·exp(−k (d − r_inscribed)) truncated to an integer)."""
    d = np.asarray(distance_cells, np.float64) * resolution
    factor = np.exp(-1.0 * scaling * (d - inscribed))
    cost = (np.float64(INSCRIBED - 1) * factor).astype(np.int64)
    cost = np.where(d <= inscribed, INSCRIBED, cost)
    cost = np.where(distance_cells == 0, LETHAL, cost)
    return np.clip(cost, 0, 255).astype(np.uint8)


def inflate(
    layer: NDArray[np.uint8], resolution: float, inscribed: float, p: InflationLayerParams
) -> NDArray[np.uint8]:
    """The master grid after the inflation layer: each cell takes the max of its own cost and
    computeCost of its Euclidean cell distance to the nearest lethal cell, for cells within
    ceil(inflation_radius / resolution) cells."""
    master = layer.copy()
    lethal = layer == LETHAL
    if not p.enabled or not lethal.any():
        return master
    radius_cells = max(0.0, math.ceil(p.inflation_radius / resolution))
    if radius_cells == 0:
        return master
    dist = ndimage.distance_transform_edt(~lethal)
    near = dist <= radius_cells
    cost = compute_cost(dist[near], resolution, inscribed, p.cost_scaling_factor)
    master[near] = np.maximum(master[near], cost)
    return master


# ----------------------------------------------------------------------------- voxel layer
class VoxelLayer:
    """Nav2's VoxelLayer fed by one depth-camera source, in a rolling window."""

    def __init__(self, grid: Grid, p: VoxelLayerParams) -> None:
        self.grid = grid
        self.p = p
        self.voxels = np.zeros((grid.size_x, grid.size_y, p.z_voxels), bool)
        self.cost = np.zeros((grid.size_x, grid.size_y), np.uint8)

    def reset(self) -> None:
        self.voxels[:] = False
        self.cost[:] = FREE

    def roll(self, robot_x: float, robot_y: float) -> None:
        """Keep the robot at the window's centre (rolling_window: true)."""
        g = self.grid
        # Costmap2D::getSizeInMetersX is (size_x - 1 + 0.5) * resolution
        cox, coy = g.shift(
            robot_x - (g.size_x - 0.5) * g.resolution / 2,
            robot_y - (g.size_y - 0.5) * g.resolution / 2,
        )
        if cox or coy:
            self.voxels = shift_array(self.voxels, cox, coy, False)
            self.cost = shift_array(self.cost, cox, coy, FREE)

    def update(self, points: FloatArray, origin: FloatArray, footprint: FloatArray | None) -> None:
        """Clear along the rays to ``points`` then mark them (world frame, z above the
        wheels' plane), then free the cells under ``footprint`` (world polygon)."""
        if not self.p.enabled:
            return
        src = self.p.depth_camera
        pts = points[
            (points[:, 2] >= src.min_obstacle_height) & (points[:, 2] <= src.max_obstacle_height)
        ]
        if src.clearing and len(pts):
            self._raytrace(pts, origin)
        if src.marking and len(pts):
            self._mark(pts, origin)
        if footprint is not None and self.p.footprint_clearing_enabled:
            cx, cy = self.grid.cell_centres()
            self.cost[inside_polygon(cx, cy, footprint)] = FREE

    def _mark(self, pts: FloatArray, origin: FloatArray) -> None:
        p, src = self.p, self.p.depth_camera
        pts = pts[pts[:, 2] <= p.max_obstacle_height]
        d2 = ((pts - origin) ** 2).sum(axis=1)
        pts = pts[(d2 < src.obstacle_max_range**2) & (d2 >= src.obstacle_min_range**2)]
        z = np.maximum(pts[:, 2], p.origin_z)  # below the floor marks the floor voxel
        mx, my, ok = self.grid.world_to_map(pts[:, 0], pts[:, 1])
        mz = np.floor((z - p.origin_z) / p.z_resolution).astype(np.int64)
        ok &= mz < p.z_voxels
        self.voxels[mx[ok], my[ok], mz[ok]] = True
        col = self.voxels.sum(axis=2) > p.mark_threshold
        self.cost[mx[ok], my[ok]] = np.where(col[mx[ok], my[ok]], LETHAL, self.cost[mx[ok], my[ok]])

    def _raytrace(self, pts: FloatArray, origin: FloatArray) -> None:
        """VoxelLayer::raytraceFreespace + clearVoxelLineInMap (3-D Bresenham in cell units)."""
        g, p, src = self.grid, self.p, self.p.depth_camera
        res = g.resolution
        ox, oy, oz = origin
        if not (
            g.origin_x <= ox < g.origin_x + g.size_x * res
            and g.origin_y <= oy < g.origin_y + g.size_y * res
            and p.origin_z <= oz < p.origin_z + p.z_voxels * p.z_resolution
        ):
            return  # Nav2 warns that the sensor is outside the map and skips raytracing
        rel = pts - origin
        dist = np.linalg.norm(rel, axis=1)
        scale = np.clip(np.minimum(1.0, (dist - 2 * res) / np.where(dist > 0, dist, 1)), 0, None)
        w = origin + rel * scale[:, None]
        a, b, c = (w - origin).T
        t = np.ones(len(w))
        end_x, end_y = g.origin_x + g.size_x * res, g.origin_y + g.size_y * res
        end_z = p.origin_z + p.z_voxels * p.z_resolution
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(
                w[:, 2] > end_z, np.clip(np.minimum(t, (end_z - 0.01 - oz) / c), 0, None), t
            )
            t = np.where(w[:, 2] < p.origin_z, np.minimum(t, (p.origin_z - oz) / c), t)
            t = np.where(w[:, 0] < g.origin_x, np.minimum(t, (g.origin_x - ox) / a), t)
            t = np.where(w[:, 1] < g.origin_y, np.minimum(t, (g.origin_y - oy) / b), t)
            t = np.where(w[:, 0] > end_x, np.minimum(t, (end_x - ox) / a), t)
            t = np.where(w[:, 1] > end_y, np.minimum(t, (end_y - oy) / b), t)
        e = origin + np.column_stack([a, b, c]) * t[:, None]
        # worldToMap3DFloat: continuous voxel coordinates
        s0 = np.array(
            [(ox - g.origin_x) / res, (oy - g.origin_y) / res, (oz - p.origin_z) / p.z_resolution]
        )
        s1 = np.column_stack(
            [
                (e[:, 0] - g.origin_x) / res,
                (e[:, 1] - g.origin_y) / res,
                (e[:, 2] - p.origin_z) / p.z_resolution,
            ]
        )
        keep = (
            (s1 >= 0).all(axis=1)
            & (s1[:, 0] < g.size_x)
            & (s1[:, 1] < g.size_y)
            & (s1[:, 2] < p.z_voxels)
        )
        s1 = s1[keep]
        if not len(s1):
            return
        max_len = math.ceil(src.raytrace_max_range / res)
        min_len = math.ceil(src.raytrace_min_range / res)
        ln = np.sqrt(((s1 - s0) ** 2).sum(axis=1))
        s1 = s1[ln.astype(np.int64) >= min_len]
        ln = ln[ln.astype(np.int64) >= min_len]
        if not len(s1):
            return
        start = s0 + (s1 - s0) / np.where(ln > 0, ln, 1)[:, None] * min_len
        start = np.where((ln > 0)[:, None], start, s0)
        sc = np.where(ln > 0, np.minimum(1.0, max_len / np.where(ln > 0, ln, 1)), 1.0)
        i0 = start.astype(np.int64)
        d = s1.astype(np.int64) - i0
        ad = np.abs(d)
        dom = np.argmax(
            np.column_stack([ad[:, 0], ad[:, 1], ad[:, 2]]) == ad.max(axis=1, keepdims=True), axis=1
        )
        da = ad[np.arange(len(ad)), dom]
        n_steps = np.minimum((sc * da).astype(np.int64), da)  # bresenham3D visits n_steps + 1
        k = np.arange(int(n_steps.max()) + 1)
        live = k[None, :] <= n_steps[:, None]
        cells = np.empty((len(s1), len(k), 3), np.int64)
        for axis in range(3):
            is_dom = dom == axis
            num = (da // 2)[:, None] + k[None, :] * ad[:, axis][:, None]
            minor = np.sign(d[:, axis])[:, None] * (num // np.maximum(da, 1)[:, None])
            major = np.sign(d[:, axis])[:, None] * k[None, :]
            cells[:, :, axis] = i0[:, axis][:, None] + np.where(is_dom[:, None], major, minor)
        c = cells[live]
        ok = (
            (c[:, 0] >= 0)
            & (c[:, 0] < g.size_x)
            & (c[:, 1] >= 0)
            & (c[:, 1] < g.size_y)
            & (c[:, 2] >= 0)
            & (c[:, 2] < p.z_voxels)
        )
        c = c[ok]
        self.voxels[c[:, 0], c[:, 1], c[:, 2]] = False
        cols = np.unique(c[:, 0] * g.size_y + c[:, 1])
        cx, cy = cols // g.size_y, cols % g.size_y
        empty = self.voxels[cx, cy].sum(axis=1) <= p.mark_threshold
        self.cost[cx[empty], cy[empty]] = FREE
