"""The terrain as a textured, smooth-shaded COLLADA mesh and as a Gazebo heightmap image."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..terrain import Terrain
from .meshes import MeshData, save_png, write_dae

#: Dry loam; the hillshade modulates it so furrows and slopes read in the Gazebo view.
SOIL_RGB = np.array([120.0, 92.0, 62.0])
MAX_HEIGHTMAP = 4097  # Gazebo wants a square (2^n + 1)-pixel heightmap


def soil_texture(t: Terrain) -> NDArray[np.uint8]:
    """RGB image, one texel per grid node, row 0 north: soil shaded by a 315°/45° hillshade."""
    shade = t.hillshade()
    rgb = SOIL_RGB[None, None, :] * (0.45 + 0.75 * shade[..., None])
    return np.asarray(np.clip(rgb, 0, 255).astype(np.uint8)[::-1])


def terrain_mesh_data(t: Terrain) -> MeshData:
    """Grid nodes as vertices (ENU), two triangles per cell, vertex normals, texel-centre UVs."""
    ny, nx = t.shape
    gx, gy = np.meshgrid(t.xs, t.ys)
    pos = np.column_stack([gx.ravel(), gy.ravel(), t.heights.ravel()])
    zy, zx = np.gradient(t.heights, t.spacing)
    n = np.stack([-zx, -zy, np.ones_like(zx)], axis=-1).reshape(-1, 3)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    j, i = np.meshgrid(np.arange(nx), np.arange(ny))
    uv = np.column_stack([(j.ravel() + 0.5) / nx, (i.ravel() + 0.5) / ny])
    a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
    faces = np.concatenate(
        [np.column_stack([a, a + 1, a + nx + 1]), np.column_stack([a, a + nx + 1, a + nx])]
    ).astype(np.int64)
    return MeshData(pos, faces, n, faces, uv, faces)


def write_terrain_dae(t: Terrain, mesh_path: Path, texture_path: Path) -> None:
    """The terrain mesh plus its texture; the DAE names the texture relative to itself."""
    save_png(soil_texture(t), texture_path)
    rel = os.path.relpath(texture_path, mesh_path.parent)
    write_dae(mesh_path, terrain_mesh_data(t), Path(rel).as_posix(), "terrain", decimals=4)


Heightmap = tuple[NDArray[np.uint16], float, tuple[float, float], float, Terrain]


def heightmap(t: Terrain) -> Heightmap:
    """16-bit heightmap resampled on a square (2^n + 1)-node grid covering the terrain.

    Returns (image with row 0 north, side length in m, centre (x, y), z range in m, the square
    grid as a Terrain); pixel value v is the height zmin + v / 65535 · range. The grid spacing
    differs from the scenario's, so the mesh stays the exact surface and this is the
    approximate, Gazebo-native alternative.
    """
    xmin, ymin, xmax, ymax = t.bounds
    side = max(xmax - xmin, ymax - ymin)
    n = min(2 ** math.ceil(math.log2(max(max(t.shape) - 1, 1))) + 1, MAX_HEIGHTMAP)
    s = np.linspace(0.0, side, n)
    gx, gy = np.meshgrid(xmin + s, ymin + s)
    z = t.height_at(gx, gy)  # beyond the grid it takes the edge height (a flat apron)
    lo, hi = float(z.min()), float(z.max())
    rng = max(hi - lo, 1e-6)
    img = np.round((z - lo) / rng * 65535.0).astype(np.uint16)[::-1]
    square = Terrain(z, xmin, ymin, side / (n - 1))
    return img, side, (xmin + side / 2, ymin + side / 2), rng, square


def save_png16(image: NDArray[np.uint16], path: Path) -> None:
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(image.astype("<u2"))).save(path)
