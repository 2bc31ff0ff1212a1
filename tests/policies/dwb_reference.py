"""Literal Python ports of Nav2 Humble's C++ (one call per pose, loops as written), used only to
check the vectorised implementation in ``policies.dwb`` against Nav2's own algorithms."""

from __future__ import annotations

import math

import numpy as np


class MapBasedQueue:
    """costmap_queue::MapBasedQueue: bins keyed by priority, each a vector popped from the back."""

    def __init__(self) -> None:
        self.bins: dict[float, list[tuple[int, int, int, int]]] = {}
        self.count = 0
        self.iter: float | None = None

    def enqueue(self, priority: float, item: tuple[int, int, int, int]) -> None:
        self.bins.setdefault(priority, []).append(item)
        self.count += 1
        if self.iter is None or priority < self.iter:
            self.iter = priority

    def front(self) -> tuple[int, int, int, int]:
        assert self.iter is not None
        return self.bins[self.iter][-1]

    def pop(self) -> None:
        assert self.iter is not None
        self.bins[self.iter].pop()
        self.count -= 1
        later = sorted(k for k in self.bins if k >= self.iter and self.bins[k])
        self.iter = later[0] if later else None


def costmap_queue_manhattan(size_x: int, size_y: int, sources: list[tuple[int, int]]) -> np.ndarray:
    """MapGridCritic::reset + enqueueCell(sources) + propogateManhattanDistances, as Humble runs
    them (MapGridQueue accepts every cell; CostmapQueue built with manhattan = true)."""
    unreachable = size_x * size_y + 1.0
    values = np.full((size_x, size_y), unreachable)
    seen = np.zeros((size_x, size_y), bool)
    q = MapBasedQueue()

    def enqueue(x: int, y: int, sx: int, sy: int) -> None:
        if seen[x, y]:
            return
        seen[x, y] = True
        q.enqueue(float(abs(x - sx) + abs(y - sy)), (x, y, sx, sy))

    for x, y in sources:
        values[x, y] = 0.0
        enqueue(x, y, x, y)
    while q.count:
        x, y, sx, sy = q.front()
        q.pop()
        if x > 0:
            enqueue(x - 1, y, sx, sy)
        if y > 0:
            enqueue(x, y - 1, sx, sy)
        if x < size_x - 1:
            enqueue(x + 1, y, sx, sy)
        if y < size_y - 1:
            enqueue(x, y + 1, sx, sy)
        values[x, y] = abs(sx - x) + abs(sy - y)
    return values


def project_velocity(v0: float, accel: float, decel: float, dt: float, target: float) -> float:
    if v0 < target:
        return min(target, v0 + accel * dt)
    return max(target, v0 + decel * dt)


def generate_trajectory(
    pose: tuple[float, float, float],
    vel: tuple[float, float],
    cmd: tuple[float, float],
    acc: tuple[float, float, float, float],
    sim_time: float,
    linear_granularity: float,
    angular_granularity: float,
) -> list[tuple[float, float, float]]:
    """StandardTrajectoryGenerator::generateTrajectory (discretize by distance, last point
    repeated); acc = (acc_x, decel_x, acc_theta, decel_theta)."""
    n = math.ceil(
        max(
            abs(cmd[0]) * sim_time / linear_granularity,
            abs(cmd[1]) * sim_time / angular_granularity,
        )
    )
    n = max(n, 1)
    dt = sim_time / n
    x, y, th = pose
    v, w = vel
    poses = [pose]
    for _ in range(n):
        v = project_velocity(v, acc[0], acc[1], dt, cmd[0])
        w = project_velocity(w, acc[2], acc[3], dt, cmd[1])
        x, y, th = (
            x + (v * math.cos(th) + 0.0 * math.cos(math.pi / 2 + th)) * dt,
            y + (v * math.sin(th) + 0.0 * math.sin(math.pi / 2 + th)) * dt,
            th + w * dt,
        )
        poses.append((x, y, th))
    poses.append(poses[-1])
    return poses


def one_d_iterator(
    current: float, vmin: float, vmax: float, acc: float, dec: float, dt: float, n: int
) -> list[float]:
    """OneDVelocityIterator's values, stepping it as XYThetaIterator does."""
    current = min(max(current, vmin), vmax)
    hi = project_velocity(current, acc, dec, dt, vmax)
    lo = project_velocity(current, acc, dec, dt, vmin)
    inc = 1.0 if abs(lo - hi) < 1e-5 else (hi - lo) / max(1, max(2, n) - 1)
    cur, return_zero, zero_now = lo, True, False
    out = []
    while not cur > hi + 1e-5:
        out.append(0.0 if zero_now else cur)
        if return_zero and cur < 0.0 and cur + inc > 0.0 and cur + inc <= hi + 1e-5:
            zero_now, return_zero = True, False
        else:
            cur += inc
            zero_now = False
    return out


def line_iterator(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    """nav2_util::LineIterator, stepped with advance() as written."""
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    xinc1 = xinc2 = 1 if x1 >= x0 else -1
    yinc1 = yinc2 = 1 if y1 >= y0 else -1
    if dx >= dy:
        xinc1, yinc2 = 0, 0
        den, num, numadd, numpixels = dx, dx // 2, dy, dx
    else:
        xinc2, yinc1 = 0, 0
        den, num, numadd, numpixels = dy, dy // 2, dx, dy
    x, y = x0, y0
    out = []
    for _ in range(numpixels + 1):
        out.append((x, y))
        num += numadd
        if num >= den:
            num -= den
            x += xinc1
            y += yinc1
        x += xinc2
        y += yinc2
    return out


def inflation_layer(
    layer: np.ndarray, resolution: float, inscribed: float, scaling: float, radius: float
) -> np.ndarray:
    """InflationLayer::updateCosts over the whole map: a wavefront from the lethal cells in
    bins of squared-distance rank, each cell taking the cost of the source that reaches it
    first (seen on pop), neighbours enqueued within ceil(radius / resolution) cells."""
    sx, sy = layer.shape
    r_cells = max(0, math.ceil(radius / resolution))
    r = r_cells + 2
    pts = sorted(
        ((x, y) for x in range(-r, r + 1) for y in range(-r, r + 1) if x * x + y * y <= r * r),
        key=lambda p: p[0] * p[0] + p[1] * p[1],
    )
    level, last, rank = 0, 0, {}
    for x, y in pts:
        if x * x + y * y != last:
            level += 1
        rank[(x, y)] = level
        last = x * x + y * y

    def cost(d: float) -> int:
        if d == 0:
            return 254
        if d * resolution <= inscribed:
            return 253
        return int(252 * math.exp(-1.0 * scaling * (d * resolution - inscribed)))

    master = layer.copy()
    seen = np.zeros(layer.shape, bool)
    bins: list[list[tuple[int, int, int, int]]] = [[] for _ in range(level + 1)]
    for i in range(sx):
        for j in range(sy):
            if layer[i, j] == 254:
                bins[0].append((i, j, i, j))
    for b in bins:
        k = 0
        while k < len(b):
            mx, my, srcx, srcy = b[k]
            k += 1
            if seen[mx, my]:
                continue
            seen[mx, my] = True
            master[mx, my] = max(int(master[mx, my]), cost(math.hypot(mx - srcx, my - srcy)))
            for nx, ny in ((mx - 1, my), (mx, my - 1), (mx + 1, my), (mx, my + 1)):
                if 0 <= nx < sx and 0 <= ny < sy and not seen[nx, ny]:
                    if math.hypot(nx - srcx, ny - srcy) > r_cells:
                        continue
                    bins[rank[(nx - srcx, ny - srcy)]].append((nx, ny, srcx, srcy))
    return master
