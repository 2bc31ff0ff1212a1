"""Reference paths: lane centrelines between adjacent rows and a zigzag with headland U-turns.

A *lane* is the centreline between two adjacent rows, planted where both rows are planted:
one stretch for a simple field, several where holes or the gaps of a MultiPolygon field cut it.
``lane_segments`` lists every stretch with the centreline it belongs to. The zigzag drives each
lane from its first stretch to its last; the stretches are ``furrow`` waypoints, and a crossing
between two stretches is ``headland``, like the lead-in, the U-turns and the lead-out.
Waypoints are at most ``RouteSpec.spacing`` apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray, IntArray
from .bounds import MAX_ROUTE_WAYPOINTS
from .errors import InputError
from .layout import RowFrame
from .spec import RouteSpec
from .terrain import Terrain

FURROW, HEADLAND = "furrow", "headland"
SEGMENTS = (FURROW, HEADLAND)


@dataclass(frozen=True, eq=False)
class Route:
    xyz: FloatArray  # (n, 3) ENU waypoints
    segment: NDArray[np.str_]  # (n,) "furrow" | "headland"
    lane: NDArray[np.int64]  # (n,) lane centreline index, -1 on headland

    def __post_init__(self) -> None:
        xyz = np.asarray(self.xyz, dtype=np.float64)
        if xyz.ndim != 2 or xyz.shape[1] != 3 or len(xyz) < 2:
            raise InputError(
                "route", f"{xyz.shape} waypoints", "allowed: at least 2 waypoints of (x, y, z)"
            )
        if not np.isfinite(xyz).all():
            raise InputError("route", "NaN or inf", "allowed: finite waypoint coordinates")
        if len(self.segment) != len(xyz) or len(self.lane) != len(xyz):
            raise InputError(
                "route",
                (len(xyz), len(self.segment), len(self.lane)),
                "allowed: one segment tag and one lane index per waypoint",
            )
        bad = ~np.isin(self.segment, SEGMENTS)
        if bad.any():
            raise InputError(
                "route.segment", str(self.segment[bad][0]), f"allowed: one of {', '.join(SEGMENTS)}"
            )
        object.__setattr__(self, "xyz", xyz)

    @property
    def xy(self) -> FloatArray:
        return self.xyz[:, :2]

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.xyz[:, :2], axis=0), axis=1).sum())

    def __len__(self) -> int:
        return len(self.xyz)


def _intersect(a: FloatArray, b: FloatArray) -> list[tuple[float, float]]:
    """Intersections of two sorted lists of disjoint intervals (t0, t1) with t1 > t0."""
    out: list[tuple[float, float]] = []
    i = j = 0
    while i < len(a) and j < len(b):
        lo, hi = max(a[i, 0], b[j, 0]), min(a[i, 1], b[j, 1])
        if hi > lo:
            out.append((float(lo), float(hi)))
        if a[i, 1] < b[j, 1]:
            i += 1
        else:
            j += 1
    return out


def lane_segments(rows: RowFrame, field: BaseGeometry | None = None) -> tuple[IntArray, FloatArray]:
    """Every planted stretch of every lane: (centreline index, (t0, t1) along the rows).

    Centreline k lies between rows k and k+1 when they are one row spacing apart (a MultiPolygon
    gap between them leaves no lane). Its stretches are where both rows are planted and, given
    the ``field``, where the centreline itself lies in it (a hole narrower than a row spacing).
    """
    n = len(rows.offsets)
    lane_of: list[int] = []
    spans: list[tuple[float, float]] = []
    for k in range(n - 1):
        if rows.offsets[k + 1] - rows.offsets[k] > 1.5 * rows.spacing:
            continue
        for span in _intersect(rows.segments(k), rows.segments(k + 1)):
            lane_of.append(k)
            spans.append(span)
    lane = np.asarray(lane_of, dtype=np.int64)
    t = np.asarray(spans, dtype=np.float64).reshape(-1, 2)
    if field is None or len(t) == 0:
        return lane, t
    s = 0.5 * (rows.offsets[lane] + rows.offsets[lane + 1])
    x0, y0 = rows.to_enu(t[:, 0], s)
    x1, y1 = rows.to_enu(t[:, 1], s)
    lines = shapely.linestrings(np.stack([np.column_stack([x0, y0]), np.column_stack([x1, y1])], 1))
    inside = shapely.contains(field, lines)
    if inside.all():
        return lane, t
    out_lane: list[int] = []
    out_t: list[tuple[float, float]] = []
    for i in range(len(t)):
        if inside[i]:
            out_lane.append(int(lane[i]))
            out_t.append((float(t[i, 0]), float(t[i, 1])))
            continue
        for part in shapely.get_parts(shapely.intersection(lines[i], field)):
            if part.geom_type != "LineString" or part.length <= 0:
                continue
            xy = shapely.get_coordinates(part)
            tt, _ = rows.to_rows(xy[:, 0], xy[:, 1])
            out_lane.append(int(lane[i]))
            out_t.append((float(tt.min()), float(tt.max())))
    order = np.lexsort((np.asarray([a for a, _ in out_t]), np.asarray(out_lane)))
    return (
        np.asarray(out_lane, dtype=np.int64)[order],
        np.asarray(out_t, dtype=np.float64).reshape(-1, 2)[order],
    )


def lane_lines(rows: RowFrame, field: BaseGeometry | None = None) -> FloatArray:
    """Every planted lane stretch as (stretches, 2 ends, 2 coords) in ENU, start -> end."""
    lane, t = lane_segments(rows, field)
    if len(lane) == 0:
        return np.empty((0, 2, 2))
    s = 0.5 * (rows.offsets[lane] + rows.offsets[lane + 1])
    x0, y0 = rows.to_enu(t[:, 0], s)
    x1, y1 = rows.to_enu(t[:, 1], s)
    return np.stack([np.column_stack([x0, y0]), np.column_stack([x1, y1])], axis=1)


# A route piece before it is sampled: ("line", (t0, s0), (t1, s1)) or ("arc", t, s0, s1, d),
# with its label and lane; counted first, so a route too long for memory is refused unmade.
Piece = tuple[tuple, str, int]


def _line_n(a: tuple[float, float], b: tuple[float, float], step: float) -> int:
    return max(2, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1)


def _arc_n(s0: float, s1: float, step: float) -> int:
    return max(3, math.ceil(math.pi * abs(s1 - s0) / 2 / step) + 1)


def _sample(shape: tuple, step: float) -> FloatArray:
    if shape[0] == "line":
        a, b = shape[1], shape[2]
        f = np.linspace(0.0, 1.0, _line_n(a, b, step))[:, None]
        return np.asarray(a) * (1 - f) + np.asarray(b) * f
    _, t, s0, s1, d = shape
    r = abs(s1 - s0) / 2
    sgn = 1.0 if s1 > s0 else -1.0
    phi = np.linspace(0.0, math.pi, _arc_n(s0, s1, step))
    return np.column_stack([t + d * r * np.sin(phi), 0.5 * (s0 + s1) - sgn * r * np.cos(phi)])


def _count(shape: tuple, step: float) -> int:
    if shape[0] == "line":
        return _line_n(shape[1], shape[2], step)
    return _arc_n(shape[2], shape[3], step)


def zigzag(
    rows: RowFrame, spec: RouteSpec, terrain: Terrain, field: BaseGeometry | None = None
) -> Route:
    """Drive ``spec.lanes`` adjacent lanes in alternating directions with U-turns between."""
    lane_of, spans = lane_segments(rows, field)
    drivable = np.unique(lane_of)
    n_lanes = len(drivable)
    if n_lanes < spec.lanes:
        raise InputError(
            "route.lanes",
            spec.lanes,
            f"the field has {n_lanes} lane(s) with crop on both sides between its "
            f"{len(rows.offsets)} rows",
        )
    first = (n_lanes - spec.lanes) // 2 if spec.first_lane is None else spec.first_lane
    if first + spec.lanes > n_lanes:
        raise InputError(
            "route.first_lane",
            first,
            f"allowed: 0..{n_lanes - spec.lanes} for {spec.lanes} lane(s)",
        )
    offsets = rows.offsets
    pieces: list[Piece] = []
    for k in range(spec.lanes):
        lane = int(drivable[first + k])
        s = 0.5 * (offsets[lane] + offsets[lane + 1])
        d = 1 if k % 2 == 0 else -1
        own = spans[lane_of == lane]
        stretches = own if d > 0 else own[::-1, ::-1]
        entry, exit_ = float(stretches[0, 0]), float(stretches[-1, 1])
        if k == 0:
            pieces.append((("line", (entry - d * spec.lead_in, s), (entry, s)), HEADLAND, -1))
        for i, (a, b) in enumerate(stretches):
            if i > 0:  # across a hole or a gap between the field's parts
                pieces.append((("line", (float(stretches[i - 1, 1]), s), (a, s)), HEADLAND, -1))
            pieces.append((("line", (float(a), s), (float(b), s)), FURROW, lane))
        if k == spec.lanes - 1:
            pieces.append((("line", (exit_, s), (exit_ + d * spec.lead_in, s)), HEADLAND, -1))
            break
        nxt = int(drivable[first + k + 1])
        s_next = 0.5 * (offsets[nxt] + offsets[nxt + 1])
        nxt_own = spans[lane_of == nxt]
        nxt_entry = float(nxt_own[-1, 1] if d > 0 else nxt_own[0, 0])
        turn = d * max(d * exit_, d * nxt_entry) + d * spec.turn_offset
        pieces.append((("line", (exit_, s), (turn, s)), HEADLAND, -1))
        pieces.append((("arc", turn, s, s_next, d), HEADLAND, -1))
        pieces.append((("line", (turn, s_next), (nxt_entry, s_next)), HEADLAND, -1))
    total = sum(_count(p[0], spec.spacing) for p in pieces) - (len(pieces) - 1)
    if total > MAX_ROUTE_WAYPOINTS:
        raise InputError(
            "route.lanes/spacing",
            (spec.lanes, spec.spacing),
            f"make {total:,} waypoints; allowed: at most {MAX_ROUTE_WAYPOINTS:,} (fewer lanes "
            "or a coarser route.spacing)",
        )
    ts_parts, labels, lanes = [], [], []
    for i, (shape, label, lane) in enumerate(pieces):
        pts = _sample(shape, spec.spacing)
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
