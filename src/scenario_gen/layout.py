"""Crop layout, fully vectorized (design.md, "The scenario pipeline").

Straight rows: candidates sit on a grid rotated by the row angle; rows are centred on the
planting area so a rectangle is planted symmetrically. A candidate is kept when it, and the
points one headland width before and after it along the row, lie inside the field shrunk by the
edge margin — the headland test is one containment call against the intersection of the shifted
polygons.

Curved and contour rows (``rowcurve``): the same in the (t, s) coordinates of the reference
curve: rows at offsets ``s`` one row spacing apart along the normal, plants at the plant
spacing along each row's own arc length, the headland measured along each row; the planting
area is built in (t, s) and mapped back to ENU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely import affinity
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray, IntArray
from .bounds import MAX_CANDIDATES
from .errors import InputError
from .rowcurve import RowCurve
from .spec import LayoutSpec


@dataclass(frozen=True)
class RowFrame:
    """Row geometry: ENU point ``origin``, along-row unit ``u`` and across-row unit ``n``.

    A row is planted over one or more *segments*: runs of consecutive nominal planting
    positions, split where a hole or a gap between the parts of a MultiPolygon field interrupts
    it. ``seg_row[k]`` is the row of segment k and ``seg_t[k]`` its along-row extent; segments
    are sorted by row, then along the row. A simple field has one segment per row, equal to
    ``(starts, ends)``.
    """

    angle: float  # rad, row direction counter-clockwise from east
    origin: tuple[float, float]
    offsets: FloatArray  # lateral offset of each planted row along n, ascending
    starts: FloatArray  # along-row extent of each row's nominal planting positions
    ends: FloatArray
    spacing: float
    seg_row: IntArray | None = None
    seg_t: FloatArray | None = None  # (segments, 2): along-row start, end
    #: the reference curve of curved or contour rows (``t`` its arc length, ``s`` the offset
    #: along its normal); None: straight rows along ``u``
    curve: RowCurve | None = None

    def __post_init__(self) -> None:
        if self.seg_row is None or self.seg_t is None:
            object.__setattr__(self, "seg_row", np.arange(len(self.offsets), dtype=np.int64))
            object.__setattr__(
                self, "seg_t", np.column_stack([self.starts, self.ends]).reshape(-1, 2)
            )

    def segments(self, row: int) -> FloatArray:
        """Planted (start, end) intervals of ``row`` along the row, ascending."""
        assert self.seg_row is not None and self.seg_t is not None
        return self.seg_t[self.seg_row == row]

    @property
    def u(self) -> FloatArray:
        return np.array([math.cos(self.angle), math.sin(self.angle)])

    @property
    def n(self) -> FloatArray:
        return np.array([-math.sin(self.angle), math.cos(self.angle)])

    @property
    def geometry(self) -> str:
        """straight, curved or contour (``layout.row_geometry``)."""
        return "straight" if self.curve is None else self.curve.kind

    def to_enu(self, t: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
        if self.curve is not None:
            return self.curve.to_enu(t, s)
        ox, oy = self.origin
        u, n = self.u, self.n
        return ox + t * u[0] + s * n[0], oy + t * u[1] + s * n[1]

    def to_rows(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        if self.curve is not None:
            return self.curve.to_rows(np.asarray(x), np.asarray(y))
        dx, dy = np.asarray(x) - self.origin[0], np.asarray(y) - self.origin[1]
        u, n = self.u, self.n
        return dx * u[0] + dy * u[1], dx * n[0] + dy * n[1]

    def heading(self, t: FloatArray) -> FloatArray:
        """Row direction (rad, counter-clockwise from east) at reference ``t``."""
        if self.curve is not None:
            return self.curve.heading(t)
        return np.full(np.shape(t), self.angle)

    def direction_at(self, x: FloatArray, y: FloatArray) -> FloatArray | float:
        """Row direction at ENU points (the frame's angle for straight rows)."""
        if self.curve is None:
            return self.angle
        t, _ = self.curve.to_rows(np.asarray(x), np.asarray(y))
        return self.curve.heading(t)

    def local_to_enu(
        self, t0: float, s0: float, x: FloatArray, y: FloatArray, d: int
    ) -> tuple[FloatArray, FloatArray]:
        """Points given in the Cartesian frame at (t0, s0) — ``x`` along ``d`` times the row
        direction there, ``y`` along the normal — in ENU: how turns are laid on any rows."""
        (ox,), (oy,) = self.to_enu(np.array([t0]), np.array([s0]))
        (h,) = self.heading(np.array([t0]))
        c, sn = math.cos(h), math.sin(h)
        return ox + d * x * c - y * sn, oy + d * x * sn + y * c

    def stretch(self, t0: float, t1: float, s: float) -> float:
        """Largest ratio of the row's length at offset ``s`` to ``t`` over [t0, t1]."""
        return 1.0 if self.curve is None else self.curve.stretch(t0, t1, s)

    def row_length(self, t0: float, t1: float, s: float) -> float:
        """Length of the row at offset ``s`` between reference ``t0`` and ``t1``, metres."""
        if self.curve is None:
            return float(t1 - t0)
        a = self.curve.row_arc(np.array([t0, t1]), s)
        return float(a[1] - a[0])


@dataclass(frozen=True)
class Layout:
    x: FloatArray
    y: FloatArray
    row: IntArray  # row index into RowFrame.offsets; -1 for weeds
    is_weed: NDArray[np.bool_]
    rows: RowFrame
    planting_area: BaseGeometry
    candidates: int  # nominal grid positions before gaps


def planting_area(field: BaseGeometry, spec: LayoutSpec, angle: float) -> BaseGeometry:
    inner = field.buffer(-spec.edge_margin, join_style="mitre") if spec.edge_margin > 0 else field
    if spec.headland > 0 and not inner.is_empty:
        dx, dy = spec.headland * math.cos(angle), spec.headland * math.sin(angle)
        inner = shapely.intersection_all(
            [inner, affinity.translate(inner, dx, dy), affinity.translate(inner, -dx, -dy)]
        )
    return inner


def _centred(lo: float, hi: float, step: float) -> FloatArray:
    mid = 0.5 * (lo + hi)
    k0, k1 = math.ceil((lo - mid) / step - 1e-9), math.floor((hi - mid) / step + 1e-9)
    return mid + step * np.arange(k0, k1 + 1, dtype=np.float64)


#: Counted positions stay this far inside the planting area, so that the outermost ones of a
#: rectangle are not lost to rounding on its boundary.
_INSET = 1e-6


def _counted(lo: float, hi: float, step: float, n: int, field: str, what: str) -> FloatArray:
    """``n`` positions ``step`` apart centred on [lo, hi], or an error if they do not fit."""
    need = (n - 1) * step
    room = hi - lo - 2 * _INSET
    if need > room:
        fit = max(0, math.floor(room / step + 1e-9)) + 1 if room >= 0 else 0
        raise InputError(
            field,
            n,
            f"{n} {what} {step:g} m apart need {need:.2f} m; the planting area (field less "
            f"layout.edge_margin and layout.headland) spans {hi - lo:.2f} m; allowed: at most "
            f"{fit}, or a larger field",
        )
    mid = 0.5 * (lo + hi)
    return mid + step * (np.arange(n, dtype=np.float64) - (n - 1) / 2)


def layout(
    field: BaseGeometry,
    spec: LayoutSpec,
    angle: float,
    rng_jitter: np.random.Generator,
    rng_gaps: np.random.Generator,
    rng_weeds: np.random.Generator,
    curve: RowCurve | None = None,
) -> Layout:
    """Plants and weeds of ``field``: straight rows at ``angle``, or parallel to ``curve``."""
    if curve is not None:
        return _layout_curved(field, spec, curve, rng_jitter, rng_gaps, rng_weeds)
    area = planting_area(field, spec, angle)
    _check_area(area, spec)
    c = area.centroid
    frame0 = RowFrame(angle, (c.x, c.y), np.empty(0), np.empty(0), np.empty(0), spec.row_spacing)
    ex = np.asarray(
        area.exterior.coords if area.geom_type == "Polygon" else shapely.get_coordinates(area)
    )
    t_b, s_b = frame0.to_rows(ex[:, 0], ex[:, 1])
    s_lo, s_hi, t_lo, t_hi = float(s_b.min()), float(s_b.max()), float(t_b.min()), float(t_b.max())
    s_rows = _row_offsets(s_lo, s_hi, spec)
    t_pos = (
        _centred(t_lo, t_hi, spec.plant_spacing)
        if spec.plants_per_row is None
        else _counted(
            t_lo, t_hi, spec.plant_spacing, spec.plants_per_row, "layout.plants_per_row", "plants"
        )
    )
    _check_candidates(len(s_rows) * len(t_pos), spec)
    S, T = np.meshgrid(s_rows, t_pos, indexing="ij")  # rows contiguous, along-row ascending
    s_all, t_all = S.ravel(), T.ravel()
    x0, y0 = frame0.to_enu(t_all, s_all)
    keep = shapely.contains_xy(area, x0, y0)
    row_of = np.repeat(np.arange(len(s_rows)), len(t_pos))[keep]
    pos_of = np.tile(np.arange(len(t_pos)), len(s_rows))[keep]
    return _plant(
        field,
        spec,
        area,
        frame0,
        s_rows,
        row_of,
        pos_of,
        s_all[keep],
        t_all[keep],
        (rng_jitter, rng_gaps, rng_weeds),
    )


def _check_area(area: BaseGeometry, spec: LayoutSpec) -> None:
    if area.is_empty or area.area <= 0:
        raise InputError(
            "layout.headland/edge_margin",
            (spec.headland, spec.edge_margin),
            "leave no planting area inside the field; allowed: smaller margins or a larger field",
        )


def _row_offsets(s_lo: float, s_hi: float, spec: LayoutSpec) -> FloatArray:
    return (
        _centred(s_lo, s_hi, spec.row_spacing)
        if spec.rows is None
        else _counted(s_lo, s_hi, spec.row_spacing, spec.rows, "layout.rows", "rows")
    )


def _check_candidates(count: int, spec: LayoutSpec) -> None:
    if count > MAX_CANDIDATES:
        raise InputError(
            "layout.plant_spacing/row_spacing",
            (spec.plant_spacing, spec.row_spacing),
            f"gives {count:,} candidate positions over the field's bounding "
            f"box; allowed: at most {MAX_CANDIDATES:,} (coarser spacing or a smaller field)",
        )


def _plant(
    field: BaseGeometry,
    spec: LayoutSpec,
    area: BaseGeometry,
    frame0: RowFrame,
    s_rows: FloatArray,
    row_of: IntArray,
    pos_of: IntArray,
    s_k: FloatArray,
    t_k: FloatArray,
    rngs: tuple[np.random.Generator, np.random.Generator, np.random.Generator],
) -> Layout:
    """The rows, plants and weeds from the kept candidates (row ``row_of``, nominal position
    ``pos_of`` along it, at ``(t_k, s_k)``), with gaps, jitter and weeds drawn."""
    rng_jitter, rng_gaps, rng_weeds = rngs
    if len(s_k) == 0:
        raise InputError(
            "field",
            f"{field.area:.1f} m²",
            "is too small for one plant at this row spacing, plant spacing and margins",
        )
    used, row_idx = np.unique(row_of, return_inverse=True)
    if spec.rows is not None and len(used) < spec.rows:
        missed = sorted(set(range(spec.rows)) - set(used.tolist()))
        raise InputError(
            "layout.rows",
            spec.rows,
            f"row {missed[0]} (of {spec.rows}, centred) misses the planting area of this "
            "field shape; allowed: fewer rows",
        )
    n_rows = len(used)
    starts = np.full(n_rows, np.inf)
    ends = np.full(n_rows, -np.inf)
    np.minimum.at(starts, row_idx, t_k)
    np.maximum.at(ends, row_idx, t_k)
    # A segment breaks where the row changes or a nominal position is skipped (hole, gap).
    brk = np.flatnonzero((np.diff(row_of) != 0) | (np.diff(pos_of) != 1)) + 1
    first = np.concatenate([[0], brk])
    last = np.concatenate([brk - 1, [len(t_k) - 1]])
    rows = RowFrame(
        frame0.angle,
        frame0.origin,
        s_rows[used],
        starts,
        ends,
        spec.row_spacing,
        row_idx[first].astype(np.int64),
        np.column_stack([t_k[first], t_k[last]]),
        frame0.curve,
    )

    missing = _gaps(row_idx, spec, rng_gaps)
    n = len(s_k)
    dl = _clipped_normal(rng_jitter, spec.jitter_lateral, n)
    dt = _clipped_normal(rng_jitter, spec.jitter_longitudinal, n)
    if rows.curve is None:
        px, py = rows.to_enu(t_k + dt, s_k + dl)
    else:  # dt is along the row: its own length per reference metre is 1 - s·κ
        k = np.clip(np.searchsorted(rows.curve.t, t_k, side="right") - 1, 0, len(rows.curve.t) - 2)
        px, py = rows.to_enu(t_k + dt / (1.0 - s_k * rows.curve.kappa[k]), s_k + dl)
    ok = ~missing & shapely.contains_xy(field, px, py)
    if n and missing.all():  # rows and lanes would stand on a field with no crop in it
        raise InputError(
            "layout.gap_prob" if spec.gap_prob >= 1.0 else "layout.gap_run_prob",
            spec.gap_prob if spec.gap_prob >= 1.0 else spec.gap_run_prob,
            f"leaves every one of the {n:,} plants out: a field with no crop; allowed: gaps "
            "that leave plants (gap_prob below 1, fewer or shorter runs)",
        )
    wx, wy = _weeds(area, spec.weed_density, rng_weeds)
    x = np.concatenate([px[ok], wx])
    y = np.concatenate([py[ok], wy])
    row = np.concatenate([row_idx[ok].astype(np.int64), np.full(len(wx), -1, np.int64)])
    weed = np.concatenate([np.zeros(int(ok.sum()), bool), np.ones(len(wx), bool)])
    return Layout(x, y, row, weed, rows, area, n)


# ----------------------------------------------------------------------------- curved rows
#: Boundary vertices are put this close (metres) before a polygon is mapped between ENU and the
#: rows' (t, s) coordinates, so its curved image is followed to well under a millimetre.
_SEGMENTIZE_M = 0.5


def _map_poly(geom: BaseGeometry, fn: object) -> BaseGeometry:
    dense = shapely.segmentize(geom, _SEGMENTIZE_M)
    out = shapely.transform(dense, lambda xy: np.column_stack(fn(xy[:, 0], xy[:, 1])))  # type: ignore[operator]
    return out if out.is_valid else shapely.make_valid(out)


def curved_planting_area(
    field: BaseGeometry, spec: LayoutSpec, curve: RowCurve
) -> tuple[BaseGeometry, BaseGeometry]:
    """The planting area in ENU and in the (t, s) coordinates of ``curve``: the field less the
    edge margin, less ``headland`` metres at both ends of every row, measured along the row."""
    inner = field.buffer(-spec.edge_margin, join_style="mitre") if spec.edge_margin > 0 else field
    if inner.is_empty:
        return inner, inner
    q = _map_poly(inner, curve.to_rows)
    if spec.headland > 0:
        h = spec.headland

        def shift(sign: float) -> BaseGeometry:
            def fn(t: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
                k = np.clip(np.searchsorted(curve.t, t, side="right") - 1, 0, len(curve.t) - 2)
                return t + sign * h / np.maximum(1.0 - s * curve.kappa[k], 0.05), s

            return _map_poly(q, fn)

        q = shapely.intersection_all([q, shift(1.0), shift(-1.0)])
    if q.is_empty or q.area <= 0:
        return q, q
    return _map_poly(q, curve.to_enu), q


def _layout_curved(
    field: BaseGeometry,
    spec: LayoutSpec,
    curve: RowCurve,
    rng_jitter: np.random.Generator,
    rng_gaps: np.random.Generator,
    rng_weeds: np.random.Generator,
) -> Layout:
    area, q = curved_planting_area(field, spec, curve)
    _check_area(area, spec)
    t_lo, s_lo, t_hi, s_hi = q.bounds
    s_rows = _row_offsets(s_lo, s_hi, spec)
    # each row's nominal positions along its own length, centred on the area's t extent
    per_row: list[FloatArray] = []
    total = 0
    for s in s_rows:
        a_lo, a_hi = curve.row_arc(np.array([t_lo, t_hi]), float(s))
        per_row.append(
            _centred(a_lo, a_hi, spec.plant_spacing)
            if spec.plants_per_row is None
            else _counted(
                a_lo,
                a_hi,
                spec.plant_spacing,
                spec.plants_per_row,
                "layout.plants_per_row",
                "plants",
            )
        )
        total += len(per_row[-1])
        _check_candidates(total, spec)
    counts = np.array([len(p) for p in per_row], np.int64)
    row_all = np.repeat(np.arange(len(s_rows)), counts)
    pos_all = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    s_all = s_rows[row_all]
    t_all = np.concatenate(
        [curve.t_of_arc(p, float(s)) for p, s in zip(per_row, s_rows, strict=True)] or [np.empty(0)]
    )
    keep = shapely.contains_xy(q, t_all, s_all)
    c = curve
    (ox,), (oy,) = c.to_enu(np.zeros(1), np.zeros(1))
    frame0 = RowFrame(
        float(c.theta0),
        (float(ox), float(oy)),
        np.empty(0),
        np.empty(0),
        np.empty(0),
        spec.row_spacing,
        curve=c,
    )
    return _plant(
        field,
        spec,
        area,
        frame0,
        s_rows,
        row_all[keep],
        pos_all[keep],
        s_all[keep],
        t_all[keep],
        (rng_jitter, rng_gaps, rng_weeds),
    )


def _clipped_normal(rng: np.random.Generator, std: float, n: int) -> FloatArray:
    z = rng.standard_normal(n)
    return np.clip(z, -3.0, 3.0) * std


def _gaps(row_idx: IntArray, spec: LayoutSpec, rng: np.random.Generator) -> NDArray[np.bool_]:
    """Missing plants: independent singles plus runs that never cross into the next row."""
    n = len(row_idx)
    single = rng.random(n) < spec.gap_prob
    starts = rng.random(n) < spec.gap_run_prob
    lengths = rng.geometric(1.0 / spec.gap_run_mean, n)
    pos = np.arange(n)
    row_end = np.searchsorted(row_idx, row_idx, side="right")  # row_idx is sorted
    cover = np.where(starts, np.minimum(pos + lengths, row_end), -1)
    run = pos < np.maximum.accumulate(cover)
    return single | run


def _weeds(
    area: BaseGeometry, density: float, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray]:
    count = int(rng.poisson(density * area.area)) if density > 0 else 0
    if count == 0:
        return np.empty(0), np.empty(0)
    xmin, ymin, xmax, ymax = area.bounds
    xs: list[FloatArray] = []
    ys: list[FloatArray] = []
    have = 0
    fill = area.area / ((xmax - xmin) * (ymax - ymin))
    while have < count:
        m = int((count - have) / fill * 1.2) + 16
        x = rng.uniform(xmin, xmax, m)
        y = rng.uniform(ymin, ymax, m)
        inside = shapely.contains_xy(area, x, y)
        xs.append(x[inside])
        ys.append(y[inside])
        have += int(inside.sum())
    return np.concatenate(xs)[:count], np.concatenate(ys)[:count]
