"""The world as the cameras see it: terrain tiles and instanced plants around the camera.

The field is cut into square tiles. A tile holds an Embree scene of its terrain triangles (the
height grid's cells, two triangles each, as ``Terrain.to_trimesh``) and its plants as Embree
*instances* (a 3×4 transform each, pointing at a shared prototype scene; an instance's geometry
id is its plant's index, so a hit names its plant). Only the tiles that
the cameras' view can reach are attached to the top-level scene — the convex hull of the view's
corners, grown by the plants' horizontal reach — and built tiles wait in an LRU cache, so the
cost of a frame does not grow with the field. Coordinates are relative to the terrain's centre
so that Embree's float32 keeps sub-millimetre precision on any field.

A prototype whose texture has cut-outs (alpha, ``Prototype.alpha``) lets rays through them: a
ray whose first hit lies on a cut-out texel is cast again from just beyond it, until it hits an
opaque texel, something else or nothing (``MAX_CUTOUTS`` times at most), for every query —
depth, colour, labels and the stereo pair's occlusion test alike.

Obstacles (stones, litter, fallen stalks: ``ObstacleMeshes``) are few and each of its own
shape: they are one static Embree scene, always attached (an obstacle's geometry id in it is its
index, so a hit names it), not tiles of instances.

Terrain hits are refined by Newton's method onto the bilinear surface of the height grid
(``Terrain.height_at``), the same surface the analytic camera intersects: the triangles only
bracket the crossing.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Scenario, Terrain
from scenario_gen.arrays import F32, FloatArray
from scenario_gen.obstacles import Obstacles

from . import native
from .classes import OBSTACLE, OTHER, SOIL
from .embree import Caster, Hits, Scene, device
from .obstacle_meshes import ObstacleMeshes
from .plant_meshes import PlantMeshes, Prototype

TILE = 4.0  # m: a terrain tile is 34 × 34 cells at 0.12 m; a frame touches ≈ 10-15 tiles
MARGIN = 1.0  # m: the view's hull is grown by this, so small moves reuse the same tiles
CACHE_TILES = 96
#: Cut-out texels one ray may pass through; a ray still on one after as many is a miss.
MAX_CUTOUTS = 64
#: How far past a cut-out hit the next cast starts: a fraction of the ray parameter (and at
#: least ``CUTOUT_STEP_MIN``): beyond the float32 rounding of that hit and of a coincident
#: back face (leaves modelled as two faces), 50 µm at 5 m.
CUTOUT_STEP = 1e-5
CUTOUT_STEP_MIN = 1e-6


@dataclass
class SceneHits:
    t: FloatArray  # ray parameter of the first hit, inf where none
    label: NDArray[np.uint8]  # OTHER / SOIL / CROP / WEED / OBSTACLE
    # the instance: a plant's row of plants.csv (CROP, WEED) or an obstacle's row of
    # obstacles.csv (OBSTACLE), -1 elsewhere
    plant: NDArray[np.int32]
    proto: NDArray[np.int32]  # index in ``MeshScene.prototypes`` of what was hit, -1 elsewhere
    prim: NDArray[np.int32]  # triangle of the prototype (plants) or of the terrain tile
    u: F32
    v: F32
    inst: NDArray[np.int32]  # top-level geometry id (see ``add_static``), -1 where no hit


@dataclass
class _Tile:
    terrain: Scene | None  # built when the tile is first attached to Embree's scene
    plants: list[int]  # plant indices
    xfm: F32  # (n, 3, 4) their transforms
    terrain_built: bool = False


class MeshScene:
    """Terrain, plants and obstacles of one scenario, ray-cast through Embree around the
    camera. ``obstacles`` (``scenario_gen.Obstacles``) are meshed in this scene's coordinates."""

    def __init__(
        self,
        terrain: Terrain,
        plants: PlantMeshes | None = None,
        tile: float = TILE,
        cache_tiles: int = CACHE_TILES,
        threads: int = 1,
        seed: int = 0,
        obstacles: Obstacles | None = None,
    ) -> None:
        self.terrain = terrain
        self.seed = int(seed)  # of the soil texture
        self.plants = plants
        self.tile = float(tile)
        self.cache_tiles = int(cache_tiles)
        xmin, ymin, xmax, ymax = terrain.bounds
        self.origin = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax), 0.0])
        self.nx = max(1, math.ceil((xmax - xmin) / self.tile))
        self.ny = max(1, math.ceil((ymax - ymin) / self.tile))
        self.dev = device()
        self.caster = Caster(self.dev, threads)
        self.top = Scene(self.dev, "medium")
        self.obstacles = (
            ObstacleMeshes.of(obstacles, self.origin)
            if obstacles is not None and len(obstacles)
            else None
        )
        # tiles are chosen within this of the view: the farthest plant or obstacle reaches
        self.reach = max(
            plants.reach if plants is not None else 0.0,
            self.obstacles.reach if self.obstacles is not None else 0.0,
        )
        self._order = np.empty(0, np.int32)
        self._labels = np.zeros(0, np.uint8)
        self._starts: dict[int, tuple[int, int]] = {}
        if plants is not None and len(plants):
            key = self._key(plants.x, plants.y)
            order = np.argsort(key, kind="stable")
            keys, first, count = np.unique(key[order], return_index=True, return_counts=True)
            self._order = order.astype(np.int32)
            self._starts = {
                int(k): (int(a), int(a + c)) for k, a, c in zip(keys, first, count, strict=True)
            }
            self._labels = np.array([p.label for p in plants.prototypes], np.uint8)
        #: prototypes whose textures have cut-outs (rays pass through those texels)
        self.cutouts = tuple(
            k
            for k, p in enumerate(plants.prototypes if plants is not None else ())
            if p.alpha is not None
        )
        self._protos: dict[int, Scene] = {}
        self._cache: OrderedDict[int, _Tile] = OrderedDict()
        self._attached: set[int] = set()
        # geometry ids in the top scene: plant i is i, terrain tile k is n_plants + k, then
        # the always-present scenes of ``add_static``
        self._n_plants = len(plants) if plants is not None else 0
        self._n_ground = self._n_plants + self.nx * self.ny
        self._statics = 0
        self._n_plant_protos = len(plants.prototypes) if plants is not None else 0
        #: every prototype: the plants', then one per obstacle (``SceneHits.proto`` indexes it)
        self.prototypes: tuple[Prototype, ...] = (
            plants.prototypes if plants is not None else ()
        ) + (self.obstacles.prototypes if self.obstacles is not None else ())
        self._obstacle_gid = -1  # the obstacles' static scene's geometry id (-1: none)
        self._obstacle_tile = np.zeros(0, np.int64)
        if self.obstacles is not None:
            ob = Scene(self.dev, "high")
            for i, pr in enumerate(self.obstacles.prototypes):  # geometry id = obstacle index
                ob.attach_triangles(i, pr.vertices, pr.faces)
            ob.commit()
            self._obstacle_scene = ob  # kept alive with the scene
            self._obstacle_gid = self.add_static(ob)
            self.top.commit()
            self._obstacle_tile = self._key(self.obstacles.x, self.obstacles.y)
        self._last_view: tuple[FloatArray, FloatArray] | None = None  # hull edge normals, offsets
        # instances_near's last answer: its tiles, plant ids, transforms and hull edges, and
        # the obstacles of those tiles
        self._near: tuple[frozenset[int], NDArray[np.int32], F32, Any] | None = None
        self._near_obstacles = np.zeros(0, np.int32)
        # the height grid as the compiled refinement (refine_rays) reads it
        self._grid: native.Geometry | None = None
        self.tiles_built = 0

    @classmethod
    def from_scenario(cls, scn: Scenario, **kwargs: object) -> MeshScene:
        return cls(
            scn.terrain,
            PlantMeshes.from_scenario(scn),
            seed=scn.seed,
            obstacles=scn.obstacles,
            **kwargs,  # type: ignore[arg-type]
        )

    # ------------------------------------------------------------------ tiles
    def _key(self, x: FloatArray, y: FloatArray) -> NDArray[np.int64]:
        t = self.terrain
        i = np.clip(np.floor((np.asarray(y) - t.y0) / self.tile), 0, self.ny - 1).astype(np.int64)
        j = np.clip(np.floor((np.asarray(x) - t.x0) / self.tile), 0, self.nx - 1).astype(np.int64)
        return i * self.nx + j

    def _proto_scene(self, k: int) -> Scene:
        sc = self._protos.get(k)
        if sc is None:
            assert self.plants is not None
            pr = self.plants.prototypes[k]
            sc = Scene(self.dev, "high")
            sc.attach_triangles(k, pr.vertices, pr.faces)  # geometry id = prototype index
            sc.commit()
            self._protos[k] = sc
        return sc

    def _terrain_scene(self, key: int) -> Scene | None:
        t = self.terrain
        ti, tj = divmod(key, self.nx)
        s = t.spacing
        ny, nx = t.shape
        c0 = min(math.floor(tj * self.tile / s), nx - 1)
        c1 = min(math.ceil((tj + 1) * self.tile / s), nx - 1)
        r0 = min(math.floor(ti * self.tile / s), ny - 1)
        r1 = min(math.ceil((ti + 1) * self.tile / s), ny - 1)
        if c1 <= c0 or r1 <= r0:
            return None
        w, h = c1 - c0 + 1, r1 - r0 + 1
        gx = t.x0 + s * np.arange(c0, c1 + 1) - self.origin[0]
        gy = t.y0 + s * np.arange(r0, r1 + 1) - self.origin[1]
        v = np.empty((h, w, 3), np.float32)
        v[..., 0] = gx[None, :]
        v[..., 1] = gy[:, None]
        v[..., 2] = t.heights[r0 : r1 + 1, c0 : c1 + 1] - self.origin[2]
        sc = Scene(self.dev, "medium", robust=True)
        sc.attach_triangles(0, v.reshape(-1, 3), _grid_faces(h, w))
        sc.commit()
        return sc

    def _build(self, key: int) -> _Tile:
        lo, hi = self._starts.get(key, (0, 0))
        ids = self._order[lo:hi].astype(np.int64)
        if hi > lo:
            assert self.plants is not None
            xfm = self.plants.transforms(ids, self.origin)
        else:
            xfm = np.zeros((0, 3, 4), np.float32)
        self.tiles_built += 1
        return _Tile(None, ids.tolist(), xfm)

    def _tile(self, key: int) -> _Tile:
        tile = self._cache.get(key)
        if tile is None:
            tile = self._build(key)
            self._cache[key] = tile
        self._cache.move_to_end(key)
        return tile

    def view(self, xy: FloatArray) -> None:
        """Attach exactly the tiles a view spanning the world points ``xy`` (k, 2) can reach."""
        pts = np.asarray(xy, np.float64).reshape(-1, 2)
        if self._last_view is not None and _still_covered(pts, self._last_view):
            return
        hull = convex_hull(pts)
        self._last_view = _edges(hull)
        want = self._tiles_near(hull, self.reach + MARGIN)
        top = self.top
        for key in sorted(self._attached - want):
            tile = self._cache[key]
            if tile.terrain is not None:
                top.detach(self._n_plants + key)
            for i in tile.plants:
                top.detach(i)
        for key in sorted(want - self._attached):
            tile = self._tile(key)
            if not tile.terrain_built:
                tile.terrain, tile.terrain_built = self._terrain_scene(key), True
            if tile.terrain is not None:
                top.attach_instance(self._n_plants + key, tile.terrain, _IDENTITY)
            if tile.plants:
                assert self.plants is not None
                proto = self.plants.proto
                for i, x in zip(tile.plants, tile.xfm, strict=True):
                    top.attach_instance(i, self._proto_scene(int(proto[i])), x)
        self._attached = want
        self._evict(want)
        top.commit()

    def instances_near(self, xy: FloatArray) -> tuple[NDArray[np.int32], F32]:
        """Plant ids and transforms (n, 12) of the tiles a view spanning the world points ``xy``
        can reach (those ``view`` would attach), for the rasteriser: no Embree scene is built.
        The arrays are reused while the set of tiles stays the same, and without a look while
        the view stays within the last one's margin (as ``view``)."""
        pts = np.asarray(xy, np.float64).reshape(-1, 2)
        if self._near is not None and _still_covered(pts, self._near[3]):
            return self._near[1], self._near[2]
        hull = convex_hull(pts)
        want = frozenset(self._tiles_near(hull, self.reach + MARGIN))
        if self._near is not None and self._near[0] == want:
            self._near = (*self._near[:3], _edges(hull))
            return self._near[1], self._near[2]
        tiles = [self._tile(k) for k in sorted(want)]
        self._evict(self._attached | want)
        ids = np.array([i for t in tiles for i in t.plants], np.int32)
        xfm = (
            np.ascontiguousarray(np.concatenate([t.xfm for t in tiles]).reshape(-1, 12))
            if len(ids)
            else np.zeros((0, 12), np.float32)
        )
        self._near = (want, ids, xfm, _edges(hull))
        self._near_obstacles = np.flatnonzero(
            np.isin(self._obstacle_tile, np.fromiter(want, np.int64, len(want)))
        ).astype(np.int32)
        return ids, xfm

    @property
    def near_obstacles(self) -> NDArray[np.int32]:
        """The obstacles of the tiles ``instances_near`` last chose (ascending indices; a new
        array exactly when its plant ids are one)."""
        return self._near_obstacles

    def _evict(self, keep: set[int] | frozenset[int]) -> None:
        """Drop the least recently used cached tiles beyond ``cache_tiles``, never ``keep``."""
        while len(self._cache) > max(self.cache_tiles, len(keep)):
            old = next(iter(self._cache))
            if old in keep:
                self._cache.move_to_end(old)
                continue
            del self._cache[old]

    def add_static(self, child: Scene) -> int:
        """Put ``child`` (world coordinates relative to ``origin``) in every view; its top-level
        geometry id, which hits on it report in ``SceneHits.inst``."""
        gid = self._n_ground + self._statics
        self._statics += 1
        self.top.attach_instance(gid, child, _IDENTITY)
        return gid

    def remove_static(self, gid: int) -> None:
        self.top.detach(gid)

    def _tiles_near(self, hull: FloatArray, grow: float) -> set[int]:
        t = self.terrain
        lo = (hull.min(axis=0) - grow - (t.x0, t.y0)) / self.tile
        hi = (hull.max(axis=0) + grow - (t.x0, t.y0)) / self.tile
        j = np.arange(max(int(lo[0]), 0), min(int(hi[0]) + 1, self.nx))
        i = np.arange(max(int(lo[1]), 0), min(int(hi[1]) + 1, self.ny))
        if len(i) == 0 or len(j) == 0:
            return set()
        jj, ii = np.meshgrid(j, i)
        cx = t.x0 + (jj.ravel() + 0.5) * self.tile
        cy = t.y0 + (ii.ravel() + 0.5) * self.tile
        half = 0.5 * self.tile + grow
        keep: NDArray[np.bool_] = np.ones(len(cx), bool)
        if len(hull) >= 3:  # separating axes: the hull's edge normals (the bbox did x and y)
            nrm, off = _edges(hull)
            near = cx[:, None] * nrm[:, 0] + cy[:, None] * nrm[:, 1]
            near -= half * (np.abs(nrm[:, 0]) + np.abs(nrm[:, 1]))
            keep = np.asarray(~(near > off + 1e-9).any(axis=1))
        keys = ii.ravel()[keep] * self.nx + jj.ravel()[keep]
        return {int(k) for k in keys}

    # ------------------------------------------------------------------ queries
    def cast(
        self,
        o: FloatArray,
        d: FloatArray,
        tnear: object = 0.0,
        tfar: object = np.inf,
        refine: bool = True,
    ) -> SceneHits:
        """First hits of world rays ``o + t·d`` (call ``view`` first for the region they span);
        ``refine=False`` leaves terrain hits on the triangles (within the cells' twist, mm: for
        shading, not for measuring)."""
        rel = (np.asarray(o, np.float64) - self.origin).astype(np.float32)
        h = self._intersect(rel, d.astype(np.float32, copy=False), tnear, tfar)
        t = h.t.astype(np.float64)
        inst = h.inst.copy()
        on_plant = (inst >= 0) & (inst < self._n_plants)
        ground = (inst >= self._n_plants) & (inst < self._n_ground)
        label = np.where(ground, SOIL, OTHER).astype(np.uint8)
        plant = np.where(on_plant, inst, -1).astype(np.int32)
        proto = np.where(on_plant, h.geom, -1).astype(np.int32)
        if on_plant.any():
            label[on_plant] = self._labels[proto[on_plant]]
        if self._obstacle_gid >= 0:
            on_obs = inst == self._obstacle_gid
            if on_obs.any():  # the static scene's geometry id is the obstacle's index
                label[on_obs] = OBSTACLE
                plant[on_obs] = h.geom[on_obs]
                proto[on_obs] = self._n_plant_protos + h.geom[on_obs]
        if refine and ground.any():
            oo = np.asarray(o, np.float64)
            if native.available() and oo.ndim == 1:  # the same Newton steps, compiled
                self._refine_native(oo, d, t, ground)
            else:
                t[ground] = refine_ground(
                    self.terrain, oo if oo.ndim == 1 else oo[ground], d[ground], t[ground]
                )
        return SceneHits(t, label, plant, proto, h.prim.copy(), h.u.copy(), h.v.copy(), inst)

    def _refine_native(
        self, o: FloatArray, d: Any, t: FloatArray, ground: NDArray[np.bool_]
    ) -> None:
        if self._grid is None:  # world coordinates: the rays are the caller's
            te = self.terrain
            heights = np.ascontiguousarray(te.heights, np.float64)
            self._grid = native.grid_geometry(heights, te.x0, te.y0, te.spacing)
        native.call(
            native.RefineRaysArgs(
                geom=self._grid, n=len(t), origin=o, dirs=np.ascontiguousarray(d, np.float32),
                t=t, ground=np.ascontiguousarray(ground, np.uint8),
            )
        )  # fmt: skip

    def occluded(
        self, o: FloatArray, d: FloatArray, tnear: object, tfar: object
    ) -> NDArray[np.bool_]:
        rel = (np.asarray(o, np.float64) - self.origin).astype(np.float32)
        d32 = d.astype(np.float32, copy=False)
        if not self.cutouts:
            return self.caster.occluded(self.top, rel, d32, tnear, tfar)
        h = self._intersect(rel, d32, tnear, tfar)  # an opaque texel on the segment
        return np.asarray(np.isfinite(h.t))

    def _intersect(self, rel: F32, d: F32, tnear: Any, tfar: Any) -> Hits:
        """Embree's first hits, passing through the cut-out texels of ``cutouts`` prototypes."""
        h = self.caster.intersect(self.top, rel, d, tnear, tfar)
        if not self.cutouts or len(d) == 0:
            return h
        h = Hits(h.t.copy(), h.geom.copy(), h.prim.copy(), h.inst.copy(), h.u.copy(), h.v.copy())
        todo = np.flatnonzero(self._on_cutout(h))
        for _ in range(MAX_CUTOUTS):
            if not len(todo):
                return h
            t = h.t[todo].astype(np.float64)
            start = t + np.maximum(CUTOUT_STEP * t, CUTOUT_STEP_MIN)
            far = tfar if np.ndim(tfar) == 0 else np.asarray(tfar)[todo]
            o = rel if rel.ndim == 1 else rel[todo]
            sub = self.caster.intersect(self.top, o, d[todo], start, far)
            for name in ("t", "geom", "prim", "inst", "u", "v"):
                getattr(h, name)[todo] = getattr(sub, name)
            todo = todo[self._on_cutout(sub)]
        h.t[todo], h.geom[todo], h.inst[todo] = np.inf, -1, -1  # through too many holes
        return h

    def _on_cutout(self, h: Hits) -> NDArray[np.bool_]:
        """Which hits lie on a cut-out texel of a plant."""
        assert self.plants is not None
        out = np.zeros(len(h.t), bool)
        on_plant = (h.inst >= 0) & (h.inst < self._n_plants) & np.isfinite(h.t)
        for k in self.cutouts:
            sel = np.flatnonzero(on_plant & (h.geom == k))
            if len(sel):
                pr = self.plants.prototypes[k]
                out[sel] = ~pr.opaque(h.prim[sel].astype(np.int64), h.u[sel], h.v[sel])
        return out

    @property
    def attached_tiles(self) -> int:
        return len(self._attached)


class SceneCache:
    """The ``MeshScene`` of the latest scenario (rebuilt when the scenario object changes)."""

    def __init__(self, **kwargs: object) -> None:
        self.kwargs = kwargs
        self._scn: Scenario | None = None
        self._scene: MeshScene | None = None

    def get(self, scn: Scenario) -> MeshScene:
        if self._scene is None or self._scn is not scn:
            self._scene = MeshScene.from_scenario(scn, **self.kwargs)
            self._scn = scn
        return self._scene


_IDENTITY = np.hstack([np.eye(3), np.zeros((3, 1))]).astype(np.float32)
_FACES: dict[tuple[int, int], NDArray[np.uint32]] = {}


def _grid_faces(h: int, w: int) -> NDArray[np.uint32]:
    """Two triangles per cell of an h × w vertex grid, split as ``Terrain.to_trimesh``."""
    f = _FACES.get((h, w))
    if f is None:
        a = (np.arange(h - 1)[:, None] * w + np.arange(w - 1)[None, :]).ravel()
        f = np.concatenate(
            [np.column_stack([a, a + 1, a + w + 1]), np.column_stack([a, a + w + 1, a + w])]
        ).astype(np.uint32)
        _FACES[(h, w)] = f
    return f


def _still_covered(pts: FloatArray, edges: tuple[FloatArray, FloatArray]) -> bool:
    """Whether tiles chosen for a hull (its ``_edges``) grown by MARGIN still serve a view
    through ``pts``: enough while the points stay within half of that margin."""
    nrm, off = edges
    return len(off) == 0 or bool((pts @ nrm.T <= off + 0.5 * MARGIN).all())


def _edges(hull: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit outward normals and offsets (n·p <= off inside) of a CCW polygon's edges."""
    if len(hull) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    edge = np.roll(hull, -1, axis=0) - hull
    nrm = np.column_stack([edge[:, 1], -edge[:, 0]])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    return nrm, (nrm * hull).sum(axis=1)


def convex_hull(pts: FloatArray) -> FloatArray:
    """Counter-clockwise convex hull of 2-D points (Andrew's monotone chain)."""
    p = np.unique(np.asarray(pts, np.float64), axis=0)
    if len(p) <= 2:
        return p

    def half(points: FloatArray) -> list[FloatArray]:
        out: list[FloatArray] = []
        for q in points:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                if (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]) > 0:
                    break
                out.pop()
            out.append(q)
        return out

    lower, upper = half(p), half(p[::-1])
    return np.array(lower[:-1] + upper[:-1])


def refine_ground(
    terrain: Terrain, o: FloatArray, d: FloatArray, t: FloatArray, iterations: int = 3
) -> FloatArray:
    """Ray parameters moved from the terrain triangles onto the bilinear height surface.

    Newton on f(t) = o_z + t·d_z − h(o_xy + t·d_xy). Within one grid cell f is a quadratic in
    t whose curvature is the cell's twist, so from the triangle's t (a few mm away) one step
    leaves an error of order twist·step² (≪ 1e-6 m) — rays whose step stays in their cell are
    done after it; the others repeat until within 1e-6 m. A ray that does not converge (grazing
    a ridge) keeps the triangle's t, within the cell's twist (a few mm) of the surface.
    """
    o = np.asarray(o, np.float64)
    d = np.asarray(d, np.float64)
    t0 = np.asarray(t, np.float64)
    t = t0.copy()
    todo = np.arange(len(t))
    s = terrain.spacing
    for k in range(iterations + 1):
        oo = o if o.ndim == 1 else o[todo]
        dd = d[todo]
        p = oo + t[todo, None] * dd
        h, hx, hy = bilinear(terrain, p[:, 0], p[:, 1])
        f = p[:, 2] - h
        open_ = np.abs(f) >= 1e-6
        todo, f, dd, hx, hy, p = todo[open_], f[open_], dd[open_], hx[open_], hy[open_], p[open_]
        if len(todo) == 0:
            return t
        df = dd[:, 2] - hx * dd[:, 0] - hy * dd[:, 1]
        step = np.clip(f / np.where(np.abs(df) > 1e-9, df, np.inf), -0.05, 0.05)
        t[todo] -= step
        if k == 0:  # one step that stays in its cell has converged (see above)
            q = p[:, :2] - step[:, None] * dd[:, :2]
            cell = np.floor((p[:, :2] - (terrain.x0, terrain.y0)) / s)
            moved = (np.floor((q - (terrain.x0, terrain.y0)) / s) != cell).any(axis=1)
            todo = todo[moved]
            if len(todo) == 0:
                return t
    oo = o if o.ndim == 1 else o[todo]
    p = oo + t[todo, None] * d[todo]
    h, _, _ = bilinear(terrain, p[:, 0], p[:, 1])
    bad = np.abs(p[:, 2] - h) >= 1e-5
    t[todo[bad]] = t0[todo[bad]]
    return t


def bilinear(terrain: Terrain, x: FloatArray, y: FloatArray) -> tuple[FloatArray, ...]:
    """Height and its x, y derivatives on the bilinear surface (as ``Terrain.height_at``)."""
    ny, nx = terrain.shape
    s = terrain.spacing
    u = np.clip((x - terrain.x0) / s, 0.0, nx - 1.0)
    v = np.clip((y - terrain.y0) / s, 0.0, ny - 1.0)
    j = np.minimum(u.astype(np.intp), nx - 2)
    i = np.minimum(v.astype(np.intp), ny - 2)
    fu, fv = u - j, v - i
    g = terrain.heights.reshape(-1)
    k = i * nx + j
    h00, h01 = g.take(k), g.take(k + 1)
    h10, h11 = g.take(k + nx), g.take(k + nx + 1)
    a, b = h01 - h00, h11 - h10
    z0 = h00 + a * fu
    z1 = h10 + b * fu
    dz = z1 - z0
    return z0 + dz * fv, (a + (b - a) * fv) / s, dz / s
