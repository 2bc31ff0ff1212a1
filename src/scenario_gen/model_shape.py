"""The proxy camera's cylinders for a user plant model, from the model's own silhouettes.

The proxy camera draws a plant as a core cylinder from the ground to its top and a leaf band
above a bare lower stem (``agrinav_gym.render.proxy_plants``). The catalog species' numbers are
fitted offline by rendering lanes (``agrinav_gym.tools.proxy_fit``); a user model gets its own
when its scenario is generated, from what a camera in the lane sees of it: its side
silhouettes.

The model, at unit height, is sampled on its surface (area-weighted, ``SAMPLES`` points from a
fixed seed; points on cut-out texels dropped) and cut into ``SLICES`` height slices. In each,
the model's reach from its axis along its x and its y axis is the ``REACH_PERCENTILE``th
percentile of the points' |x| and |y| (what a camera beside the row sees of it at that height,
leaf tips included). The proxy matches this profile in the least-absolute-error sense: a band
base ``base`` (tried every 5 % of the height, the lowest of equals: a model without a bare
stem has no band), a core whose radius is the mean reach below it (both axes averaged), and a
band whose radii along the model's x and y are the mean reaches above it (``reach_x``,
``reach_y``). All four are fractions of the plant's height, so they hold at any scale. The
band's radius across the row is the extent of that ellipse across it: for a plant turned by
ψ − α from the rows, ``h·√((reach_x·sin(ψ − α))² + (reach_y·cos(ψ − α))²)`` — the catalog
maize's ``reach·|sin(ψ − α)|`` when its leaves lie in one plane.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .arrays import FloatArray

SAMPLES = 200_000
SLICES = 50
REACH_PERCENTILE = 95.0
MIN_POINTS = 20
BASES = np.round(np.arange(0.0, 0.96, 0.05), 3)


@dataclass(frozen=True)
class ProxyShape:
    """Core radius, band base and band half-widths along the model's x and y, per unit
    height."""

    core: float
    base: float
    reach_x: float
    reach_y: float

    def to_dict(self) -> dict[str, float]:
        return {
            "core": self.core,
            "base": self.base,
            "reach_x": self.reach_x,
            "reach_y": self.reach_y,
        }

    def band(self, across: Any, along: Any) -> Any:
        """The band's radius per unit height for rows at these components of the model's x and
        y axes across them (``sin(ψ − α)``, ``cos(ψ − α)``)."""
        return np.hypot(self.reach_x * np.asarray(across), self.reach_y * np.asarray(along))


def surface_points(mesh: Any, n: int = SAMPLES, seed: int = 0) -> FloatArray:
    """``n`` area-weighted points on ``mesh``'s surface, without those on cut-out texels
    (alpha 0 in its texture)."""
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not area.sum() > 0:
        return np.zeros((0, 3))
    rng = np.random.default_rng(seed)
    face = rng.choice(len(f), n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    w = np.column_stack([1 - s, s * (1 - r2), s * r2])
    pts = np.einsum("ni,nij->nj", w, tri[face])
    visual = getattr(mesh, "visual", None)
    image = getattr(getattr(visual, "material", None), "image", None)
    uv = getattr(visual, "uv", None)
    if image is not None and uv is not None and "A" in image.mode:
        alpha = np.asarray(image, np.uint8)[..., -1]
        uvp = np.einsum("ni,nij->nj", w, np.asarray(uv, np.float64)[f[face]])
        h, wd = alpha.shape
        x = np.floor(np.mod(uvp[:, 0], 1.0) * wd).astype(np.int64).clip(0, wd - 1)
        y = np.floor((1.0 - np.mod(uvp[:, 1], 1.0)) * h).astype(np.int64).clip(0, h - 1)
        pts = pts[alpha[y, x] >= 128]
    out: FloatArray = pts
    return out


def reaches(pts: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per height slice of unit-height points: the reach along x and along y (0 where a slice
    has fewer than ``MIN_POINTS``)."""
    iz = np.clip(np.floor(pts[:, 2] * SLICES), 0, SLICES - 1).astype(np.int64)
    order = np.argsort(iz, kind="stable")
    cuts = np.searchsorted(iz[order], np.arange(SLICES + 1))
    rx, ry = np.zeros(SLICES), np.zeros(SLICES)
    for k in range(SLICES):
        sel = order[cuts[k] : cuts[k + 1]]
        if len(sel) >= MIN_POINTS:
            rx[k] = np.percentile(np.abs(pts[sel, 0]), REACH_PERCENTILE)
            ry[k] = np.percentile(np.abs(pts[sel, 1]), REACH_PERCENTILE)
    return rx, ry


def proxy_shape(mesh: Any) -> ProxyShape:
    """The proxy's shape for ``mesh`` (base at the origin, unit height, +z up)."""
    pts = surface_points(mesh)
    if len(pts) == 0:
        return ProxyShape(0.0, 0.0, 0.0, 0.0)
    rx, ry = reaches(pts)
    z = (np.arange(SLICES) + 0.5) / SLICES
    best: tuple[float, ProxyShape] | None = None
    for b in BASES:
        shape = _step(rx, ry, z, float(b))
        px = np.where(z < b, shape.core, shape.reach_x)
        py = np.where(z < b, shape.core, shape.reach_y)
        err = float(np.abs(rx - px).sum() + np.abs(ry - py).sum())
        if best is None or err < best[0] - 1e-9:
            best = (err, shape)
    assert best is not None
    return best[1]


def _step(rx: FloatArray, ry: FloatArray, z: FloatArray, base: float) -> ProxyShape:
    """The best core and band for a band base: the core's radius is the mean reach below the
    base (both axes; with no bare stem, the smaller axis' mean reach), the band's radii the
    mean reaches above it, never less than the core's."""
    below, above = z < base, z >= base
    if below.any():
        core = float(0.5 * (rx[below] + ry[below]).mean())
    else:
        core = float(min(rx.mean(), ry.mean()))
    reach_x = max(float(rx[above].mean()), core)
    reach_y = max(float(ry[above].mean()), core)
    return ProxyShape(round(core, 5), base, round(reach_x, 5), round(reach_y, 5))
