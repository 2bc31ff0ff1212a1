"""Merged static tiles: a large field as a few hundred Gazebo models instead of one per plant.

The source paper measured ≈1.45 MB of Gazebo memory per plant model. Above a threshold
(``ExportOptions.include_limit``) plants are baked into square tiles of about
``tile_plants`` plants each: per tile one static model whose visuals are the plants' real
meshes, transformed (pose and exact per-plant scale, no size binning), merged per colour into
binary STL, and whose collision is one mesh of the plants' stem proxies (prisms). A user
``crop.model`` referenced as its own files (``plantmodels.UserFiles``) is not flattened: each of
its plants is a visual of the tile naming that mesh, textures and all, at the plant's pose and
exact size. Tiles are written one at a time, so memory stays bounded by one tile whatever the
field size.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..arrays import FloatArray, IntArray
from ..model import Scenario
from .meshes import face_colours, opaque_faces, write_stl
from .plantmodels import Assignment, fmt, model_config, static_model_sdf, visual_xml

#: Stem proxies of a tile are one collision mesh of prisms: one SDF <collision> per plant costs
#: libsdformat ≥240 kB of DOM each (a 99k-plant world did not load within 24 GB).
PRISM_SIDES = 8


def rotations(roll: FloatArray, pitch: FloatArray, yaw: FloatArray) -> FloatArray:
    """(n, 3, 3) rotation matrices R = Rz(yaw)·Ry(pitch)·Rx(roll) (URDF and SDF rpy)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    r = np.empty((len(np.atleast_1d(roll)), 3, 3))
    r[:, 0, 0] = cy * cp
    r[:, 0, 1] = cy * sp * sr - sy * cr
    r[:, 0, 2] = cy * sp * cr + sy * sr
    r[:, 1, 0] = sy * cp
    r[:, 1, 1] = sy * sp * sr + cy * cr
    r[:, 1, 2] = sy * sp * cr - cy * sr
    r[:, 2, 0] = -sp
    r[:, 2, 1] = cp * sr
    r[:, 2, 2] = cp * cr
    return r


@dataclass(frozen=True, eq=False)
class Tile:
    name: str
    origin: tuple[float, float]
    side: float
    plants: IntArray


def prism(sides: int = PRISM_SIDES) -> FloatArray:
    """(4·sides, 3, 3) triangles of a closed prism around the unit z axis from z 0 to 1.

    Its faces are tangent to the unit circle (vertices at 1/cos(π/sides)), so the stem is never
    thinner than its proxy radius; the corners reach 8 % further for 8 sides.
    """
    a = 2 * np.pi * (np.arange(sides) + 0.5) / sides
    ring = np.column_stack([np.cos(a), np.sin(a)]) / np.cos(np.pi / sides)
    nxt = np.roll(ring, -1, axis=0)
    z0, z1 = np.zeros((sides, 1)), np.ones((sides, 1))
    b0, b1 = np.hstack([ring, z0]), np.hstack([nxt, z0])
    t0, t1 = np.hstack([ring, z1]), np.hstack([nxt, z1])
    c0, c1 = np.tile([0.0, 0.0, 0.0], (sides, 1)), np.tile([0.0, 0.0, 1.0], (sides, 1))
    return np.concatenate(
        [
            np.stack([b0, b1, t1], axis=1),
            np.stack([b0, t1, t0], axis=1),
            np.stack([c0, b1, b0], axis=1),  # bottom cap faces down
            np.stack([c1, t0, t1], axis=1),
        ]
    )


def stem_prisms(
    rot: FloatArray, base: FloatArray, radius: FloatArray, height: FloatArray
) -> FloatArray:
    """Every stem proxy as a prism on its plant's axis: (n·4·sides, 3, 3) triangles."""
    unit = prism().reshape(-1, 3)
    local = unit[None] * np.stack([radius, radius, height], axis=1)[:, None, :]
    world = np.matmul(local, rot.transpose(0, 2, 1)) + base[:, None, :]
    return world.reshape(-1, 3, 3)


def make_tiles(scn: Scenario, plants_per_tile: int) -> list[Tile]:
    """Square tiles sized to hold about ``plants_per_tile`` plants at the field's density."""
    p = scn.plants
    return grid_tiles(p.x, p.y, float(scn.field.area), plants_per_tile, "agrinav_tile")


def grid_tiles(x: FloatArray, y: FloatArray, area: float, per_tile: int, prefix: str) -> list[Tile]:
    """Square tiles named ``<prefix>_rRRR_cCCC`` holding about ``per_tile`` of the points
    (x, y) spread over ``area`` m² (the plants', or the obstacles')."""
    if len(x) == 0:
        return []
    area = max(area, 1e-6)
    side = max(math.sqrt(per_tile * area / len(x)), 0.5)
    x0, y0 = float(x.min()), float(y.min())
    ix = np.floor((x - x0) / side).astype(np.int64)
    iy = np.floor((y - y0) / side).astype(np.int64)
    order = np.lexsort((np.arange(len(x)), ix, iy))
    keys = iy[order] * (int(ix.max()) + 1) + ix[order]
    cuts = np.flatnonzero(np.diff(keys)) + 1
    tiles = []
    # a dense corner of an irregular field may exceed the target; split it, never overfill
    cap = 2 * per_tile
    for members in np.split(order, cuts):
        r, c = int(iy[members[0]]), int(ix[members[0]])
        chunks = [members[i : i + cap] for i in range(0, len(members), cap)]
        for k, chunk in enumerate(chunks):
            suffix = f"_{k}" if len(chunks) > 1 else ""
            tiles.append(
                Tile(
                    f"{prefix}_r{r:03d}_c{c:03d}{suffix}",
                    (x0 + c * side, y0 + r * side),
                    side,
                    np.sort(chunk),
                )
            )
    return tiles


@dataclass(frozen=True, eq=False)
class _Shape:
    triangles: FloatArray  # (f, 3, 3) at nominal size
    colour: IntArray  # (f,) index into the palette


def _shapes(a: Assignment) -> tuple[list[_Shape | None], NDArray[np.uint8]]:
    """Per model its triangles and their palette colours (None: referenced, not merged)."""
    keep = [opaque_faces(pm.mesh) for pm in a.models]  # no cut-out face, painted
    rgb = [
        face_colours(pm.mesh)[k] if pm.user is None else None
        for pm, k in zip(a.models, keep, strict=True)
    ]
    used = [c for c in rgb if c is not None]
    palette = np.unique(np.concatenate(used), axis=0) if used else np.empty((0, 3), np.uint8)
    shapes: list[_Shape | None] = []
    for pm, c, k in zip(a.models, rgb, keep, strict=True):
        if c is None:
            shapes.append(None)
            continue
        v = np.asarray(pm.mesh.vertices, np.float64)[np.asarray(pm.mesh.faces)[k]]
        idx = np.array([np.flatnonzero((palette == col).all(axis=1))[0] for col in c], np.int64)
        shapes.append(_Shape(v, idx))
    return shapes, palette


def write_tiles(
    models_dir: Path, scn: Scenario, a: Assignment, tiles: list[Tile]
) -> Iterator[tuple[Tile, int]]:
    """Write each tile's model folder; yields (tile, triangles) as each one is done."""
    shapes, palette = _shapes(a)
    p = scn.plants
    nominal = np.array([pm.height for pm in a.models])
    radius = np.array([pm.proxy_radius for pm in a.models])
    for tile in tiles:
        sel = tile.plants
        ox, oy = tile.origin
        scale = p.height[sel] / nominal[a.model[sel]]
        rot = rotations(p.roll[sel], p.pitch[sel], p.yaw[sel])
        pos = np.column_stack([p.x[sel] - ox, p.y[sel] - oy, p.z[sel]])
        folder = models_dir / tile.name
        (folder / "meshes").mkdir(parents=True)
        by_colour: dict[int, list[FloatArray]] = {}
        visuals = []
        total = 0
        for m in np.unique(a.model[sel]).tolist():
            k = a.model[sel] == m
            sh = shapes[m]
            if sh is None:  # the user's model, by reference: one visual per plant
                pm = a.models[m]
                for j in np.flatnonzero(k).tolist():
                    i = int(sel[j])
                    visuals.append(visual_xml(pm, p.height[i], f"plant_{i:06d}", rot[j], pos[j]))
                total += int(k.sum()) * len(pm.mesh.faces)
                continue
            # (k, 3, 3) @ (3, 3f): every corner of every plant in one batched product
            m_k = rot[k] * scale[k, None, None]
            tri = np.matmul(m_k, sh.triangles.reshape(-1, 3).T).transpose(0, 2, 1)
            tri = (tri + pos[k, None, :]).reshape(len(m_k), -1, 3, 3)
            for c in np.unique(sh.colour).tolist():
                by_colour.setdefault(c, []).append(tri[:, sh.colour == c].reshape(-1, 3, 3))
        for c in sorted(by_colour):
            tri = np.concatenate(by_colour[c])
            total += len(tri)
            write_stl(folder / "meshes" / f"colour{c:02d}.stl", tri)
            r, g, b = (palette[c] / 255.0).tolist()
            visuals.append(
                f'<visual name="colour{c:02d}"><geometry><mesh>'
                f"<uri>model://{tile.name}/meshes/colour{c:02d}.stl</uri></mesh></geometry>"
                f"<material><ambient>{fmt(r, g, b, 1, digits=4)}</ambient>"
                f"<diffuse>{fmt(r, g, b, 1, digits=4)}</diffuse>"
                f"<specular>0.05 0.05 0.05 1</specular></material></visual>"
            )
        r_stem = radius[a.model[sel]] * scale
        has = r_stem > 0
        cols = []
        if has.any():
            stems = stem_prisms(rot[has], pos[has], r_stem[has], p.height[sel][has])
            write_stl(folder / "meshes" / "stems.stl", stems)
            cols.append(
                f'<collision name="stems"><geometry><mesh><uri>model://{tile.name}/meshes/'
                "stems.stl</uri></mesh></geometry></collision>"
            )
        (folder / "model.sdf").write_text(static_model_sdf(tile.name, visuals + cols))
        desc = f"{len(sel)} plants merged (static), {total} triangles; agrinav export"
        (folder / "model.config").write_text(model_config(tile.name, desc))
        yield tile, total
