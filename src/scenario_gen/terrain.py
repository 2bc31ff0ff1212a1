"""The terrain: a regular height grid in the local ENU frame.

Every source (DEM, mesh, plane) ends as one of these, sampled at the level-of-detail spacing.
Two height functions live here, on purpose:

* ``height_at`` — bilinear over the grid, the surface a physics engine triangulates and the
  robot drives on;
* ``idw`` — the source paper's k-nearest-neighbour (k = 3) inverse-squared-distance weighting
  over the terrain samples, one vectorized ``cKDTree`` query, with central differences of the
  same function for the slope. It is what plants are placed with (design.md, "The scenario
  pipeline").

On a regular grid the central difference of the IDW function one grid step either side of a
point reuses that point's neighbour set shifted by one node, so slope comes from the same single
query; because the IDW error pattern repeats with the grid period, that difference is exact for
planes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .arrays import FloatArray

IDW_EPS = 1e-12  # m², keeps the weight finite at a sample


@dataclass(frozen=True, eq=False)
class Terrain:
    """Heights (ny, nx) in metres; node (i, j) lies at (x0 + j·spacing, y0 + i·spacing)."""

    heights: FloatArray
    x0: float
    y0: float
    spacing: float
    lod: int | None = None
    _tree: list[cKDTree] = field(default_factory=list, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        h = np.ascontiguousarray(self.heights, dtype=np.float64)
        if h.ndim != 2 or min(h.shape) < 2:
            raise ValueError(f"terrain heights must be a 2-D grid of at least 2x2, got {h.shape}")
        if not np.isfinite(h).all():
            raise ValueError("terrain heights contain NaN or inf")
        object.__setattr__(self, "heights", h)

    def __getstate__(self) -> dict[str, object]:
        state = dict(self.__dict__)
        state["_tree"] = []  # rebuilt on demand; a pickled tree is as large as the grid
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def size(self) -> int:
        return int(self.heights.size)

    @cached_property
    def xs(self) -> FloatArray:
        return self.x0 + self.spacing * np.arange(self.shape[1], dtype=np.float64)

    @cached_property
    def ys(self) -> FloatArray:
        return self.y0 + self.spacing * np.arange(self.shape[0], dtype=np.float64)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) in metres."""
        return (self.x0, self.y0, float(self.xs[-1]), float(self.ys[-1]))

    @property
    def relief(self) -> float:
        return float(self.heights.max() - self.heights.min())

    def contains(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.bool_]:
        xmin, ymin, xmax, ymax = self.bounds
        if isinstance(x, float) and isinstance(y, float):  # the per-step scalar path
            return np.bool_(xmin <= x <= xmax and ymin <= y <= ymax)
        xa, ya = np.asarray(x), np.asarray(y)
        return (xa >= xmin) & (xa <= xmax) & (ya >= ymin) & (ya <= ymax)

    # ------------------------------------------------------------------ bilinear surface
    def height_at(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Bilinear height at (x, y), vectorized; points off the grid take the edge height, a
        NaN coordinate gives NaN."""
        xa, ya = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
        ny, nx = self.shape
        u = np.clip((xa - self.x0) / self.spacing, 0.0, nx - 1.0)
        v = np.clip((ya - self.y0) / self.spacing, 0.0, ny - 1.0)
        unknown = np.isnan(u) | np.isnan(v)
        if unknown.any():  # NaN would index the grid at -2^63
            u, v = np.where(unknown, 0.0, u), np.where(unknown, 0.0, v)
        j = np.minimum(u.astype(np.intp), nx - 2)
        i = np.minimum(v.astype(np.intp), ny - 2)
        fu, fv = u - j, v - i
        h = self.heights
        z0 = h[i, j] * (1 - fu) + h[i, j + 1] * fu
        z1 = h[i + 1, j] * (1 - fu) + h[i + 1, j + 1] * fu
        z = z0 * (1 - fv) + z1 * fv
        return np.where(unknown, np.nan, z) if unknown.any() else z

    def normal_at(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Unit surface normal of the bilinear surface, shape (..., 3)."""
        d = self.spacing
        xa, ya = np.asarray(x, np.float64), np.asarray(y, np.float64)
        zx = (self.height_at(xa + d, ya) - self.height_at(xa - d, ya)) / (2 * d)
        zy = (self.height_at(xa, ya + d) - self.height_at(xa, ya - d)) / (2 * d)
        n = np.stack([-zx, -zy, np.ones_like(zx)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def slope_deg(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Slope of the bilinear surface at (x, y), degrees from horizontal."""
        return np.degrees(np.arccos(np.clip(self.normal_at(x, y)[..., 2], -1.0, 1.0)))

    # ------------------------------------------------------------------ k-NN IDW
    @property
    def tree(self) -> cKDTree:
        """KD-tree over the grid nodes' (x, y), built once per terrain."""
        if not self._tree:
            gx, gy = np.meshgrid(self.xs, self.ys)
            self._tree.append(cKDTree(np.column_stack([gx.ravel(), gy.ravel()])))
        return self._tree[0]

    def idw(
        self, x: ArrayLike, y: ArrayLike, k: int = 3
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(z, ∂z/∂x, ∂z/∂y) by k-NN inverse-squared-distance weighting, one tree query."""
        xa = np.asarray(x, np.float64).ravel()
        ya = np.asarray(y, np.float64).ravel()
        dist, idx = self.tree.query(np.column_stack([xa, ya]), k=k, workers=-1)
        w = 1.0 / (dist * dist + IDW_EPS)
        wsum = w.sum(axis=1)
        ny, nx = self.shape
        i, j = np.divmod(idx, nx)
        h = self.heights
        z = (w * h[i, j]).sum(axis=1) / wsum
        jp, jm = np.minimum(j + 1, nx - 1), np.maximum(j - 1, 0)
        ip, im = np.minimum(i + 1, ny - 1), np.maximum(i - 1, 0)
        gx = (h[i, jp] - h[i, jm]) / ((jp - jm) * self.spacing)
        gy = (h[ip, j] - h[im, j]) / ((ip - im) * self.spacing)
        dzdx = (w * gx).sum(axis=1) / wsum
        dzdy = (w * gy).sum(axis=1) / wsum
        return z, dzdx, dzdy

    # ------------------------------------------------------------------ derived
    def with_heights(self, heights: FloatArray) -> Terrain:
        return Terrain(heights, self.x0, self.y0, self.spacing, self.lod)

    def to_trimesh(self, y_up: bool = False) -> object:
        """The grid as a triangle mesh (two triangles per cell), ENU or glTF's Y-up axes."""
        import trimesh

        ny, nx = self.shape
        gx, gy = np.meshgrid(self.xs, self.ys)
        v = np.column_stack([gx.ravel(), gy.ravel(), self.heights.ravel()])
        if y_up:
            v = np.column_stack([v[:, 0], v[:, 2], -v[:, 1]])
        a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
        faces = np.concatenate(
            [np.column_stack([a, a + 1, a + nx + 1]), np.column_stack([a, a + nx + 1, a + nx])]
        )
        return trimesh.Trimesh(vertices=v, faces=faces, process=False)

    def hillshade(self, azimuth_deg: float = 315.0, altitude_deg: float = 45.0) -> FloatArray:
        """Lambertian hillshade in [0, 1], rows from south to north like ``heights``."""
        return hillshade(self.heights, self.spacing, self.spacing, azimuth_deg, altitude_deg)


def hillshade(
    z: FloatArray,
    dx: float,
    dy: float,
    azimuth_deg: float = 315.0,
    altitude_deg: float = 45.0,
) -> FloatArray:
    """Lambertian hillshade in [0, 1] of a height grid whose row index grows by ``dy`` metres.

    ``dy`` > 0 when row 0 is the southern edge (``Terrain.heights``), < 0 when it is the
    northern one (an image); the light comes from ``azimuth_deg`` clockwise from north either way.
    """
    zy, zx = np.gradient(np.nan_to_num(np.asarray(z, np.float64)), dy, dx)
    az, alt = np.radians(90.0 - azimuth_deg), np.radians(altitude_deg)
    light = np.array([np.cos(alt) * np.cos(az), np.cos(alt) * np.sin(az), np.sin(alt)])
    n = np.stack([-zx, -zy, np.ones_like(zx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.asarray(np.clip(n @ light, 0.0, 1.0))


def grid_for_bounds(
    xmin: float, ymin: float, xmax: float, ymax: float, spacing: float
) -> tuple[float, float, int, int]:
    """Origin and node counts of a grid snapped to ``spacing`` that covers the bounds."""
    x0 = np.floor(xmin / spacing) * spacing
    y0 = np.floor(ymin / spacing) * spacing
    nx = int(np.ceil((xmax - x0) / spacing)) + 1
    ny = int(np.ceil((ymax - y0) / spacing)) + 1
    return float(x0), float(y0), max(nx, 2), max(ny, 2)
