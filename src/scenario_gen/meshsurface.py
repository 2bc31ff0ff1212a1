"""Heights of a triangle-mesh terrain: the surface itself, not its vertices.

A mesh's height at (x, y) is the barycentric interpolation over the triangle lying under the
point, so it is exact on every triangle whether or not triangles share vertices (STL files and
unmerged glTF never do). Triangles are binned into a uniform 2-D grid by their bounding boxes;
a query looks only at the triangles of its cell, all points at once. Where triangles overlap in
plan (an overhang, a double surface) the highest is the ground. A point no triangle covers is
off the mesh.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .arrays import FloatArray, IntArray

_CHUNK = 1 << 18  # query points per batch: bounds the (point, candidate) pairs held at once
_EDGE_TOL = 1e-9  # barycentric slack, so points on a shared edge are not lost to rounding


class TriangleSurface:
    """The z = f(x, y) surface of a triangle mesh, vectorized."""

    def __init__(self, vertices: FloatArray, faces: IntArray) -> None:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        tri = v[f]  # (m, 3, 3)
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        lo, hi = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1)
        scale = np.maximum((hi - lo).max(axis=1), 1e-300)
        ok = np.abs(det) > 1e-12 * scale * scale  # walls (zero area in plan) hold no ground
        self.a, self.b, self.c = a[ok], b[ok], c[ok]
        self.det = det[ok]
        self.count = int(ok.sum())
        if self.count == 0:
            self.lo = self.cell = np.zeros(2)
            self.shape = (1, 1)
            self.start = np.zeros(2, np.int64)
            self.items = np.empty(0, np.int64)
            return
        lo, hi = lo[ok], hi[ok]
        self.lo = lo.min(axis=0)
        extent = np.maximum(hi.max(axis=0) - self.lo, 1e-9)
        cell = float(np.median((hi - lo).max(axis=1)))
        # no more cells than about two per triangle, however uneven the triangle sizes
        cell = max(cell, float(np.sqrt(extent[0] * extent[1] / (2 * self.count + 16))))
        while True:  # coarsen until the bins hold a few entries per triangle
            i0, i1, shape = self._cells(lo, hi, cell, extent)
            per = (i1[:, 0] - i0[:, 0] + 1) * (i1[:, 1] - i0[:, 1] + 1)
            if per.sum() <= 8 * self.count + 1024:
                break
            cell *= 2
        self.cell = np.array([cell, cell])
        self.shape = shape
        tri_id = np.repeat(np.arange(self.count, dtype=np.int64), per)
        first = np.repeat(np.cumsum(per) - per, per)
        k = np.arange(len(tri_id), dtype=np.int64) - first  # index within each triangle's box
        w = (i1[:, 0] - i0[:, 0] + 1)[tri_id]
        cx = i0[tri_id, 0] + k % w
        cy = i0[tri_id, 1] + k // w
        cid = cy * shape[0] + cx
        order = np.argsort(cid, kind="stable")
        self.items = tri_id[order]
        self.start = np.searchsorted(cid[order], np.arange(shape[0] * shape[1] + 1))

    def _cells(
        self, lo: FloatArray, hi: FloatArray, cell: float, extent: FloatArray
    ) -> tuple[IntArray, IntArray, tuple[int, int]]:
        shape = (int(extent[0] // cell) + 1, int(extent[1] // cell) + 1)
        i0 = np.floor((lo - self.lo) / cell).astype(np.int64)
        i1 = np.floor((hi - self.lo) / cell).astype(np.int64)
        top = np.array(shape) - 1
        return np.clip(i0, 0, top), np.clip(i1, 0, top), shape

    def heights(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """(z, covered): the surface height at each point, and whether a triangle lies under it
        (z is NaN where none does). Where surfaces are stacked, the topmost."""
        z, _, covered = self.layers(x, y)
        return z, covered

    def layers(
        self, x: FloatArray, y: FloatArray
    ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
        """(top, bottom, covered): the highest and lowest surface at each point (equal where
        the mesh is one layer; NaN where no triangle lies under it)."""
        x = np.asarray(x, np.float64).ravel()
        y = np.asarray(y, np.float64).ravel()
        top, bottom = np.full(len(x), np.nan), np.full(len(x), np.nan)
        for s in range(0, len(x), _CHUNK):
            top[s : s + _CHUNK], bottom[s : s + _CHUNK] = self._chunk(
                x[s : s + _CHUNK], y[s : s + _CHUNK]
            )
        return top, bottom, np.isfinite(top)

    def _chunk(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        out = np.full(len(x), np.nan)
        low = np.full(len(x), np.nan)
        if self.count == 0:
            return out, low
        gx = np.floor((x - self.lo[0]) / self.cell[0]).astype(np.int64)
        gy = np.floor((y - self.lo[1]) / self.cell[1]).astype(np.int64)
        inside = (gx >= 0) & (gy >= 0) & (gx < self.shape[0]) & (gy < self.shape[1])
        cid = np.where(inside, gy * self.shape[0] + gx, 0)
        n = np.where(inside, self.start[cid + 1] - self.start[cid], 0)
        pt = np.repeat(np.arange(len(x)), n)
        first = np.repeat(np.cumsum(n) - n, n)
        tri = self.items[self.start[cid[pt]] + np.arange(len(pt)) - first]
        a, b, c, det = self.a[tri], self.b[tri], self.c[tri], self.det[tri]
        px, py = x[pt], y[pt]
        l1 = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / det
        l2 = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
        l0 = 1.0 - l1 - l2
        hit = (l0 >= -_EDGE_TOL) & (l1 >= -_EDGE_TOL) & (l2 >= -_EDGE_TOL)
        zz = l0 * a[:, 2] + l1 * b[:, 2] + l2 * c[:, 2]
        np.fmax.at(out, pt[hit], zz[hit])
        np.fmin.at(low, pt[hit], zz[hit])
        return out, low
