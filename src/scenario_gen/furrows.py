"""Ridge/furrow micro-relief along the crop rows, plus optional soil roughness (design.md,
"The scenario pipeline").

Rows sit on the ridges and lanes in the furrows between them, as in ridge-tilled maize; on
curved and contour rows the ridges follow the rows. Relief is full over the planting area and
fades to zero over ``taper`` metres outside it.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray
from .layout import RowFrame
from .spec import FurrowSpec
from .terrain import Terrain


def ridge_profile(q: FloatArray, profile: str) -> FloatArray:
    """Relief in [-0.5, 0.5] at ``q`` = distance to the nearest row in row spacings (0..0.5)."""
    if profile == "sine":
        return 0.5 * np.cos(2 * np.pi * q)
    # Trapezoid: flat ridge top (30 % of the spacing), flat furrow bottom (30 %), straight sides.
    return 0.5 - np.clip((q - 0.15) / 0.2, 0.0, 1.0)


def add_relief(
    terrain: Terrain, rows: RowFrame, area: BaseGeometry, spec: FurrowSpec, rng: np.random.Generator
) -> Terrain:
    h = terrain.heights.copy()
    gx, gy = np.meshgrid(terrain.xs, terrain.ys)
    if spec.enabled and spec.depth > 0:
        region = area.buffer(spec.taper)
        if rows.curve is None:
            _, s = rows.to_rows(gx, gy)
            inside = shapely.contains_xy(region, gx, gy)
        else:  # the offset from a curve costs a search: only where the relief is
            inside = shapely.contains_xy(region, gx, gy)
            s = np.zeros_like(gx)
            s[inside] = rows.to_rows(gx[inside], gy[inside])[1]
        phase = (s - rows.offsets[0]) / rows.spacing
        q = np.abs(phase - np.round(phase))
        dist = ndimage.distance_transform_edt(inside) * terrain.spacing
        weight = np.clip(dist / spec.taper, 0.0, 1.0)
        h += spec.depth * weight * ridge_profile(q, spec.profile)
    if spec.roughness > 0:
        sigma = spec.roughness_length / terrain.spacing
        noise = ndimage.gaussian_filter(rng.standard_normal(h.shape), sigma, mode="wrap")
        std = float(noise.std())
        if std > 0:
            h += noise * (spec.roughness / std)
    return terrain.with_heights(h)
