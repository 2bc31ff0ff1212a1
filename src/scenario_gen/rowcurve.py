"""Reference curves of curved and contour rows: a smooth curve and its parallel offsets.

Every row of a curved or contour field is the curve shifted sideways by its offset ``s`` along
the curve's normal, so neighbouring rows are one row spacing apart along the normal wherever
they are measured (parallel curves), as a planter keeps its row units abreast. Coordinates are
(t, s): ``t`` the arc length of the reference curve from the frame origin, ``s`` the signed
distance along its left normal. A row at offset ``s`` is ``1 − s·κ`` times as long as the
reference over the same ``t`` (κ the reference curvature, positive to the left), so its own arc
length is ``L = t − s·(θ(t) − θ(0))`` with θ the reference heading: plants are spaced along
``L``, each row at the planter's spacing.

The curve is sampled every ``STEP`` metres of arc; between samples its heading changes at a
constant rate (a circular arc per step), so positions and headings agree exactly, an arc is
represented exactly and the offsets are exactly parallel. Outside the sampled stretch it
continues straight along its end tangents.

Two curves are built here:

- ``arc_curve`` (``layout.row_geometry: curved``): concentric circular arcs whose centre lies
  outside the planting area, at the drawn radius from its nearest point, so every row is at
  least that radius.
- ``contour_curve`` (``contour``): the terrain contour through the field centre (the key line
  of contour planting), traced on the terrain smoothed over ``CONTOUR_SMOOTH_M`` and
  straightened where it would bend a row tighter than the minimum radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely
from scipy import ndimage
from scipy.spatial import cKDTree
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray, IntArray
from .errors import InputError
from .spec import LayoutSpec

#: Sampling step of a reference curve, metres.
STEP = 0.25
#: Terrain smoothing (Gaussian σ, metres) before the key contour is traced: a DEM resampled to
#: centimetres still carries its 10-30 m pixels' creases, which a row should not follow.
CONTOUR_SMOOTH_M = 4.0
#: Spacing of the height samples the key contour is traced on, metres.
CONTOUR_GRID_M = 1.0
#: Mean slope under the field below which contour rows are refused (no contour to follow).
MIN_CONTOUR_SLOPE = 0.01
#: Headings the key line is smoothed over (Gaussian σ, metres of arc) before its curvature is
#: bounded.
HEADING_SMOOTH_M = 2.0


@dataclass(frozen=True, eq=False)
class RowCurve:
    """A reference curve sampled as a polyline: ``xy`` (M, 2) ENU, ``t`` (M,) arc length with 0
    at the frame origin, ``theta`` (M,) heading (unwrapped, rad), ``kind`` curved or contour."""

    kind: str
    xy: FloatArray
    t: FloatArray
    theta: FloatArray

    @classmethod
    def from_headings(
        cls, kind: str, start: FloatArray, theta: FloatArray, step: float, i0: int
    ) -> RowCurve:
        """The curve with heading ``theta[i]`` at arc length ``(i − i0)·step``, through
        ``start`` at ``i0``; between samples it is a circular arc (the heading changes at a
        constant rate), so positions and headings agree exactly."""
        theta = np.asarray(theta, np.float64)
        d = np.diff(theta)
        chord = step * np.sinc(d / (2 * np.pi))  # sin(d/2) / (d/2)
        mid = theta[:-1] + 0.5 * d
        steps = chord[:, None] * np.column_stack([np.cos(mid), np.sin(mid)])
        xy = np.empty((len(theta), 2))
        xy[i0] = start
        xy[i0 + 1 :] = start + np.cumsum(steps[i0:], axis=0)
        xy[:i0] = start - np.cumsum(steps[:i0][::-1], axis=0)[::-1]
        t = step * (np.arange(len(theta), dtype=np.float64) - i0)
        return cls(kind, xy, t, theta)

    # ------------------------------------------------------------------ geometry
    @cached_property
    def _tree(self) -> cKDTree:
        return cKDTree(self.xy)

    @cached_property
    def kappa(self) -> FloatArray:
        """Curvature of each polyline segment (M-1,), 1/m, positive to the left."""
        return np.diff(self.theta) / np.diff(self.t)

    @property
    def theta0(self) -> float:
        return float(np.interp(0.0, self.t, self.theta))

    def _at(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
        """(x, y, heading, segment index) of the reference at ``t``: on the segment's arc, and
        straight along the end tangents past the ends."""
        t = np.asarray(t, np.float64)
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        t0 = self.t[i]
        last = len(self.t) - 1
        # past the ends: from the end point, straight along its heading
        before, after = t < self.t[0], t > self.t[last]
        u = np.where(after, t - self.t[last], t - t0)
        k = np.where(before | after, 0.0, self.kappa[i])
        th0 = np.where(after, self.theta[last], self.theta[i])
        x0 = np.where(after, self.xy[last, 0], self.xy[i, 0])
        y0 = np.where(after, self.xy[last, 1], self.xy[i, 1])
        d = k * u
        chord = u * np.sinc(d / (2 * np.pi))
        mid = th0 + 0.5 * d
        return x0 + chord * np.cos(mid), y0 + chord * np.sin(mid), th0 + d, i

    def heading(self, t: FloatArray) -> FloatArray:
        return self._at(t)[2]

    def to_enu(self, t: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
        x, y, th, _ = self._at(t)
        return x - s * np.sin(th), y + s * np.cos(th)

    def to_rows(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(t, s) of ENU points: the foot of the normal through each point, Newton-refined."""
        q = np.column_stack([np.ravel(x), np.ravel(y)]).astype(np.float64)
        shape = np.shape(x)
        if len(q) == 0:
            return np.empty(shape), np.empty(shape)
        _, j = self._tree.query(q)
        m = len(self.t)
        best_t = np.empty(len(q))
        best_d = np.full(len(q), np.inf)
        for i in (np.maximum(j - 1, 0), np.minimum(j, m - 2)):
            a, b = self.xy[i], self.xy[i + 1]
            d = b - a
            f = np.einsum("ij,ij->i", q - a, d) / np.einsum("ij,ij->i", d, d)
            lo = np.where(i == 0, -np.inf, 0.0)  # the end segments extend straight
            hi = np.where(i == m - 2, np.inf, 1.0)
            f = np.clip(f, lo, hi)
            p = a + f[:, None] * d
            dist = np.einsum("ij,ij->i", q - p, q - p)
            better = dist < best_d
            best_d = np.where(better, dist, best_d)
            best_t = np.where(better, self.t[i] + f * (self.t[i + 1] - self.t[i]), best_t)
        t = best_t
        for _ in range(3):
            cx, cy, th, k = self._at(t)
            inside = (t > self.t[0]) & (t < self.t[-1])
            kap = np.where(inside, self.kappa[k], 0.0)
            rx, ry = q[:, 0] - cx, q[:, 1] - cy
            c, sn = np.cos(th), np.sin(th)
            g = rx * c + ry * sn
            s = -rx * sn + ry * c
            t = t + g / np.maximum(1.0 - s * kap, 0.1)
        cx, cy, th, _ = self._at(t)
        s = -(q[:, 0] - cx) * np.sin(th) + (q[:, 1] - cy) * np.cos(th)
        return t.reshape(shape), s.reshape(shape)

    def row_arc(self, t: FloatArray, s: FloatArray | float) -> FloatArray:
        """Arc length along the row at offset ``s`` at reference ``t`` (0 at t = 0)."""
        return np.asarray(t) - s * (self.heading(t) - self.theta0)

    def t_of_arc(self, arc: FloatArray, s: float) -> FloatArray:
        """Reference ``t`` at arc length ``arc`` along the row at offset ``s``."""
        grid = self.t - s * (self.theta - self.theta0)
        out = np.interp(arc, grid, self.t)
        # straight past the ends, where the row's length grows one for one
        out = np.where(arc < grid[0], self.t[0] + (arc - grid[0]), out)
        return np.where(arc > grid[-1], self.t[-1] + (arc - grid[-1]), out)

    def stretch(self, t0: float, t1: float, s: float) -> float:
        """Largest factor between the row's length and the reference's over [t0, t1]."""
        lo, hi = np.searchsorted(self.t, [min(t0, t1), max(t0, t1)])
        k = self.kappa[max(lo - 1, 0) : min(hi + 1, len(self.kappa))]
        return float(np.max(np.abs(1.0 - s * k))) if len(k) else 1.0

    def to_dict(self) -> dict[str, object]:
        """Plain lists (full precision: JSON round-trips every double)."""
        return {
            "kind": self.kind,
            "t": self.t.tolist(),
            "x": self.xy[:, 0].tolist(),
            "y": self.xy[:, 1].tolist(),
            "theta": self.theta.tolist(),
        }


# ----------------------------------------------------------------------------- builders
def _extent(area: BaseGeometry, origin: FloatArray, u: FloatArray, n: FloatArray) -> FloatArray:
    """Points of the area's (densified) boundary relative to ``origin`` in the (u, n) frame."""
    xy = shapely.get_coordinates(shapely.segmentize(area.boundary, 0.5))
    d = xy - origin
    return np.column_stack([d @ u, d @ n])


def arc_curve(
    area: BaseGeometry,
    angle: float,
    radius: float,
    side: int,
    reach: float,
) -> RowCurve:
    """Concentric arcs through the area's centroid, tangent to ``angle`` there, bending to the
    ``side`` (+1 left, -1 right), every point of the area at least ``radius`` from the centre;
    sampled ``reach`` metres beyond the area along the arc (at most a half turn each way)."""
    c = area.centroid
    origin = np.array([c.x, c.y])
    u = np.array([math.cos(angle), math.sin(angle)])
    n = np.array([-math.sin(angle), math.cos(angle)])
    ts = _extent(area, origin, u, n)
    toward = float((side * ts[:, 1]).max())  # how far the area reaches toward the centre
    r0 = radius + max(toward, 0.0)  # the centre is origin + side * r0 * n
    # angular extent of the area seen from the centre (it lies in a half plane: < pi)
    rel = ts - np.array([0.0, side * r0])
    phi = side * np.arctan2(rel[:, 0], -side * rel[:, 1])
    a_lo = max(float(phi.min()) - reach / r0, -0.95 * math.pi)
    a_hi = min(float(phi.max()) + reach / r0, 0.95 * math.pi)
    k0, k1 = math.floor(a_lo * r0 / STEP), math.ceil(a_hi * r0 / STEP)
    theta = angle + side * STEP * np.arange(k0, k1 + 1, dtype=np.float64) / r0
    return RowCurve.from_headings("curved", origin, theta, STEP, -k0)


def contour_curve(
    area: BaseGeometry,
    heights: object,
    bounds: tuple[float, float, float, float],
    angle: float,
    min_radius: float,
) -> RowCurve:
    """The smoothed terrain contour through the area's centroid, oriented within 90° of
    ``angle``, its curvature bounded so that no row of the area curves tighter than
    ``min_radius``. ``heights(x, y)`` samples the site's terrain; ``bounds`` is the terrain
    extent the curve must span."""
    import contourpy  # matplotlib's contour generator

    xmin, ymin, xmax, ymax = bounds
    g = CONTOUR_GRID_M
    xs = np.arange(xmin, xmax + g, g)
    ys = np.arange(ymin, ymax + g, g)
    gx, gy = np.meshgrid(xs, ys)
    z = np.asarray(heights(gx.ravel(), gy.ravel()), np.float64).reshape(gx.shape)  # type: ignore[operator]
    # smooth what a plane leaves, so the padding at the edges does not bend a slope's contours
    a = np.column_stack([np.ones(gx.size), gx.ravel(), gy.ravel()])
    coef = np.linalg.lstsq(a, z.ravel(), rcond=None)[0]
    tilt = (a @ coef).reshape(z.shape)
    z = tilt + ndimage.gaussian_filter(z - tilt, CONTOUR_SMOOTH_M / g, mode="nearest")
    c = area.centroid
    cx, cy = c.x, c.y
    zy, zx = np.gradient(z, g)
    inside = shapely.contains_xy(area, gx, gy)
    slope = float(np.hypot(zx, zy)[inside].mean()) if inside.any() else 0.0
    if slope < MIN_CONTOUR_SLOPE:
        raise InputError(
            "layout.row_geometry",
            "contour",
            f"the terrain under the field is flat (mean slope {100 * slope:.2f} %); allowed: "
            f"contour rows on a mean slope of at least {100 * MIN_CONTOUR_SLOPE:g} %, or "
            "straight or curved rows",
        )
    level = float(ndimage.map_coordinates(z, [[(cy - ymin) / g], [(cx - xmin) / g]], order=1)[0])
    lines = contourpy.contour_generator(xs, ys, z).lines(level)
    pieces = [np.asarray(p, np.float64) for p in lines if len(p) >= 2]
    if not pieces:  # pragma: no cover - the level is sampled at the centroid
        raise InputError("layout.row_geometry", "contour", "no contour through the field centre")
    near = [float(np.hypot(p[:, 0] - cx, p[:, 1] - cy).min()) for p in pieces]
    raw = pieces[int(np.argmin(near))]
    # resample every STEP metres along the contour
    seg = np.hypot(*np.diff(raw, axis=0).T)
    keep = np.concatenate([[True], seg > 1e-9])
    raw = raw[keep]
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(raw, axis=0).T))])
    m = max(2, math.ceil(arc[-1] / STEP) + 1)
    a = np.linspace(0.0, arc[-1], m)
    pts = np.column_stack([np.interp(a, arc, raw[:, 0]), np.interp(a, arc, raw[:, 1])])
    d = np.gradient(pts, axis=0)
    theta = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    i0 = int(np.argmin(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy)))
    if math.cos(theta[i0] - angle) < 0:  # run along the field's axis, not against it
        pts, theta = pts[::-1], np.unwrap(theta[::-1] + math.pi)
        i0 = m - 1 - i0
    step = float(a[1] - a[0]) if m > 1 else STEP
    theta = ndimage.gaussian_filter1d(theta, HEADING_SMOOTH_M / step, mode="nearest")
    # bound the curvature so the farthest row of the area keeps min_radius
    u = np.array([math.cos(theta[i0]), math.sin(theta[i0])])
    n = np.array([-u[1], u[0]])
    ts = _extent(area, pts[i0], u, n)
    reach = float(np.abs(ts[:, 1]).max())
    k_max = 1.0 / (min_radius + reach)
    dth = np.clip(np.diff(theta), -k_max * step, k_max * step)
    theta = np.concatenate([[0.0], np.cumsum(dth)])
    theta += float(np.arctan2(u[1], u[0])) - theta[i0]
    # the positions follow from the headings, outward from the point nearest the centroid
    return RowCurve.from_headings("contour", pts[i0], theta, step, i0)


def row_curve(
    spec: LayoutSpec,
    field: BaseGeometry,
    angle: float,
    bounds: tuple[float, float, float, float],
    heights: object,
    rng: np.random.Generator,
) -> RowCurve | None:
    """The reference curve ``spec.row_geometry`` asks for (None: straight rows). ``curved``
    draws its radius from ``spec.curve_radius`` and the side it bends to from ``rng``;
    ``contour`` samples ``heights(x, y)`` over ``bounds`` (the terrain's extent)."""
    if spec.row_geometry == "straight":
        return None
    inner = field.buffer(-spec.edge_margin, join_style="mitre") if spec.edge_margin > 0 else field
    if inner.is_empty:
        raise InputError(
            "layout.edge_margin",
            spec.edge_margin,
            "leaves no planting area inside the field; allowed: a smaller margin",
        )
    if spec.row_geometry == "curved":
        lo, hi = spec.curve_radius
        radius = float(rng.uniform(lo, hi))
        side = 1 if rng.random() < 0.5 else -1
        xmin, ymin, xmax, ymax = bounds
        return arc_curve(inner, angle, radius, side, math.hypot(xmax - xmin, ymax - ymin))
    return contour_curve(inner, heights, bounds, angle, spec.curve_radius[0])
