"""Reference routes for the tasks and a cheap incremental tracker along them."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Scenario
from scenario_gen.arrays import FloatArray
from scenario_gen.routes import lane_path

TABLE_STEP = 0.02  # m: route lookup table resolution (waypoints are ≤ 0.1 m apart)
#: A reversing route's cusp counts as reached this close along the route (m): a robot stops
#: and reverses within a few centimetres of it.
CUSP_REACH = 0.1


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

    Called twice per env step with a handful of segments, so it is plain Python: for windows
    this small numpy's per-call overhead costs more than the arithmetic.

    A route that reverses (a three-point turn) doubles back on itself at its cusps, where the
    nearest segment may lie on the other leg: the search then stays within the leg it is on
    and moves on to the next leg once the point's foot is within ``CUSP_REACH`` of the cusp.
    """

    def __init__(self, route: RoutePath) -> None:
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
