"""Reference routes for the tasks and a cheap incremental tracker along them."""

from __future__ import annotations

import ctypes
import itertools
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Scenario
from scenario_gen.arrays import FloatArray
from scenario_gen.routes import lane_path

from .render import native as _native

TABLE_STEP = 0.02  # m: route lookup table resolution (waypoints are ≤ 0.1 m apart)
#: A reversing route's cusp counts as reached this close along the route (m): a robot stops
#: and reverses within a few centimetres of it.
CUSP_REACH = 0.1
FEW = 32  # lookups of at most this many points run in Python floats (lookup_points)


@dataclass(frozen=True, eq=False)
class RoutePath:
    xy: FloatArray  # (n, 2) waypoints
    z: FloatArray
    furrow: NDArray[np.bool_]  # per waypoint
    arc: FloatArray  # cumulative arc length at each waypoint
    heading: FloatArray  # the robot's facing along the segment leaving each waypoint
    #: the segment leaving each waypoint is driven backwards (a three-point turn's middle leg:
    #: there ``heading`` faces against the direction of travel); None: all forwards
    reverse: NDArray[np.bool_] | None = None

    @classmethod
    def from_points(
        cls,
        xy: FloatArray,
        z: FloatArray,
        furrow: NDArray[np.bool_],
        reverse: NDArray[np.bool_] | None = None,
    ) -> RoutePath:
        d = np.diff(xy, axis=0)
        seg = np.hypot(d[:, 0], d[:, 1])
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        heading = np.arctan2(d[:, 1], d[:, 0])
        heading = np.concatenate([heading, heading[-1:]])
        if reverse is not None and reverse.any():
            heading = np.where(reverse, heading + math.pi, heading)
            heading = (heading + math.pi) % (2 * math.pi) - math.pi
        else:
            reverse = None
        return cls(xy, z, furrow, arc, heading, reverse)

    @property
    def length(self) -> float:
        return float(self.arc[-1])

    @cached_property
    def _table(self) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
        """The route resampled every TABLE_STEP of arc length, for constant-time lookups, and
        the direction of its last segment."""
        n = max(2, int(self.length // TABLE_STEP) + 1)
        s = np.arange(n, dtype=np.float64) * TABLE_STEP
        pts = self.sample(s)
        tags = self.furrow[
            np.minimum(np.searchsorted(self.arc, s, side="right") - 1, len(self.furrow) - 1)
        ]
        d = self.xy[-1] - self.xy[-2]
        return pts, tags, d / max(float(np.hypot(d[0], d[1])), 1e-12)

    def lookup(self, s: NDArray[np.floating]) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Points and furrow tags at arc lengths ``s``. Past the end the route's last segment
        goes on at true distances, so "keep going straight" is what an observation says there
        (the end point repeated would say "stop here")."""
        if len(s) <= FEW:
            return self.lookup_points(s.tolist())
        pts, tags, direction = self._table
        u = np.maximum(s, 0.0) / TABLE_STEP
        i = np.minimum(u.astype(np.intp), len(pts) - 2)
        f = np.minimum(u - i, 1.0)[:, None]
        out = pts[i] * (1.0 - f) + pts[i + 1] * f
        tag = tags[i]
        past = s > (len(pts) - 1) * TABLE_STEP
        if past.any():
            out[past] = self.xy[-1] + (s[past] - self.length)[:, None] * direction
            tag = np.where(past, self.furrow[-1], tag)
        return out, tag

    @cached_property
    def _table_lists(self) -> tuple[list[list[float]], list[bool], float, float, float, float]:
        pts, tags, direction = self._table
        (x1, y1), (dx, dy) = self.xy[-1].tolist(), direction.tolist()
        return pts.tolist(), tags.tolist(), x1, y1, dx, dy

    def lookup_points(self, s: list[float]) -> tuple[FloatArray, NDArray[np.bool_]]:
        """``lookup`` of a few arc lengths (an observation's points) in Python floats: the
        same arithmetic, element by element, without numpy's per-call cost."""
        pts, tags, x1, y1, dx, dy = self._table_lists
        last = len(pts) - 2
        end = (len(pts) - 1) * TABLE_STEP
        length = self.length
        xy: list[float] = []
        tag: list[bool] = []
        for v in s:
            if v > end:  # past the end: the last segment goes on
                t = v - length
                xy += (x1 + t * dx, y1 + t * dy)
                tag.append(bool(self.furrow[-1]))
                continue
            u = max(v, 0.0) / TABLE_STEP
            i = min(int(u), last)
            f = min(u - i, 1.0)
            (ax, ay), (bx, by) = pts[i], pts[i + 1]
            g = 1.0 - f
            xy += (ax * g + bx * f, ay * g + by * f)
            tag.append(tags[i])
        return np.array(xy, np.float64).reshape(-1, 2), np.array(tag, bool)

    @cached_property
    def native(self) -> _native.Route:
        """The route as the compiled kernels read it (``route_t``)."""
        pts, tags, direction = self._table
        return _native.Route(
            xy=np.ascontiguousarray(self.xy, np.float64),
            arc=np.ascontiguousarray(self.arc, np.float64),
            n=len(self.xy),
            table=np.ascontiguousarray(pts, np.float64),
            tags=np.ascontiguousarray(tags, np.uint8),
            m=len(pts),
            table_step=TABLE_STEP,
            end=self.xy[-1].tolist(),
            direction=direction.tolist(),
            length=self.length,
            furrow_last=int(bool(self.furrow[-1])),
        )

    def sample(self, s: FloatArray) -> FloatArray:
        """Points at arc lengths ``s`` (clamped to the route)."""
        return np.column_stack(
            [np.interp(s, self.arc, self.xy[:, 0]), np.interp(s, self.arc, self.xy[:, 1])]
        )


def lane_route(scn: Scenario, lane: int, spacing: float = 0.05, lead: float = 0.0) -> RoutePath:
    """One lane centreline (start -> end of its crop rows), optionally with a headland lead-in;
    on curved and contour rows it follows the rows' curve."""
    if scn.rows.curve is not None:
        xy, furrow = lane_path(scn.rows, scn.field, lane, spacing, lead)
        return RoutePath.from_points(xy, scn.terrain.height_at(xy[:, 0], xy[:, 1]), furrow)
    a, b = scn.lanes[lane]
    u = (b - a) / np.linalg.norm(b - a)
    start = a - lead * u
    n = max(2, math.ceil(np.linalg.norm(b - start) / spacing) + 1)
    f = np.linspace(0.0, 1.0, n)[:, None]
    xy = start * (1 - f) + b * f
    furrow = ((xy - a) @ u) >= -1e-9
    return RoutePath.from_points(xy, scn.terrain.height_at(xy[:, 0], xy[:, 1]), furrow)


def scenario_route(scn: Scenario) -> RoutePath:
    r = scn.route
    return RoutePath.from_points(
        r.xy.copy(), r.xyz[:, 2].copy(), r.segment == "furrow", r.direction < 0
    )


class Tracker:
    """Nearest route segment to a moving point, searched in a window around the last match.

    Called twice per env step with a handful of segments: in the compiled kernel
    ``route_track`` where the extension is built (``native`` None: when available), else in
    Python floats (for windows this small numpy's per-call cost exceeds the arithmetic); the
    two give the same bits.

    A route that reverses (a three-point turn) doubles back on itself at its cusps, where the
    nearest segment may lie on the other leg: the search then stays within the leg it is on
    and moves on to the next leg once the point's foot is within ``CUSP_REACH`` of the cusp
    (in Python: the kernel searches one leg-free route).
    """

    def __init__(self, route: RoutePath, native: bool | None = None) -> None:
        self.route = route
        self.k = 0
        self._xy = route.xy.tolist()
        self._arc = route.arc.tolist()
        self._legs: list[tuple[int, int]] | None = None  # (first, last) segment of each leg
        self._leg_of: list[int] = []
        if route.reverse is not None:
            seg = route.reverse[:-1]
            cuts = [0, *(np.flatnonzero(seg[1:] != seg[:-1]) + 1).tolist(), len(seg)]
            self._legs = [(a, b - 1) for a, b in itertools.pairwise(cuts)]
            self._leg_of = np.repeat(np.arange(len(self._legs)), np.diff(cuts)).tolist()
        self._args: _native.RouteTrackArgs | None = None
        use_kernel = _native.available() if native is None else native
        if use_kernel and self._legs is None:
            self._args = _native.RouteTrackArgs(
                route=route.native, x=0.0, y=0.0, k=0, cte=0.0, s=0.0
            )
            self._call = _native.kernel("route_track")
            self._ref = ctypes.byref(self._args)

    def reset(self, x: float, y: float) -> None:
        d = np.hypot(self.route.xy[:, 0] - x, self.route.xy[:, 1] - y)
        self.k = int(np.argmin(d[: max(2, len(d) // 2)]))  # starts belong to the first half
        self.update(x, y)

    def reset_at(self, s: float, x: float, y: float) -> None:
        """Restart the search at the segment holding arc length ``s`` (a robot put back on the
        route, anywhere along it)."""
        self.k = int(
            np.clip(np.searchsorted(self.route.arc, s, side="right") - 1, 0, len(self._xy) - 2)
        )
        self.update(x, y)

    def _seg(self, k: int, x: float, y: float) -> tuple[float, float, float]:
        ax, ay = self._xy[k]
        bx, by = self._xy[k + 1]
        dx, dy = bx - ax, by - ay
        px, py = x - ax, y - ay
        L2 = dx * dx + dy * dy
        u = 0.0 if L2 <= 0 else min(max((px * dx + py * dy) / L2, 0.0), 1.0)
        ex, ey = px - u * dx, py - u * dy
        return ex * ex + ey * ey, u, dx * py - dy * px

    def update(self, x: float, y: float) -> tuple[float, float, int]:
        """(signed cross-track error, arc length, segment index) of the point.

        Walks forward, then backward, from the last match while the distance shrinks, so a
        step costs a few segment tests; the route's continuity keeps it on the right lane.
        """
        a = self._args
        if a is not None:
            a.x, a.y, a.k = x, y, self.k
            status = self._call(self._ref)
            if status:
                raise _native.failed("route_track", status)
            self.k = k = a.k
            return a.cte, a.s, k
        last = len(self._xy) - 2
        k = min(self.k, last)
        lo, hi = 0, last
        if self._legs is not None:
            leg = self._leg_of[k]
            lo, hi = self._legs[leg]
        best = self._seg(k, x, y)
        for step in (1, -1):
            j = k + step
            while lo <= j <= hi:
                cand = self._seg(j, x, y)
                if cand[0] > best[0] + 1e-12:
                    break
                k, best = j, cand
                j += step
        if self._legs is not None and hi < last:
            foot = self._arc[k] + best[1] * (self._arc[k + 1] - self._arc[k])
            if self._arc[hi + 1] - foot <= CUSP_REACH:
                # at the cusp: on to the next leg, from its start (near a cusp the legs
                # overlap, so a search there could land farther along it)
                k = hi + 1
                best = self._seg(k, x, y)
        self.k = k
        d2, u, cross = best
        seg = self._arc[k + 1] - self._arc[k]
        return math.copysign(math.sqrt(d2), cross), self._arc[k] + u * seg, k
