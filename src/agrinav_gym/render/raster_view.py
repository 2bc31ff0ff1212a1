"""The mesh camera's views by rasterisation: the compiled twin of its Embree ray casts.

For a pinhole camera the first hit of the ray through each pixel centre is what a z-buffer
rasteriser computes, so for the large frames of datasets (848 × 480) the mesh camera draws its
views (csrc/raster.c) instead of casting 407k rays: the plants of the tiles around the view,
culled by bounding sphere, and the terrain grid, culled in blocks, into a visibility buffer
(1/z, instance slot, triangle). The per-pixel work then runs compiled as well (csrc/frame.c):
terrain hits refined onto the bilinear surface as ``refine_ground`` does, labels, the D455's
stereo invalidation, noise, and the colour camera's shading. The geometry, the images and the
noise stream are those of the ray-cast path; tests compare the two pixel by pixel.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

from ..interface import CameraModel
from . import native, pixel_noise, shading
from .mesh_scene import MeshScene
from .plant_meshes import Prototype

ZNEAR = 1e-3  # m: the ray casts start at the camera; nothing of the scene comes this close

#: a row-major 3×4 identity transform: an obstacle's slot (its vertices are in scene coordinates)
_IDENTITY_ROW = np.array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], np.float32)


@dataclass
class VisBuffer:
    """A rasterised view: per pixel 1/z (0: nothing), instance slot (-1 none, -2 terrain) and
    triangle.

    ``hiz`` says whether the view keeps coarse depth tiles to skip hidden geometry. Under a
    maize canopy that saves a third of a view; in an open field the triangles it skips are cheap
    ones and the bookkeeping costs more. The image is the same either way, so each view uses
    whichever was faster, timing both now and then (every ``PROBE`` frames the other one)."""

    iz: NDArray[np.float32]
    inst: NDArray[np.int32]
    prim: NDArray[np.int32]
    hiz: bool = True
    frames: int = 0
    seconds: float = 0.0  # drawing this frame (both bands)
    cost: dict[bool, float] = field(default_factory=dict)  # smoothed seconds, by ``hiz``
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)  # for ``seconds``

    PROBE = 8

    def next_frame(self) -> None:
        if self.frames:
            old = self.cost.get(self.hiz)
            self.cost[self.hiz] = self.seconds if old is None else 0.5 * (old + self.seconds)
        self.frames += 1
        if len(self.cost) < 2 or self.frames % self.PROBE == 0:
            self.hiz = not self.hiz if self.frames > 1 else True
        else:
            self.hiz = self.cost[True] <= self.cost[False]
        self.seconds = 0.0


@dataclass
class Resolved:
    """Per pixel of a view: ray length (inf: none), class, plant id, prototype and triangle."""

    t: FloatArray
    label: NDArray[np.uint8]
    plant: NDArray[np.int32]
    proto: NDArray[np.int32]
    prim: NDArray[np.int32]


def camera_params(
    model: CameraModel,
    rot: FloatArray,
    pos: FloatArray,
    origin: FloatArray,
    zfar: float,
    lateral: float = 0.0,
) -> native.Camera:
    """The kernels' camera for ``model`` on a base at ``pos``/``rot``, in scene coordinates
    (world minus ``origin``); ``lateral`` moves it that far to its right."""
    r_wc = rot @ model.rotation  # camera body -> world
    o = pos + rot @ np.asarray(model.position, np.float64) - origin - lateral * r_wc[:, 1]
    return native.Camera(
        origin=o, rot=r_wc.T.ravel(), fx=model.fx, fy=model.fy, cx=model.cx, cy=model.cy,
        znear=ZNEAR, zfar=zfar, width=model.width, height=model.height,
    )  # fmt: skip


#: Faces per culling cluster (cluster_spheres): measured, see docs/camera.md.
CLUSTER_FACES = 32


class SceneGeometry:
    """A ``MeshScene``'s prototypes, terrain and shading tables as the kernels read them, and
    the plant instances near the current view. Built once per scene; keeps the arrays alive.

    Obstacles are prototypes of their own (after the plants', as ``MeshScene.prototypes``),
    their vertices already in scene coordinates: each obstacle near the view is a slot with the
    identity transform after the plants' slots, its plant id the obstacle's index."""

    def __init__(self, scene: MeshScene) -> None:
        self.scene = scene
        protos: tuple[Prototype, ...] = scene.prototypes
        self.protos = protos
        self._n_plant_protos = len(scene.plants.prototypes) if scene.plants else 0
        self._v = [np.ascontiguousarray(p.vertices, np.float32) for p in protos]
        self._f = [np.ascontiguousarray(p.faces, np.uint32) for p in protos]
        self.vaddr = np.array([a.ctypes.data for a in self._v], np.int64)
        self.faddr = np.array([a.ctypes.data for a in self._f], np.int64)
        self._adj = [face_adjacency(v, f) for v, f in zip(self._v, self._f, strict=True)]
        self.adjaddr = np.array([a.ctypes.data for a in self._adj], np.int64)
        self.nv = np.array([len(a) for a in self._v], np.int32)
        self.nf = np.array([len(a) for a in self._f], np.int32)
        self.sphere = np.zeros((max(len(protos), 1), 4), np.float32)
        for k, v in enumerate(self._v):
            if len(v):
                c = 0.5 * (v.min(axis=0) + v.max(axis=0))
                self.sphere[k, :3] = c
                self.sphere[k, 3] = float(np.linalg.norm(v - c, axis=1).max())
        self._clusters = [
            cluster_spheres(v, f, CLUSTER_FACES) for v, f in zip(self._v, self._f, strict=True)
        ]
        self.claddr = np.array([a.ctypes.data for a in self._clusters], np.int64)
        self.labels = np.array([p.label for p in protos] or [0], np.uint8)
        t, o = scene.terrain, scene.origin
        self.heights = np.ascontiguousarray(t.heights, np.float64)
        self._grid = (t.x0 - o[0], t.y0 - o[1], t.spacing)
        # shading: all prototypes' faces in one table, textures by address
        counts = [len(f) for f in self._f]
        self.face_offset = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        self.face_rgb = np.ascontiguousarray(
            np.concatenate([p.face_rgb for p in protos]) if protos else np.zeros((1, 3)), np.uint8
        )
        self.face_normal = np.ascontiguousarray(
            np.concatenate([p.normals for p in protos]) if protos else np.zeros((1, 3)),
            np.float32,
        )
        self._tex: list[Any] = []
        self.tex_image = np.zeros(max(len(protos), 1), np.int64)
        self.tex_uv = np.zeros(max(len(protos), 1), np.int64)
        self.tex_hw = np.zeros(2 * max(len(protos), 1), np.int32)
        for k, p in enumerate(protos):
            if p.texture is not None and p.uv is not None:
                img = np.ascontiguousarray(p.texture, np.uint8)
                uv = np.ascontiguousarray(p.uv, np.float32)
                self._tex += [img, uv]
                self.tex_image[k], self.tex_uv[k] = img.ctypes.data, uv.ctypes.data
                self.tex_hw[2 * k : 2 * k + 2] = img.shape[:2]
        soil = tiled_texture(scene.seed)
        self.materials = native.Materials(
            face_offset=self.face_offset, face_rgb=self.face_rgb, face_normal=self.face_normal,
            tex_image=self.tex_image, tex_uv=self.tex_uv, tex_hw=self.tex_hw, soil=soil,
            soil_n=soil.shape[0],
        )  # fmt: skip
        self._near_ids: NDArray[np.int32] | None = None
        self.use(np.zeros(0, np.int32), np.zeros((0, 12), np.float32))

    def use(
        self,
        plant_ids: NDArray[np.int32],
        xfm: NDArray[np.float32],
        obstacles: NDArray[np.int32] | None = None,
    ) -> None:
        """Make these plants (ids, row-major 3×4 transforms) and ``obstacles`` (indices) the
        instance slots."""
        pm = self.scene.plants
        proto = pm.proto[plant_ids] if pm is not None and len(plant_ids) else np.zeros(0)
        if obstacles is not None and len(obstacles):
            ob = np.asarray(obstacles, np.int32)
            plant_ids = np.concatenate([np.asarray(plant_ids, np.int32), ob])
            xfm = np.concatenate(
                [np.asarray(xfm, np.float32).reshape(-1, 12), np.tile(_IDENTITY_ROW, (len(ob), 1))]
            )
            proto = np.concatenate([proto, self._n_plant_protos + ob])
        self.slot_plant = np.ascontiguousarray(plant_ids, np.int32)
        self.xfm = np.ascontiguousarray(xfm, np.float32)
        self.slot_proto = np.ascontiguousarray(proto, np.int32)
        if not len(self.slot_plant):  # the kernels read one slot's worth of pointers
            self.slot_proto = np.zeros(1, np.int32)
            self.xfm = np.zeros((1, 12), np.float32)
        x0, y0, spacing = self._grid
        ny, nx = self.heights.shape
        self.geom = native.Geometry(
            n_slots=len(self.slot_plant),
            n_protos=len(self.protos),
            slot_proto=self.slot_proto,
            xfm=self.xfm,
            proto_vertices=self.vaddr if len(self.vaddr) else None,
            proto_faces=self.faddr if len(self.faddr) else None,
            proto_nv=self.nv if len(self.nv) else None,
            proto_nf=self.nf if len(self.nf) else None,
            proto_sphere=self.sphere,
            proto_adj=self.adjaddr if len(self.adjaddr) else None,
            proto_clusters=self.claddr if len(self.claddr) else None,
            cluster=CLUSTER_FACES,
            heights=self.heights,
            nx=nx,
            ny=ny,
            x0=x0,
            y0=y0,
            spacing=spacing,
        )

    def near(self, xy: FloatArray) -> None:
        """Slots for the plants and obstacles of every tile a view spanning world points ``xy``
        can reach."""
        ids, xfm = self.scene.instances_near(xy)
        if ids is not self._near_ids:
            self.use(ids, xfm, self.scene.near_obstacles)
            self._near_ids = ids

    # ------------------------------------------------------------------ kernels
    # Each takes a band of rows [r0, r1): two threads work on one view's two bands at once; a
    # view's size is its camera's.
    def draw(self, cam: native.Camera, vb: VisBuffer, r0: int, r1: int) -> None:
        t0 = time.perf_counter()
        native.call(
            native.RasterViewArgs(
                cam=cam, geom=self.geom, terrain=1, hiz=int(vb.hiz), iz=vb.iz, inst=vb.inst,
                prim=vb.prim, row0=r0, row1=r1,
            )
        )  # fmt: skip
        with vb.lock:  # both bands, drawn at once: what the view costs the CPU
            vb.seconds += time.perf_counter() - t0

    def resolve(
        self,
        cam: native.Camera,
        forward: FloatArray,
        vb: VisBuffer,
        out: Resolved,
        refine: bool,
        robot: tuple[FloatArray, NDArray[np.int32]] | None,
        r0: int,
        r1: int,
    ) -> None:
        native.call(
            native.ResolveViewArgs(
                cam=cam,
                geom=self.geom,
                forward=forward,
                vis_iz=vb.iz,
                vis_inst=vb.inst,
                vis_prim=vb.prim,
                slot_plant=self.slot_plant if len(self.slot_plant) else None,
                proto_label=self.labels,
                refine_terrain=int(refine),
                robot_t=robot[0] if robot else None,
                robot_prim=robot[1] if robot else None,
                t=out.t,
                label=out.label,
                plant=out.plant,
                proto=out.proto,
                prim=out.prim,
                row0=r0,
                row1=r1,
            )
        )

    def stereo_prepare(
        self,
        w: int,
        h: int,
        fx: float,
        baseline: float,
        left: Resolved,
        forward: FloatArray,
        scratch: FloatArray,
        r0: int,
        r1: int,
    ) -> None:
        """Rows r0..r1 of ``scratch`` (3 h·w: FrameBuffers.stereo) for ``stereo``."""
        native.call(
            native.StereoPrepareArgs(
                width=w, height=h, fx=fx, baseline=baseline, t=left.t, forward=forward,
                scratch=scratch, row0=r0, row1=r1,
            )
        )  # fmt: skip

    def stereo(
        self,
        cam: native.Camera,
        forward: FloatArray,
        baseline: float,
        nearest: float,
        left: Resolved,
        left_vb: VisBuffer,
        right: VisBuffer,
        scratch: FloatArray,
        bad: NDArray[np.uint8],
        r0: int,
        r1: int,
    ) -> None:
        """Rows r0..r1 of ``bad``: 1 where the stereo pair cannot match, else 0 (csrc/frame.c
        ``stereo_invalid``, after ``stereo_prepare`` on every row into ``scratch``)."""
        native.call(
            native.StereoInvalidArgs(
                cam=cam,
                geom=self.geom,
                baseline=baseline,
                nearest=nearest,
                t=left.t,
                forward=forward,
                left_inst=left_vb.inst,
                left_prim=left_vb.prim,
                right_iz=right.iz,
                right_inst=right.inst,
                right_prim=right.prim,
                scratch=scratch,
                bad=bad,
                row0=r0,
                row1=r1,
            )
        )

    def shade(
        self,
        cam: native.Camera,
        forward: FloatArray,
        res: Resolved,
        vb: VisBuffer,
        par: native.Shading,
        robot: tuple[FloatArray, NDArray[np.uint8], NDArray[np.float32]] | None,
        rgb: NDArray[np.uint8],
        r0: int,
        r1: int,
    ) -> None:
        """Rows r0..r1 of the 8-bit RGB (h·w, 3) of a resolved colour view (``MeshCamera.shade``'s
        rules); ``par`` from ``shading_params``."""
        native.call(
            native.ShadeViewArgs(
                cam=cam,
                geom=self.geom,
                materials=self.materials,
                shading=par,
                forward=forward,
                t=res.t,
                label=res.label,
                vis_inst=vb.inst,
                proto=res.proto,
                prim=res.prim,
                robot_rot=robot[0] if robot else None,
                robot_rgb=robot[1] if robot else None,
                robot_normal=robot[2] if robot else None,
                rgb=rgb,
                row0=r0,
                row1=r1,
            )
        )

    def shading_params(self, soil_rgb: FloatArray, light: FloatArray, far: float) -> native.Shading:
        """The kernels' light of a colour frame (render/shading.py's constants)."""
        o = self.scene.origin
        return native.Shading(
            soil_rgb=soil_rgb, light=light, sky_horizon=shading.SKY_HORIZON,
            sky_zenith=shading.SKY_ZENITH, ambient=shading.AMBIENT, far=far, origin=o[:2],
            texel=shading.TEXEL,
        )  # fmt: skip


@lru_cache(maxsize=4)
def tiled_texture(seed: int) -> NDArray[np.float32]:
    """The soil texture (``shading.soil_texture``) stored in 8 × 8 tiles, as frame.c reads it."""
    tex = shading.soil_texture(seed)
    n = tex.shape[0]
    out = tex.reshape(n // 8, 8, n // 8, 8).transpose(0, 2, 1, 3)
    return np.ascontiguousarray(out).reshape(n, n)


def cluster_spheres(
    vertices: NDArray[np.float32], faces: NDArray[np.uint32], size: int
) -> NDArray[np.float32]:
    """(ceil(F / size), 4): centre and radius of a sphere around each run of ``size`` faces (a
    mesh's faces come leaf by leaf, so a run is a piece of one organ): the rasteriser skips a
    run outside the view, its band of rows or behind what is drawn, as it skips a plant."""
    f = np.asarray(faces, np.int64)
    n = -(-len(f) // size)
    if n == 0:
        return np.zeros((0, 4), np.float32)
    pad = np.concatenate([f, np.repeat(f[-1:], n * size - len(f), axis=0)])  # repeat the last
    p = np.asarray(vertices, np.float64)[pad.reshape(n, size * 3)]  # (n, 3 size, 3)
    centre = (0.5 * (p.min(axis=1) + p.max(axis=1))).astype(np.float32)
    reach = np.linalg.norm(p - centre[:, None, :].astype(np.float64), axis=2).max(axis=1)
    out = np.empty((n, 4), np.float32)
    out[:, :3] = centre
    # float32 rounding of the radius must not shrink the sphere
    out[:, 3] = reach * (1 + 1e-6) + 1e-7
    return out


def face_adjacency(vertices: NDArray[np.float32], faces: NDArray[np.uint32]) -> NDArray[np.int32]:
    """(F, 3): the face across edge (v0, v1), (v1, v2), (v2, v0) of each face, -1 where none.
    Vertices at the same position count as one (meshes repeat them along texture seams)."""
    f = np.asarray(faces, np.int64)
    out = np.full((len(f), 3), -1, np.int32)
    if len(f) == 0:
        return out
    _, canon = np.unique(np.asarray(vertices), axis=0, return_inverse=True)
    c = canon.reshape(-1)[f]
    a = np.stack([c, np.roll(c, -1, axis=1)], axis=-1).reshape(-1, 2)  # edge e of face i at 3i+e
    a.sort(axis=1)
    key = a[:, 0] * (int(c.max()) + 1) + a[:, 1]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])  # consecutive slots sharing an edge
    for x, y in ((order[same], order[same + 1]), (order[same + 1], order[same])):
        out.reshape(-1)[x] = (y // 3).astype(np.int32)
    return out


def finish_depth(
    res: Resolved,
    forward: FloatArray,
    key: int | None,
    k_sigma: float,
    min_range: float,
    max_range: float,
    bad: NDArray[np.uint8],
    labels: bool,
    depth: NDArray[np.float32],
    i0: int,
    i1: int,
) -> None:
    """Pixels i0..i1 of ``depth``: with the noise of the frame's ``key`` (pixel_noise; None:
    none), 0 where invalid; with ``labels`` cuts ``res``'s labels at the far limit in place."""
    native.call(
        native.FinishDepthArgs(
            i0=i0, i1=i1, t=res.t, forward=forward, **pixel_noise.kernel_args(key),
            k_sigma=k_sigma, min_range=min_range, max_range=max_range, bad=bad, depth=depth,
            label=res.label if labels else None, plant=res.plant if labels else None,
        )
    )  # fmt: skip


def new_vis(n: int) -> VisBuffer:
    return VisBuffer(np.empty(n, np.float32), np.empty(n, np.int32), np.empty(n, np.int32))


def new_resolved(n: int) -> Resolved:
    return Resolved(
        np.empty(n),
        np.empty(n, np.uint8),
        np.empty(n, np.int32),
        np.empty(n, np.int32),
        np.empty(n, np.int32),
    )


@dataclass
class FrameBuffers:
    """A camera's per-frame working arrays, kept between frames (outputs are not among them)."""

    n: int

    def __post_init__(self) -> None:
        self.views = [new_vis(self.n) for _ in range(3)]
        self.resolved = [new_resolved(self.n) for _ in range(2)]
        self.bad = np.zeros(self.n, np.uint8)
        # the stereo test's per-pixel inverse depth, best occluder after it and its column
        # (stereo_prepare), made here once: both bands write into the one array
        self.stereo = np.empty(3 * self.n)

    def parts(self) -> tuple[VisBuffer, VisBuffer, VisBuffer, Resolved, Resolved, Any]:
        for v in self.views:
            v.next_frame()
        return (*self.views, *self.resolved, self.bad)  # type: ignore[return-value]


class Bands:
    """Runs a stage of a frame as two bands of rows, the top one here and the bottom one in the
    worker thread, moving the split towards equal times frame by frame (each stage keeps its
    own). The bands are disjoint and every pixel depends only on the frame's inputs, so the
    images do not depend on where the split falls."""

    def __init__(self, h: int, threads: int) -> None:
        self.h = h
        self.threaded = threads > 1 and h >= 8
        self.split: dict[str, float] = {}

    def run(self, stage: str, fn: Any) -> list[Any]:
        """``fn(r0, r1)`` over all rows; returns the bands' results (top first)."""
        h = self.h
        if not self.threaded:
            return [fn(0, h)]
        frac = self.split.get(stage, 0.5)
        m = min(max(round(frac * h), 1), h - 1)

        def timed(r0: int, r1: int) -> tuple[float, Any]:
            t0 = time.perf_counter()
            out = fn(r0, r1)
            return time.perf_counter() - t0, out

        fut = pool().submit(timed, m, h)
        t_top, top = timed(0, m)
        t_bot, bot = fut.result()
        # per-row rates of the two bands; the split that would have balanced them, damped
        a, b = t_top / m, t_bot / (h - m)
        if a > 0 and b > 0:
            self.split[stage] = min(max(0.5 * frac + 0.5 * b / (a + b), 0.02), 0.98)
        return [top, bot]


_POOLS: dict[int, ThreadPoolExecutor] = {}
_POOL_LOCK = threading.Lock()


def pool() -> ThreadPoolExecutor:
    """One worker thread per process for the second band of a frame's stages (a forked child
    gets its own: executors do not survive ``fork``)."""
    pid = os.getpid()
    with _POOL_LOCK:
        ex = _POOLS.get(pid)
        if ex is None:
            _POOLS.clear()
            ex = ThreadPoolExecutor(max_workers=1, thread_name_prefix="agrinav-raster")
            _POOLS[pid] = ex
    return ex
