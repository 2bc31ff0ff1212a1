"""Cross-track metrics exactly as the source paper defines them (design.md, "Metrics"), in one
place.

Cross-track error = perpendicular distance from each recorded pose (the ground projection of
base_link) to the nearest segment of the reference path — the globally nearest one, found
exactly in O(log n) per pose. Reported: global RMSE, MAE, max, in-furrow RMSE and headland RMSE
(by the tag of each pose's nearest segment: furrow when both its waypoints are), completion
(% of the route's length reached along the route) and crops hit; beside them the obstacles
(stones, litter, fallen stalks) the robot's footprint touched, in all and per kind. The paper's
RMSEs weigh every recorded pose (every 20 Hz step: time-weighted, so a robot standing still
adds its error again each step); the ``path_*`` RMSEs weigh each pose by the path driven around
it (half of the distance to each neighbour, trapezoidal in arc length), so they measure where
the robot went, not how long it stayed — the headline of the benchmark tables. A category
without poses reports ``None``, not NaN, so results compare and serialize cleanly.

Where rows were planted off their logged lines (``layout.drift_amplitude``) the route is the
logged line, and ``planted_lane_rmse`` measures the driven path from the lanes as planted.
"""

from __future__ import annotations

import ctypes
import math
from bisect import bisect_left, bisect_right
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from scenario_gen.arrays import FloatArray
from scenario_gen.obstacles import OBSTACLE_KINDS

from .render import native as _native


class RouteProjector:
    """Exact nearest segment of a polyline to a point.

    The nearest point q of the polyline lies on a segment whose nearer endpoint is within L/2
    of q (L: the longest segment), so within d + L/2 of the query point for any upper bound d
    of the answer — the distance to the nearest vertex, or to any one segment (the task's
    tracker knows one). Only the segments touching the vertices in that disc are tested (any
    set of segments that holds those gives the same answer, ties to the lowest index); a
    uniform grid of the vertices finds them with a few dictionary lookups. Where the extension
    is built (``native`` None: when available) the search runs in the kernel ``route_nearest``,
    the Python below its twin (the same bits).
    """

    def __init__(
        self, xy: FloatArray, furrow: NDArray[np.bool_], native: bool | None = None
    ) -> None:
        self.xy = np.asarray(xy, np.float64)
        if len(self.xy) < 2:
            raise ValueError(f"a route needs at least 2 points, got {len(self.xy)}")
        d = np.diff(self.xy, axis=0)
        self.seg_len = np.hypot(d[:, 0], d[:, 1])
        self.arc = np.concatenate([[0.0], np.cumsum(self.seg_len)])
        self.half = 0.5 * float(self.seg_len.max())
        self.tree = cKDTree(self.xy)
        f = np.asarray(furrow, bool)
        self.seg_furrow = f[:-1] & f[1:]
        self.cell = max(10.0 * self.half, 0.25)  # a few vertices per cell
        self.grid: dict[tuple[int, int], list[int]] = {}
        for i, (cx, cy) in enumerate(np.floor(self.xy / self.cell).astype(int).tolist()):
            self.grid.setdefault((cx, cy), []).append(i)
        self._pts = self.xy.tolist()
        self._len = self.seg_len.tolist()
        self._arc = self.arc.tolist()
        n = len(self._pts) - 1
        # per cell, the segments touching its vertices in index order; per segment what the
        # distance test reads (the same expressions as computed in the loop before)
        self._cell_segs = {
            key: sorted({j for v in verts for j in (v - 1, v) if 0 <= j < n})
            for key, verts in self.grid.items()
        }
        self._segs = []
        for k in range(n):
            (ax, ay), (bx, by) = self._pts[k], self._pts[k + 1]
            dx, dy = bx - ax, by - ay
            self._segs.append((ax, ay, dx, dy, dx * dx + dy * dy))
        # per grid row (y cell), its occupied x cells in order and their vertices with their
        # coordinates: a disc's vertices are found among the occupied cells only
        self._rows: dict[int, tuple[list[int], list[list[tuple[int, float, float]]]]] = {}
        for (cx, cy), verts in sorted(self.grid.items(), key=lambda kv: (kv[0][1], kv[0][0])):
            xs, cells = self._rows.setdefault(cy, ([], []))
            xs.append(cx)
            cells.append([(v, *self._pts[v]) for v in verts])
        self._nearest: _native.RouteNearestArgs | None = None
        if _native.available() if native is None else native:
            self._nearest = _native.RouteNearestArgs(
                grid=self._grid_block(), x=0.0, y=0.0, bound=0.0, d=0.0, s=0.0, k=0
            )
            self._call = _native.kernel("route_nearest")
            self._ref = ctypes.byref(self._nearest)

    def _grid_block(self) -> _native.RouteGrid:
        """The search as the kernel ``route_nearest`` reads it: the segments, and the vertices
        in a dense grid of cells (``native.cell_grid``)."""
        g = _native.cell_grid(self.xy, self.cell)
        return _native.RouteGrid(
            n=len(self.xy),
            segs=np.array(self._segs, np.float64).reshape(-1, 5),
            seg_len=np.ascontiguousarray(self.seg_len, np.float64),
            arc=np.ascontiguousarray(self.arc, np.float64),
            half=self.half,
            **g.fields(),
            xy=np.ascontiguousarray(self.xy, np.float64),
        )

    @property
    def length(self) -> float:
        return float(self.arc[-1])

    def project(self, x: float, y: float, bound: float | None = None) -> tuple[float, int, float]:
        """(distance, segment index, arc length of the nearest point); ``bound`` is any upper
        bound of the distance (else the nearest vertex's distance is used)."""
        if bound is None:
            bound = float(self.tree.query((x, y))[0])
        a = self._nearest
        if a is not None:  # the kernel: the same search (tests compare the two)
            a.x, a.y, a.bound = x, y, bound
            status = self._call(self._ref)
            if status:
                raise _native.failed("route_nearest", status)
            return a.d, a.k, a.s
        r = bound + self.half + 1e-9
        c = self.cell
        i0, i1 = math.floor((x - r) / c), math.floor((x + r) / c)
        j0, j1 = math.floor((y - r) / c), math.floor((y + r) / c)
        n = len(self._pts) - 1
        if i0 == i1 and j0 == j1:  # the usual case: one cell, its segments listed
            segs = self._cell_segs.get((i0, j0), [])
        elif j1 - j0 > 40:  # a loose bound: the KD-tree is cheaper
            near = self.tree.query_ball_point((x, y), r)
            segs = sorted({j for v in near for j in (v - 1, v) if 0 <= j < n})
        else:  # the vertices in the disc, from the occupied cells of its rows
            rows, r2 = self._rows, r * r
            near = []
            for j in range(j0, j1 + 1):
                row = rows.get(j)
                if row is None:
                    continue
                xs, cells = row
                for cell in cells[bisect_left(xs, i0) : bisect_right(xs, i1)]:
                    for v, vx, vy in cell:
                        ex, ey = vx - x, vy - y
                        if ex * ex + ey * ey <= r2:
                            near.append(v)
            segs = sorted({j for v in near for j in (v - 1, v) if 0 <= j < n})
        if len(segs) > 24:
            return self._project_many(x, y, np.asarray(segs))
        best_d, best_k, best_u = math.inf, 0, 0.0
        table = self._segs
        for k in segs:
            ax, ay, dx, dy, L2 = table[k]
            u = 0.0 if L2 <= 0 else min(max(((x - ax) * dx + (y - ay) * dy) / L2, 0.0), 1.0)
            ex, ey = x - ax - u * dx, y - ay - u * dy
            dist = math.sqrt(ex * ex + ey * ey)
            if dist < best_d:
                best_d, best_k, best_u = dist, k, u
        if best_d == math.inf:
            return best_d, 0, 0.0
        return best_d, best_k, self._arc[best_k] + best_u * self._len[best_k]

    def _project_many(self, x: float, y: float, segs: NDArray[np.intp]) -> tuple[float, int, float]:
        a, b = self.xy[segs], self.xy[segs + 1]
        ab = b - a
        L2 = (ab * ab).sum(axis=1)
        rel = np.array([x, y]) - a
        u = np.clip(np.where(L2 > 0, (rel * ab).sum(axis=1) / np.where(L2 > 0, L2, 1.0), 0.0), 0, 1)
        e = rel - u[:, None] * ab
        d = np.sqrt((e * e).sum(axis=1))
        i = int(np.argmin(d))  # first minimum: the lowest segment index, as the loop keeps
        k = int(segs[i])
        return float(d[i]), k, float(self.arc[k] + u[i] * self.seg_len[k])


class EpisodeMetrics:
    """Accumulates the paper's metrics pose by pose: O(log n) per pose, O(1) to report."""

    def __init__(self, xy: FloatArray, furrow: NDArray[np.bool_]) -> None:
        self.route = RouteProjector(xy, furrow)
        self._seg_furrow = self.route.seg_furrow.tolist()
        self.poses: list[tuple[float, float]] = []
        self.errors: list[float] = []  # per pose, for figures
        # (poses, Σd², Σ|d|, max) over all poses, in furrow, on the headland
        self.sums = {k: [0, 0.0, 0.0, 0.0] for k in ("all", "furrow", "headland")}
        # (metres driven, ∫d² ds) per category: the path-weighted RMSE, trapezoidal in ds
        self.path = {k: [0.0, 0.0] for k in ("all", "furrow", "headland")}
        self._last: tuple[float, float, float, str] | None = None  # x, y, d, category
        self.reached = 0.0  # furthest arc length along the route (the task's tracker)

    def update(self, x: float, y: float, s: float, bound: float | None = None) -> None:
        """Record a pose; ``s`` is its arc length along the route as the task tracks it and
        ``bound`` its distance to any one route segment (speeds up the exact search)."""
        d, k, _ = self.route.project(x, y, bound)
        self.poses.append((x, y))
        self.errors.append(d)
        cat = "furrow" if self._seg_furrow[k] else "headland"
        sums = self.sums
        dd = d * d
        for a in (sums["all"], sums[cat]):
            a[0] += 1
            a[1] += dd
            a[2] += d
            a[3] = max(a[3], d)
        if self._last is not None:
            # Each pose owns half of the path on either side of it: standing still weighs nothing.
            px, py, pd, pcat = self._last
            half = 0.5 * math.hypot(x - px, y - py)
            path = self.path
            for key, err in (("all", pd), (pcat, pd), ("all", d), (cat, d)):
                acc = path[key]
                acc[0] += half
                acc[1] += half * err * err
        self._last = (x, y, d, cat)
        self.reached = max(self.reached, s)

    def break_path(self) -> None:
        """The next pose does not continue the driven path (the robot was put back on the
        route): no path is weighed between the two."""
        self._last = None

    def result(self, crops_hit: int, obstacles_hit: Iterable[str] = ()) -> dict[str, Any]:
        """The metrics so far; ``obstacles_hit`` is the kind of each distinct obstacle
        touched (``scenario_gen.obstacles.OBSTACLE_KINDS``)."""
        by_kind = dict.fromkeys(OBSTACLE_KINDS, 0)
        for kind in obstacles_hit:
            by_kind[kind] += 1  # an unknown kind is a KeyError: no count is dropped silently

        def rmse(key: str) -> float | None:
            n, sq = self.sums[key][0], self.sums[key][1]
            return math.sqrt(sq / n) if n else None

        def path_rmse(key: str) -> float | None:
            ds, sq = self.path[key]
            return math.sqrt(sq / ds) if ds > 0 else None

        n, _, total, worst = self.sums["all"]
        length = self.route.length
        return {
            "path_rmse": path_rmse("all"),
            "path_in_furrow_rmse": path_rmse("furrow"),
            "path_headland_rmse": path_rmse("headland"),
            "driven_m": self.path["all"][0],
            "rmse": rmse("all"),
            "mae": total / n if n else None,
            "max": worst if n else None,
            "in_furrow_rmse": rmse("furrow"),
            "headland_rmse": rmse("headland"),
            "completion": 100.0 * self.reached / length if length > 0 else 0.0,
            "crops_hit": int(crops_hit),
            "obstacles_hit": sum(by_kind.values()),
            "obstacles_hit_by_kind": by_kind,
            "poses": int(n),
        }

    @property
    def trajectory(self) -> FloatArray:
        """Ground-truth base positions (N, 2): for evaluation, never policies."""
        return np.asarray(self.poses, np.float64).reshape(-1, 2)


def planted_lane_rmse(poses: FloatArray, scenario: Any) -> float | None:
    """Path-weighted RMSE (m) of the poses (N, 2) that stand in a planted lane from that
    lane's centre as planted, midway between its two rows with their drift
    (``scenario_gen.drift.lane_error``): the error a follower of the rows is judged by where
    the route is the logged line. Each pose weighs half the path to each neighbour, as the
    ``path_*`` RMSEs; None without a pose in a lane."""
    from scenario_gen.drift import lane_error
    from scenario_gen.generate import planting_drift

    xy = np.asarray(poses, np.float64).reshape(-1, 2)
    if len(xy) == 0:
        return None
    err, inside = lane_error(
        scenario.rows, planting_drift(scenario), scenario.spec.layout, xy[:, 0], xy[:, 1]
    )
    step = np.hypot(*np.diff(xy, axis=0).T)
    weight = 0.5 * (np.concatenate([[0.0], step]) + np.concatenate([step, [0.0]]))
    w = weight[inside]
    if w.sum() <= 0.0:
        return None
    return math.sqrt(float(np.sum(w * err[inside] ** 2) / w.sum()))
