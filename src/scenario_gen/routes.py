"""Reference paths: lane centrelines between adjacent rows and a zigzag with headland U-turns.

Waypoints are at most ``RouteSpec.spacing`` apart and each is tagged ``furrow`` (inside a lane
between crop rows) or ``headland`` (lead-in, turns, lead-out).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .errors import InputError
from .layout import RowFrame
from .spec import RouteSpec
from .terrain import Terrain

FloatArray = NDArray[np.float64]

FURROW, HEADLAND = "furrow", "headland"


@dataclass(frozen=True, eq=False)
class Route:
    xyz: FloatArray  # (n, 3) ENU waypoints
    segment: NDArray[np.str_]  # (n,) "furrow" | "headland"
    lane: NDArray[np.int64]  # (n,) lane index, -1 on headland

    @property
    def xy(self) -> FloatArray:
        return self.xyz[:, :2]

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.xyz[:, :2], axis=0), axis=1).sum())

    def __len__(self) -> int:
        return len(self.xyz)


def lane_lines(rows: RowFrame) -> FloatArray:
    """Centrelines between adjacent rows as (lanes, 2 ends, 2 coords) in ENU, start -> end."""
    if len(rows.offsets) < 2:
        return np.empty((0, 2, 2))
    s = 0.5 * (rows.offsets[:-1] + rows.offsets[1:])
    t0 = np.maximum(rows.starts[:-1], rows.starts[1:])
    t1 = np.minimum(rows.ends[:-1], rows.ends[1:])
    ok = t1 > t0
    x0, y0 = rows.to_enu(t0[ok], s[ok])
    x1, y1 = rows.to_enu(t1[ok], s[ok])
    return np.stack([np.column_stack([x0, y0]), np.column_stack([x1, y1])], axis=1)


def _line(a: tuple[float, float], b: tuple[float, float], step: float) -> FloatArray:
    n = max(2, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1)
    f = np.linspace(0.0, 1.0, n)[:, None]
    return np.asarray(a) * (1 - f) + np.asarray(b) * f


def _arc(t: float, s0: float, s1: float, d: int, step: float) -> FloatArray:
    r = abs(s1 - s0) / 2
    sgn = 1.0 if s1 > s0 else -1.0
    n = max(3, math.ceil(math.pi * r / step) + 1)
    phi = np.linspace(0.0, math.pi, n)
    return np.column_stack([t + d * r * np.sin(phi), 0.5 * (s0 + s1) - sgn * r * np.cos(phi)])


def zigzag(rows: RowFrame, spec: RouteSpec, terrain: Terrain) -> Route:
    """Drive ``spec.lanes`` adjacent lanes in alternating directions with U-turns between."""
    s = 0.5 * (rows.offsets[:-1] + rows.offsets[1:])
    t0 = np.maximum(rows.starts[:-1], rows.starts[1:])
    t1 = np.minimum(rows.ends[:-1], rows.ends[1:])
    n_lanes = len(s)
    if n_lanes < spec.lanes:
        raise InputError(
            "route.lanes",
            spec.lanes,
            f"the field has {n_lanes} lane(s) between its {len(rows.offsets)} rows",
        )
    first = (n_lanes - spec.lanes) // 2 if spec.first_lane is None else spec.first_lane
    if first + spec.lanes > n_lanes:
        raise InputError(
            "route.first_lane",
            first,
            f"allowed: 0..{n_lanes - spec.lanes} for {spec.lanes} lane(s)",
        )
    pieces: list[tuple[FloatArray, str, int]] = []  # (t, s) points, label, lane
    step = spec.spacing
    for k in range(spec.lanes):
        lane = first + k
        d = 1 if k % 2 == 0 else -1
        entry, exit_ = (t0[lane], t1[lane]) if d > 0 else (t1[lane], t0[lane])
        if k == 0:
            pieces.append(
                (_line((entry - d * spec.lead_in, s[lane]), (entry, s[lane]), step), HEADLAND, -1)
            )
        pieces.append((_line((entry, s[lane]), (exit_, s[lane]), step), FURROW, lane))
        if k == spec.lanes - 1:
            pieces.append(
                (_line((exit_, s[lane]), (exit_ + d * spec.lead_in, s[lane]), step), HEADLAND, -1)
            )
            break
        nxt = lane + 1
        nxt_entry = t1[nxt] if d > 0 else t0[nxt]
        turn = d * max(d * exit_, d * nxt_entry) + d * spec.turn_offset
        pieces.append((_line((exit_, s[lane]), (turn, s[lane]), step), HEADLAND, -1))
        pieces.append((_arc(turn, s[lane], s[nxt], d, step), HEADLAND, -1))
        pieces.append((_line((turn, s[nxt]), (nxt_entry, s[nxt]), step), HEADLAND, -1))
    ts_parts, labels, lanes = [], [], []
    for i, (pts, label, lane) in enumerate(pieces):
        pts = pts if i == 0 else pts[1:]  # junctions are shared with the previous piece
        ts_parts.append(pts)
        labels.append(np.full(len(pts), label))
        lanes.append(np.full(len(pts), lane, dtype=np.int64))
    ts = np.concatenate(ts_parts)
    x, y = rows.to_enu(ts[:, 0], ts[:, 1])
    inside = terrain.contains(x, y)
    if not inside.all():
        i = int(np.argmin(inside))
        raise InputError(
            "route",
            f"waypoint at ENU ({x[i]:.1f}, {y[i]:.1f}) m",
            "leaves the terrain; raise terrain.margin or shorten route.lead_in / route.turn_offset",
        )
    z = terrain.height_at(x, y)
    return Route(np.column_stack([x, y, z]), np.concatenate(labels), np.concatenate(lanes))
