"""The proxy plants and the terrain laid out for the compiled proxy cast (csrc/proxycast.c)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Terrain
from scenario_gen.arrays import FloatArray

from . import native
from .classes import CROP, OBSTACLE, OTHER, SOIL, WEED
from .proxy_plants import PlantField


class ProxyGeometry:
    """The terrain and a ``PlantField`` as csrc/proxycast.c reads them: the height grid with the
    highest vertex of each block of ``BLOCK`` × ``BLOCK`` cells (rays skip blocks they pass
    above), and the cylinders listed per square cell of a grid over the field (CSR: cell c holds
    ``items[start[c]:start[c+1]]``), each in every cell its disc's bounding square touches."""

    BLOCK = 8
    CELL = 1.0  # m: measured against 0.25-0.75 m on paper-P1 (cells cost more than cylinders)

    def __init__(self, terrain: Terrain, plants: PlantField) -> None:
        self.terrain, self.plants = terrain, plants
        h = np.ascontiguousarray(terrain.heights, np.float64)
        self.h = h
        ny, nx = h.shape
        b = self.BLOCK
        bny, bnx = -(-(ny - 1) // b), -(-(nx - 1) // b)
        # each block's cells span vertices [b i, b i + b] (shared edges belong to both blocks)
        pad = np.full((bny * b + 1, bnx * b + 1), -np.inf)
        pad[:ny, :nx] = h
        rows = np.maximum.reduceat(pad[:-1], np.arange(0, bny * b, b), axis=0)
        rows = np.maximum(rows, pad[b::b][:bny])
        blocks = np.maximum.reduceat(rows[:, :-1], np.arange(0, bnx * b, b), axis=1)
        self.bmax = np.ascontiguousarray(np.maximum(blocks, rows[:, b::b][:, :bnx]))
        self.bnx, self.bny = bnx, bny
        n = len(plants.radius)
        # one record per cylinder: x, y, bottom, top, radius
        cyl = np.zeros((max(n, 1), 5))
        if n:
            cyl[:] = np.column_stack([plants.xy, plants.z, plants.top, plants.radius])
        self.weed = plants.is_weed
        self.obstacle = plants.is_obstacle
        self.any_obstacle = bool(self.obstacle.any())
        self.ztop = float(plants.top.max()) if n else -np.inf  # the tallest plant
        g = self.CELL
        if n:
            x, y, r = plants.xy[:, 0], plants.xy[:, 1], plants.radius
            self.gx, self.gy = float((x - r).min()) - g, float((y - r).min()) - g
            self.gnx = int((float((x + r).max()) - self.gx) // g) + 2
            self.gny = int((float((y + r).max()) - self.gy) // g) + 2
            j0, j1 = (
                ((x - r - self.gx) // g).astype(np.int64),
                ((x + r - self.gx) // g).astype(np.int64),
            )
            i0, i1 = (
                ((y - r - self.gy) // g).astype(np.int64),
                ((y + r - self.gy) // g).astype(np.int64),
            )
            nj, ni = j1 - j0 + 1, i1 - i0 + 1
            cnt = nj * ni
            item = np.repeat(np.arange(n), cnt)
            k = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            cell = (np.repeat(i0, cnt) + k // np.repeat(nj, cnt)) * self.gnx + (
                np.repeat(j0, cnt) + k % np.repeat(nj, cnt)
            )
            order = np.argsort(cell, kind="stable")  # cylinders by index within a cell
            self.items = np.ascontiguousarray(item[order], np.int32)
            counts = np.bincount(cell, minlength=self.gnx * self.gny)
            self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
        else:
            self.gx = self.gy = 0.0
            self.gnx = self.gny = 0
            self.items = np.zeros(1, np.int32)
            self.start = np.zeros(2, np.int32)
        # the records in cell order (a cell's cylinders are read one after another)
        self.item_cyl = np.ascontiguousarray(cyl[self.items])
        self.kernel_scene = native.ProxyScene(
            heights=h, nx=nx, ny=ny, x0=terrain.x0, y0=terrain.y0, spacing=terrain.spacing,
            block_max=self.bmax, block=b, bnx=bnx, bny=bny, gnx=self.gnx, gny=self.gny,
            gx=self.gx, gy=self.gy, cell=self.CELL, cell_start=self.start,
            cell_items=self.items, cylinders=self.item_cyl, ztop=self.ztop,
        )  # fmt: skip

    def serves(self, terrain: Terrain, plants: PlantField) -> bool:
        return self.terrain is terrain and self.plants is plants

    def cast_raw(
        self,
        o: FloatArray,
        rays: FloatArray,
        t_lim: FloatArray,
        rot: FloatArray | None = None,
    ) -> tuple[FloatArray, NDArray[np.int32]]:
        """First hit per ray (``o`` one origin, ``rays`` unit directions, in the body frame when
        ``rot`` (body -> world) is given) within ``t_lim``: length (inf where none) and what it
        hit (-1 terrain, -2 nothing, else the cylinder)."""
        n = len(rays)
        o = np.ascontiguousarray(o, np.float64)
        d = np.ascontiguousarray(rays, np.float64)
        r = None if rot is None else np.ascontiguousarray(rot, np.float64)
        lim = np.ascontiguousarray(t_lim, np.float64)
        if lim.shape != (n,):
            lim = np.ascontiguousarray(np.broadcast_to(lim, (n,)))
        t = np.empty(n)
        what = np.empty(n, np.int32)
        native.call(
            native.ProxyCastArgs(
                scene=self.kernel_scene, n=n, origin=o, dirs=d, rot=r, tlim=lim, t=t, what=what
            )
        )
        return t, what

    def labels(self, what: NDArray[np.int32]) -> NDArray[np.uint8]:
        lab = np.full(len(what), OTHER, np.uint8)
        lab[what == -1] = SOIL
        on = what >= 0
        if on.any():
            k = what[on]
            cls = np.where(self.weed[k], WEED, CROP)
            if self.any_obstacle:  # a field without obstacles does the work it always did
                cls = np.where(self.obstacle[k], OBSTACLE, cls)
            lab[on] = cls
        return lab
