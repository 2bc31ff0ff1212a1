"""Reference paths: lane centrelines between adjacent rows and a zigzag with headland turns.

A *lane* is the centreline between two adjacent rows, planted where both rows are planted:
one stretch for a simple field, several where holes or the gaps of a MultiPolygon field cut it.
``lane_segments`` lists every stretch with the centreline it belongs to. The zigzag drives each
lane from its first stretch to its last; the stretches are ``furrow`` waypoints, and a crossing
between two stretches is ``headland``, like the lead-in, the turns and the lead-out. On curved
and contour rows the lanes follow the rows' curve. Waypoints are at most ``RouteSpec.spacing``
apart.

Each waypoint also carries ``turn`` (the turn type, ``turns.TURN_TYPES``, on a headland turn;
empty elsewhere) and ``direction`` (+1 when the segment leaving it is driven forwards, −1
backwards: the reversing leg of a ``three_point`` turn).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray, IntArray
from .bounds import MAX_ROUTE_WAYPOINTS
from .errors import InputError
from .layout import RowFrame
from .spec import RouteSpec
from .terrain import Terrain
from .turns import TURN_TYPES, TurnPath, canonical_turn, footprint_corners, footprint_hits

FURROW, HEADLAND = "furrow", "headland"
SEGMENTS = (FURROW, HEADLAND)
TURN_TAGS = ("", *TURN_TYPES)


@dataclass(frozen=True, eq=False)
class Route:
    xyz: FloatArray  # (n, 3) ENU waypoints
    segment: NDArray[np.str_]  # (n,) "furrow" | "headland"
    lane: NDArray[np.int64]  # (n,) lane centreline index, -1 on headland
    turn: NDArray[np.str_] = None  # type: ignore[assignment]  # (n,) turn type or ""
    direction: NDArray[np.int8] = None  # type: ignore[assignment]  # (n,) +1 fwd, -1 reverse

    def __post_init__(self) -> None:
        n = len(self.xyz)
        if self.turn is None:
            object.__setattr__(self, "turn", np.full(n, "", dtype="<U11"))
        if self.direction is None:
            object.__setattr__(self, "direction", np.ones(n, np.int8))
        object.__setattr__(self, "direction", np.asarray(self.direction, np.int8))
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
        if len(self.turn) != len(xyz) or len(self.direction) != len(xyz):
            raise InputError(
                "route",
                (len(xyz), len(self.turn), len(self.direction)),
                "allowed: one turn tag and one direction per waypoint",
            )
        bad = ~np.isin(self.turn, TURN_TAGS)
        if bad.any():
            raise InputError(
                "route.turn", str(self.turn[bad][0]), f"allowed: one of {', '.join(TURN_TYPES)}"
            )
        if not np.isin(self.direction, (-1, 1)).all():
            raise InputError("route.direction", "not +1/-1", "allowed: +1 forward, -1 reverse")
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


#: How close to a lane's end (m along the rows) a row's stretch must come to flank it there.
_END_TOL = 1e-9


def crop_end(rows: RowFrame, flanking: tuple[int, ...], t: float, d: int) -> float:
    """Where the crop beside a lane ends, along the rows in the direction ``d``: the farthest
    end of the planted stretches of the ``flanking`` rows that reach the lane's end ``t``.

    A lane ends where either of its rows does; where row ends are staggered (curved and contour
    rows, a field edge at an angle to the rows) the other row goes on past it, and a turn laid
    from the lane's end would cross that row's last plants."""
    end = t
    for r in flanking:
        seg = rows.segments(r)
        reach = seg[(seg[:, 0] <= t + _END_TOL) & (seg[:, 1] >= t - _END_TOL)]
        if len(reach):
            end = d * max(d * end, float(np.max(d * reach[:, 1 if d > 0 else 0])))
    return end


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
    if rows.curve is None:
        x0, y0 = rows.to_enu(t[:, 0], s)
        x1, y1 = rows.to_enu(t[:, 1], s)
        lines = shapely.linestrings(
            np.stack([np.column_stack([x0, y0]), np.column_stack([x1, y1])], 1)
        )
    else:
        lines = np.array(
            [
                shapely.LineString(centreline(rows, a, b, si, 0.5))
                for (a, b), si in zip(t, s, strict=True)
            ]
        )
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


def centreline(rows: RowFrame, t0: float, t1: float, s: float, step: float) -> FloatArray:
    """(n, 2) ENU points of the line at offset ``s`` from ``t0`` to ``t1``, at most ``step``
    metres apart (a curve on curved and contour rows)."""
    n = max(2, math.ceil(abs(t1 - t0) * rows.stretch(t0, t1, s) / step) + 1)
    t = np.linspace(t0, t1, n)
    return np.column_stack(rows.to_enu(t, np.full(n, s)))


def lane_path(
    rows: RowFrame, field: BaseGeometry | None, stretch: int, spacing: float, lead: float = 0.0
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Planted lane stretch ``stretch`` (an index into ``lane_segments``) as (n, 2) ENU points
    at most ``spacing`` apart, with ``lead`` metres of headland before it, and each point's
    furrow flag."""
    lane, t = lane_segments(rows, field)
    k = int(lane[stretch])
    s = 0.5 * (rows.offsets[k] + rows.offsets[k + 1])
    t0, t1 = float(t[stretch, 0]), float(t[stretch, 1])
    start = _along(rows, t0, s, -lead)  # lead metres along the lane
    n = max(2, math.ceil(abs(t1 - start) * rows.stretch(start, t1, s) / spacing) + 1)
    tt = np.linspace(start, t1, n)
    return np.column_stack(rows.to_enu(tt, np.full(n, s))), tt >= t0 - 1e-9


# A route piece before it is sampled: ("line", (t0, s0), (t1, s1)) or ("arc", t, s0, s1, d) in
# the rows' coordinates, or ("turn", t, s, d, TurnPath) laid at (t, s) in the direction d; with
# its label, lane and turn tag. Counted first, so a route too long for memory is refused unmade.
Piece = tuple[tuple, str, int, str]


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


def _count(shape: tuple, step: float, rows: RowFrame) -> int:
    if shape[0] == "line":
        (t0, s0), (t1, _) = shape[1], shape[2]
        if rows.curve is None:
            return _line_n(shape[1], shape[2], step)
        return _line_n((t0, 0.0), (t0 + (t1 - t0) * rows.stretch(t0, t1, s0), 0.0), step)
    if shape[0] == "turn":
        return len(shape[4])
    return _arc_n(shape[2], shape[3], step)


def _to_enu(shape: tuple, step: float, rows: RowFrame) -> tuple[FloatArray, FloatArray]:
    """ENU points of a piece, and the robot's facing direction at each (turns only; NaN)."""
    if shape[0] == "turn":
        _, t, s, d, tp = shape
        x, y = rows.local_to_enu(t, s, tp.xy[:, 0], tp.xy[:, 1], d)
        (h,) = rows.heading(np.array([t]))
        yaw = h + tp.yaw if d > 0 else math.pi + h - tp.yaw
        return np.column_stack([x, y]), yaw
    if shape[0] == "line" and rows.curve is not None:
        (t0, s0), (t1, _) = shape[1], shape[2]
        n = _count(shape, step, rows)
        ts = np.column_stack([np.linspace(t0, t1, n), np.full(n, s0)])
    else:
        ts = _sample(shape, step)
    x, y = rows.to_enu(ts[:, 0], ts[:, 1])
    return np.column_stack([x, y]), np.full(len(ts), np.nan)


def zigzag(
    rows: RowFrame,
    spec: RouteSpec,
    terrain: Terrain,
    field: BaseGeometry | None = None,
    crops: FloatArray | None = None,
) -> Route:
    """Drive ``spec.lanes`` adjacent lanes in alternating directions with turns between.

    Every turn starts past the crop beside both lanes (``crop_end``). ``crops`` (n, 2) are the
    crop plants the turns other than the semicircle must clear: such a turn starts
    ``spec.turn_offset`` past the crop, or farther until the footprint swept along it keeps
    ``spec.turn_clearance`` from every plant, and must stay inside ``field``."""
    lane_of, spans = lane_segments(rows, field)
    drivable = np.unique(lane_of)
    n_lanes = len(drivable)
    if n_lanes == 0 and len(rows.offsets) < 2:
        # no lane at all: the field, not the lane count, is what to change
        raise InputError(
            "field",
            f"{len(rows.offsets)} crop row(s) at layout.row_spacing {rows.spacing:g} m",
            "a lane needs a crop row on each side along its length; allowed: a field at least "
            "two rows wide across them (a wider field, narrower row spacing, or "
            "layout.row_angle_deg along its long side)",
        )
    if n_lanes == 0:
        raise InputError(
            "layout",
            f"{len(rows.offsets)} crop rows with no stretch planted on both sides of a lane",
            "a lane needs crop on each side along its length; allowed: rows planted along "
            "each other (layout.plant_spacing well below the rows' length, gaps and "
            "missing plants that leave crop on both sides)",
        )
    if n_lanes < spec.lanes:
        raise InputError(
            "route.lanes",
            spec.lanes,
            f"the field has {n_lanes} lane(s) with crop on both sides between its "
            f"{len(rows.offsets)} rows; allowed: at most {n_lanes} (or a wider field)",
        )
    first = (n_lanes - spec.lanes) // 2 if spec.first_lane is None else spec.first_lane
    if first + spec.lanes > n_lanes:
        raise InputError(
            "route.first_lane",
            first,
            f"allowed: 0..{n_lanes - spec.lanes} for {spec.lanes} lane(s)",
        )
    fitted = _TurnFitter(rows, spec, field, crops)
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
            lead = _along(rows, entry, s, -d * spec.lead_in)
            pieces.append((("line", (lead, s), (entry, s)), HEADLAND, -1, ""))
        for i, (a, b) in enumerate(stretches):
            if i > 0:  # across a hole or a gap between the field's parts
                pieces.append((("line", (float(stretches[i - 1, 1]), s), (a, s)), HEADLAND, -1, ""))
            pieces.append((("line", (float(a), s), (float(b), s)), FURROW, lane, ""))
        if k == spec.lanes - 1:
            lead = _along(rows, exit_, s, d * spec.lead_in)
            pieces.append((("line", (exit_, s), (lead, s)), HEADLAND, -1, ""))
            break
        nxt = int(drivable[first + k + 1])
        s_next = 0.5 * (offsets[nxt] + offsets[nxt + 1])
        nxt_own = spans[lane_of == nxt]
        nxt_entry = float(nxt_own[-1, 1] if d > 0 else nxt_own[0, 0])
        far = crop_end(rows, (lane, lane + 1), exit_, d)
        far = d * max(d * far, d * crop_end(rows, (nxt, nxt + 1), nxt_entry, d))
        if spec.turn == "semicircle" and rows.curve is None:
            turn = far + d * spec.turn_offset
            shape: tuple = ("arc", turn, s, s_next, d)
        else:
            turn, shape = fitted.turn(far, s, s_next, d)
        pieces.append((("line", (exit_, s), (turn, s)), HEADLAND, -1, ""))
        pieces.append((shape, HEADLAND, -1, spec.turn))
        pieces.append((("line", (turn, s_next), (nxt_entry, s_next)), HEADLAND, -1, ""))
    total = sum(_count(p[0], spec.spacing, rows) for p in pieces) - (len(pieces) - 1)
    if total > MAX_ROUTE_WAYPOINTS:
        raise InputError(
            "route.lanes/spacing",
            (spec.lanes, spec.spacing),
            f"make {total:,} waypoints; allowed: at most {MAX_ROUTE_WAYPOINTS:,} (fewer lanes "
            "or a coarser route.spacing)",
        )
    parts: list[FloatArray] = []
    labels: list[NDArray[np.str_]] = []
    lanes: list[NDArray[np.int64]] = []
    tags: list[NDArray[np.str_]] = []
    dirs: list[NDArray[np.int8]] = []
    for i, (shape, label, lane, tag) in enumerate(pieces):
        pts, _ = _to_enu(shape, spec.spacing, rows)
        direction = shape[4].direction if shape[0] == "turn" else np.ones(len(pts), np.int8)
        if i > 0:  # junctions are shared with the previous piece
            pts, direction = pts[1:], direction[1:]
            tags[-1][-1] = tag or tags[-1][-1]
        parts.append(pts)
        labels.append(np.full(len(pts), label))
        lanes.append(np.full(len(pts), lane, dtype=np.int64))
        tags.append(np.full(len(pts), tag, dtype="<U11"))
        dirs.append(np.asarray(direction, np.int8))
    xy = np.concatenate(parts)
    x, y = xy[:, 0], xy[:, 1]
    inside = terrain.contains(x, y)
    if not inside.all():
        i = int(np.argmin(inside))
        raise InputError(
            "route",
            f"waypoint at ENU ({x[i]:.1f}, {y[i]:.1f}) m",
            "leaves the terrain; raise terrain.margin or shorten route.lead_in / route.turn_offset",
        )
    z = terrain.height_at(x, y)
    return Route(
        np.column_stack([x, y, z]),
        np.concatenate(labels),
        np.concatenate(lanes),
        np.concatenate(tags),
        np.concatenate(dirs),
    )


def _along(rows: RowFrame, t: float, s: float, metres: float) -> float:
    """Reference ``t`` ``metres`` along the row line at offset ``s`` from ``t``."""
    if rows.curve is None:
        return t + metres
    c = rows.curve
    return float(c.t_of_arc(c.row_arc(np.array([t]), s) + metres, s)[0])


#: How far a turn that touches the crop is moved out per try, and at most, metres.
_PUSH_STEP = 0.05
_PUSH_MAX = 20.0


class _TurnFitter:
    """Turns sized to the robot: laid ``turn_offset`` past the crop, then moved out until
    the footprint swept along them clears every crop plant, and checked to fit the field."""

    def __init__(
        self,
        rows: RowFrame,
        spec: RouteSpec,
        field: BaseGeometry | None,
        crops: FloatArray | None,
    ) -> None:
        self.rows, self.spec, self.field = rows, spec, field
        self.crops = np.empty((0, 2)) if crops is None else np.asarray(crops, np.float64)
        self._cache: dict[float, TurnPath] = {}

    @cached_property
    def tree(self) -> cKDTree | None:
        return cKDTree(self.crops) if len(self.crops) else None

    def _path(self, w: float) -> TurnPath:
        key = round(w, 9)
        if key not in self._cache:
            self._cache[key] = canonical_turn(
                self.spec.turn, w, self.spec.turn_radius, self.spec.spacing
            )
        return self._cache[key]

    def turn(self, far: float, s: float, s_next: float, d: int) -> tuple[float, tuple]:
        """(turn point t, piece) for the turn from lane ``s`` to ``s_next``, the crop ending
        at ``far`` along the direction ``d``."""
        spec, rows = self.spec, self.rows
        tp = self._path(s_next - s)
        if spec.turn == "semicircle":
            return self._place(far, spec.turn_offset, s, d, tp)
        length, width = spec.footprint
        offset = max(spec.turn_offset, 0.5 * length + spec.turn_clearance)
        while True:
            t, shape = self._place(far, offset, s, d, tp)
            pts, yaw = _to_enu(shape, spec.spacing, rows)
            if self.tree is None or not len(
                footprint_hits(pts, yaw, length, width, spec.turn_clearance, self.crops, self.tree)
            ):
                break
            offset += _PUSH_STEP
            if offset > spec.turn_offset + _PUSH_MAX:  # pragma: no cover - a crop in the way
                raise InputError(
                    "route.turn",
                    spec.turn,
                    f"finds no place within {_PUSH_MAX:g} m past the crop where the robot's "
                    "swept footprint clears the plants; allowed: a larger layout.headland",
                )
        if self.field is not None:
            corners = footprint_corners(pts, yaw, length, width).reshape(-1, 2)
            out = ~shapely.contains_xy(self.field, corners[:, 0], corners[:, 1])
            if out.any():
                depth = offset + float(np.max(tp.xy[:, 0])) + 0.5 * math.hypot(length, width)
                raise InputError(
                    "route.turn",
                    spec.turn,
                    f"the {spec.turn} turn of radius {spec.turn_radius:g} m for a "
                    f"{length:g} x {width:g} m footprint starts {offset:.2f} m past the crop "
                    f"and needs about {depth:.1f} m of headland beyond it; it leaves the field "
                    f"at ENU ({corners[out][0, 0]:.1f}, {corners[out][0, 1]:.1f}) m; allowed: "
                    "a larger layout.headland, a smaller route.turn_radius or turn_offset",
                )
        return t, shape

    def _place(
        self, far: float, offset: float, s: float, d: int, tp: TurnPath
    ) -> tuple[float, tuple]:
        t = _along(self.rows, far, s, d * offset)
        return t, ("turn", t, s, d, tp)
