"""Rotated-grid crop layout (DESIGN §4.3), fully vectorized.

Candidates sit on a grid rotated by the row angle; rows are centred on the planting area so a
rectangle is planted symmetrically. A candidate is kept when it, and the points one headland
width before and after it along the row, lie inside the field shrunk by the edge margin — the
headland test is one containment call against the intersection of the shifted polygons.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely import affinity
from shapely.geometry.base import BaseGeometry

from .errors import InputError
from .spec import LayoutSpec

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class RowFrame:
    """Row geometry: ENU point ``origin``, along-row unit ``u`` and across-row unit ``n``."""

    angle: float  # rad, row direction counter-clockwise from east
    origin: tuple[float, float]
    offsets: FloatArray  # lateral offset of each planted row along n, ascending
    starts: FloatArray  # along-row extent of each row's nominal planting positions
    ends: FloatArray
    spacing: float

    @property
    def u(self) -> FloatArray:
        return np.array([math.cos(self.angle), math.sin(self.angle)])

    @property
    def n(self) -> FloatArray:
        return np.array([-math.sin(self.angle), math.cos(self.angle)])

    def to_enu(self, t: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
        ox, oy = self.origin
        u, n = self.u, self.n
        return ox + t * u[0] + s * n[0], oy + t * u[1] + s * n[1]

    def to_rows(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        dx, dy = np.asarray(x) - self.origin[0], np.asarray(y) - self.origin[1]
        u, n = self.u, self.n
        return dx * u[0] + dy * u[1], dx * n[0] + dy * n[1]


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


def layout(
    field: BaseGeometry,
    spec: LayoutSpec,
    angle: float,
    rng_jitter: np.random.Generator,
    rng_gaps: np.random.Generator,
    rng_weeds: np.random.Generator,
) -> Layout:
    area = planting_area(field, spec, angle)
    if area.is_empty or area.area <= 0:
        raise InputError(
            "layout.headland/edge_margin",
            (spec.headland, spec.edge_margin),
            "leave no planting area inside the field; allowed: smaller margins or a larger field",
        )
    c = area.centroid
    frame0 = RowFrame(angle, (c.x, c.y), np.empty(0), np.empty(0), np.empty(0), spec.row_spacing)
    ex = np.asarray(
        area.exterior.coords if area.geom_type == "Polygon" else shapely.get_coordinates(area)
    )
    t_b, s_b = frame0.to_rows(ex[:, 0], ex[:, 1])
    s_rows = _centred(float(s_b.min()), float(s_b.max()), spec.row_spacing)
    t_pos = _centred(float(t_b.min()), float(t_b.max()), spec.plant_spacing)
    if len(s_rows) * len(t_pos) > 50_000_000:
        raise InputError(
            "layout.plant_spacing",
            spec.plant_spacing,
            "gives over 50 million candidate plants; allowed: a coarser spacing or a smaller field",
        )
    S, T = np.meshgrid(s_rows, t_pos, indexing="ij")  # rows contiguous, along-row ascending
    s_all, t_all = S.ravel(), T.ravel()
    x0, y0 = frame0.to_enu(t_all, s_all)
    keep = shapely.contains_xy(area, x0, y0)
    row_of = np.repeat(np.arange(len(s_rows)), len(t_pos))[keep]
    s_k, t_k = s_all[keep], t_all[keep]
    if len(s_k) == 0:
        raise InputError(
            "field",
            f"{field.area:.1f} m²",
            "is too small for one plant at this row spacing, plant spacing and margins",
        )
    used, row_idx = np.unique(row_of, return_inverse=True)
    n_rows = len(used)
    starts = np.full(n_rows, np.inf)
    ends = np.full(n_rows, -np.inf)
    np.minimum.at(starts, row_idx, t_k)
    np.maximum.at(ends, row_idx, t_k)
    rows = RowFrame(angle, frame0.origin, s_rows[used], starts, ends, spec.row_spacing)

    missing = _gaps(row_idx, spec, rng_gaps)
    n = len(s_k)
    dl = _clipped_normal(rng_jitter, spec.jitter_lateral, n)
    dt = _clipped_normal(rng_jitter, spec.jitter_longitudinal, n)
    px, py = rows.to_enu(t_k + dt, s_k + dl)
    ok = ~missing & shapely.contains_xy(field, px, py)
    wx, wy = _weeds(area, spec.weed_density, rng_weeds)
    x = np.concatenate([px[ok], wx])
    y = np.concatenate([py[ok], wy])
    row = np.concatenate([row_idx[ok].astype(np.int64), np.full(len(wx), -1, np.int64)])
    weed = np.concatenate([np.zeros(int(ok.sum()), bool), np.ones(len(wx), bool)])
    return Layout(x, y, row, weed, rows, area, n)


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
