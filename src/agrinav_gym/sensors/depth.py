"""The analytic depth camera (the fast proxy of the D455): terrain and plant cylinders.

Rendering a pybullet image costs 6-42 ms here (DESIGN §8); this casts one ray per pixel
against the terrain's bilinear height surface and against the plants as vertical capped
cylinders (``PlantField``). Where the compiled kernels are built (sensors/native.py) one call
per frame intersects both exactly in double precision (csrc/proxycast.c: the bilinear surface
cell by cell as a quadratic in t, the cylinders through a grid of cells); elsewhere both go
through Embree in one query (``MeshScene``): the terrain's triangles bracket each crossing and
Newton puts it on the bilinear surface, the cylinders are Embree's capped cones of equal
radii. ``ground_hits`` (a march with secant refinement) and ``plant_hits`` (cylinders paired
with rays through their azimuth intervals) are the same geometry in numpy: the references both
fast paths are tested against.

Depth is z-depth along the optical axis, as the D455 reports it. Noise follows the stereo
error law σ_z = z²·s / (f·B) with the native sensor's focal length; pixels outside
[min_range, max_range] or without a hit read 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Terrain

from ..config import CameraConfig
from ..interface import CameraModel
from ..sim.mesh_scene import MeshScene
from ..sim.plants import PlantField
from ..sim.world import SOIL_RGB
from . import native, pixel_noise
from .embree import Scene
from .shading import Lighting

FloatArray = NDArray[np.float64]
OTHER, SOIL, CROP, WEED = 0, 1, 2, 3
MARCH_STEP = 0.15  # m between terrain samples along a ray before the secant refinement
MAX_MARCH = 24


@dataclass
class DepthFrame:
    depth: NDArray[np.float32]  # (H, W) metres, 0 = invalid
    label: NDArray[np.uint8] | None = None  # (H, W) OTHER/SOIL/CROP/WEED(/ROBOT)
    rgb: NDArray[np.uint8] | None = None  # (H, W, 3)
    # mesh camera only: plant index (row of plants.csv) per depth pixel, -1 elsewhere, and
    # the labels of the colour camera's own pixels (RGB is seen from the colour camera)
    instance: NDArray[np.int32] | None = None
    rgb_label: NDArray[np.uint8] | None = None
    rgb_instance: NDArray[np.int32] | None = None


class DepthCamera(Lighting):
    """``model`` gives intrinsics and mount (the public ``RobotInterface.camera``); ``cfg`` the
    sensor's noise, range and outputs."""

    def __init__(self, cfg: CameraConfig, model: CameraModel) -> None:
        self.cfg = cfg
        d = model.pixel_rays()
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        self.forward = d[:, 0].copy()  # cos of the angle to the optical axis
        self.rays_body = d @ model.rotation.T  # +pitch about y tilts the axis down
        self.mount = np.asarray(model.position, np.float64)
        self.edge = corner_pixels(model.width, model.height)
        self.t_lim = (cfg.max_range + 0.05) / self.forward  # ray length to the far limit
        self._ground: tuple[Terrain, MeshScene] | None = None
        self._scene: tuple[Terrain, MeshScene] | None = None
        self._cylinders: tuple[PlantField, int] | None = None
        self._proxy: ProxyGeometry | None = None
        self.f_native = 0.5 * cfg.native_width / math.tan(math.radians(cfg.hfov_deg) / 2)
        self._init_lighting(SOIL_RGB)

    def noise_sigma(self, z: FloatArray) -> FloatArray:
        return z * z * self.cfg.subpixel / (self.f_native * self.cfg.baseline)

    def pose(self, rot: FloatArray, pos: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Camera origin and world ray directions for a base pose (rot: body -> world)."""
        return pos + rot @ self.mount, self.rays_body @ rot.T

    def render(
        self,
        rot: FloatArray,
        pos: FloatArray,
        terrain: Terrain,
        plants: PlantField,
        rng: np.random.Generator | None,
        rgb: bool = False,
        labels: bool = False,
    ) -> DepthFrame:
        cfg = self.cfg
        o = pos + rot @ self.mount
        key = None  # one draw a frame, whatever the scene (pixel_noise)
        if rng is not None and cfg.subpixel > 0:
            key = pixel_noise.frame_key(rng)
        kernels = native.lib()
        rays = None  # world directions, made only where needed (the kernel turns body rays)
        if kernels is not None:  # one cast, then noise and validity in one call (finish_depth)
            g = self._proxy_geometry(terrain, plants)
            t, what = g.cast_raw(o, self.rays_body, self.t_lim, rot)
            depth = np.empty(len(t), np.float32)
            kernels.finish_depth(
                0, len(t), t.ctypes.data, self.forward.ctypes.data, *pixel_noise.kernel_args(key),
                cfg.subpixel / (self.f_native * cfg.baseline), cfg.min_range, cfg.max_range,
                None, depth.ctypes.data, None, None,
            )  # fmt: skip
        else:
            rays = self.rays_body @ rot.T
            t, lab = self.cast(o, rays, terrain, plants, self.t_lim)
            z = t * self.forward
            hit = np.isfinite(z)
            if key is not None:
                z[hit] += self.noise_sigma(z[hit]) * pixel_noise.normals(key, len(z))[hit]
            valid = hit & (z >= cfg.min_range) & (z <= cfg.max_range)
            depth = np.where(valid, z, 0.0).astype(np.float32)
        shape = (cfg.height, cfg.width)
        frame = DepthFrame(depth.reshape(shape))
        if labels or rgb:
            if kernels is not None:
                lab = g.labels(what)
            lab = np.where(t * self.forward <= cfg.max_range, lab, OTHER).astype(np.uint8)
            if labels:
                frame.label = lab.reshape(shape)
            if rgb:
                if rays is None:
                    rays = self.rays_body @ rot.T
                frame.rgb = self._shade(o, rays, t, lab, terrain).reshape(*shape, 3)
        return frame

    def _proxy_geometry(self, terrain: Terrain, plants: PlantField) -> ProxyGeometry:
        if self._proxy is None or not self._proxy.serves(terrain, plants):
            self._proxy = ProxyGeometry(terrain, plants)
        return self._proxy

    def cast(
        self,
        o: FloatArray,
        rays: FloatArray,
        terrain: Terrain,
        plants: PlantField,
        t_lim: FloatArray,
    ) -> tuple[FloatArray, NDArray[np.uint8]]:
        """First hit per ray within ``t_lim`` (inf where none) and its class."""
        if native.available():
            g = self._proxy_geometry(terrain, plants)
            t, what = g.cast_raw(o, rays, t_lim)
            return t, g.labels(what)
        if self._scene is None or self._scene[0] is not terrain:
            self._scene = (terrain, MeshScene(terrain))
            self._cylinders = None
        scene = self._scene[1]
        if self._cylinders is None or self._cylinders[0] is not plants:
            if self._cylinders is not None and self._cylinders[1] >= 0:
                scene.remove_static(self._cylinders[1])
            gid = -1
            if len(plants.radius):
                cyl = Scene(scene.dev, "medium")
                base = np.column_stack([plants.xy, plants.z]) - scene.origin
                top = np.column_stack([plants.xy, plants.top]) - scene.origin
                cyl.attach_cylinders(0, base, top, plants.radius.astype(np.float32))
                cyl.commit()
                gid = scene.add_static(cyl)
            self._cylinders = (plants, gid)
        gid = self._cylinders[1]
        e = self.edge
        scene.view(np.vstack([o[None, :2], (o + rays[e] * t_lim[e, None])[:, :2]]))
        h = scene.cast(o, rays, 0.0, t_lim)
        on = (h.inst == gid) & (gid >= 0)
        weed = plants.is_weed[np.where(on, h.prim, 0)] if len(plants.radius) else on
        lab = np.where(on, np.where(weed, WEED, CROP), h.label).astype(np.uint8)
        return h.t, lab

    def ground(
        self, o: FloatArray, rays: FloatArray, terrain: Terrain, t_lim: FloatArray
    ) -> FloatArray:
        """``ground_hits`` through Embree: the terrain's triangles bracket each crossing, Newton
        puts it on the bilinear surface (equal to the march within 1e-5 m, several × faster)."""
        if self._ground is None or self._ground[0] is not terrain:
            self._ground = (terrain, MeshScene(terrain))
        scene = self._ground[1]
        e = self.edge
        scene.view(np.vstack([o[None, :2], (o + rays[e] * t_lim[e, None])[:, :2]]))
        return scene.cast(o, rays, 0.0, t_lim).t

    def _shade(
        self,
        o: FloatArray,
        rays: FloatArray,
        t: FloatArray,
        lab: NDArray[np.uint8],
        terrain: Terrain,
    ) -> NDArray[np.uint8]:
        colours = np.array([[0.62, 0.76, 0.94], [0, 0, 0], [0.22, 0.55, 0.16], [0.62, 0.62, 0.2]])
        out = colours[lab]
        soil = lab == SOIL
        if soil.any():
            hit = o + rays[soil] * t[soil, None]
            n = terrain.normal_at(hit[:, 0], hit[:, 1])
            out[soil] = self.soil_rgb * (0.35 + 0.65 * np.clip(n @ self.light, 0, 1))[:, None]
        plant = (lab == CROP) | (lab == WEED)
        out[plant] *= (0.8 + 0.2 * np.clip(-rays[plant, 2], 0, 1))[:, None]
        return (np.clip(out, 0, 1) * 255).astype(np.uint8)


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
        te = self.terrain
        ny, nx = self.h.shape
        native.require("the proxy camera").proxy_cast(
            n, o.ctypes.data, d.ctypes.data, native.ptr(r), lim.ctypes.data, self.ztop,
            self.h.ctypes.data,
            nx, ny, te.x0, te.y0, te.spacing, self.bmax.ctypes.data, self.BLOCK, self.bnx,
            self.bny, self.gnx, self.gny, self.gx, self.gy, self.CELL, self.start.ctypes.data,
            self.items.ctypes.data, self.item_cyl.ctypes.data, t.ctypes.data, what.ctypes.data,
        )  # fmt: skip
        return t, what

    def labels(self, what: NDArray[np.int32]) -> NDArray[np.uint8]:
        lab = np.full(len(what), OTHER, np.uint8)
        lab[what == -1] = SOIL
        on = what >= 0
        if on.any():
            lab[on] = np.where(self.weed[what[on]], WEED, CROP)
        return lab


def corner_pixels(width: int, height: int) -> NDArray[np.int64]:
    """The four corner pixels: a frustum's ground footprint is the hull of the apex and the far
    ends of the corner rays (the projection of a convex pyramid)."""
    return np.array([0, width - 1, (height - 1) * width, height * width - 1], np.int64)


def ground_hits(o: FloatArray, rays: FloatArray, terrain: Terrain, t_lim: FloatArray) -> FloatArray:
    """Ray length to the first terrain crossing (inf where none within ``t_lim``): a bracketed
    march with secant refinement, the reference ``DepthCamera.ground`` is tested against."""
    reach = float(t_lim.max())
    s = terrain.spacing
    ny, nx = terrain.shape
    j0 = max(int((o[0] - reach - terrain.x0) / s), 0)
    j1 = min(int((o[0] + reach - terrain.x0) / s) + 2, nx)
    i0 = max(int((o[1] - reach - terrain.y0) / s), 0)
    i1 = min(int((o[1] + reach - terrain.y0) / s) + 2, ny)
    window = terrain.heights[i0:i1, j0:j1] if (i1 > i0 and j1 > j0) else terrain.heights
    # a slab a little thicker than the local relief, so a flat field still brackets the crossing
    zlo, zhi = float(window.min()) - 1e-3, float(window.max()) + 1e-3
    dz = rays[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (zlo - o[2]) / dz
        b = (zhi - o[2]) / dz
    t_in = np.where(dz != 0, np.minimum(a, b), np.where(zlo <= o[2] <= zhi, 0.0, np.inf))
    t_out = np.where(dz != 0, np.maximum(a, b), np.where(zlo <= o[2] <= zhi, np.inf, -np.inf))
    t_in = np.maximum(t_in, 0.0)
    t_out = np.minimum(t_out, t_lim)
    live = t_in < t_out
    out = np.full(len(rays), np.inf)
    if not live.any():
        return out
    r = rays[live]
    ta, tb = t_in[live], t_out[live]
    # The ray can only cross the terrain inside the slab [zlo, zhi] of the local window, so the
    # march covers that stretch only: a few samples on a furrowed field, more on a hillside.
    span = float(np.percentile(tb - ta, 90))
    samples = int(np.clip(math.ceil(span / MARCH_STEP) + 1, 4, MAX_MARCH))
    ts = ta[:, None] + (tb - ta)[:, None] * np.linspace(0.0, 1.0, samples)[None, :]

    def f(t: FloatArray, rr: FloatArray) -> FloatArray:
        return (
            o[2] + t * rr[..., 2] - terrain.height_at(o[0] + t * rr[..., 0], o[1] + t * rr[..., 1])
        )

    fs = f(ts, r[:, None, :])
    below = fs <= 0.0
    hit = below.any(axis=1)
    if not hit.any():
        return out
    k = np.argmax(below, axis=1)[hit]
    rows = np.flatnonzero(hit)
    r = r[hit]
    km = np.maximum(k - 1, 0)
    t0, t1 = ts[rows, km], ts[rows, k]
    f0, f1 = fs[rows, km], fs[rows, k]
    for _ in range(2):  # secant / regula falsi refinement of the bracket
        tm = np.where(f0 != f1, t0 + f0 * (t1 - t0) / np.where(f0 != f1, f0 - f1, 1.0), t1)
        fm = f(tm, r)
        above = fm > 0
        t0, f0 = np.where(above, tm, t0), np.where(above, fm, f0)
        t1, f1 = np.where(above, t1, tm), np.where(above, f1, fm)
    tm = np.where(f0 != f1, t0 + f0 * (t1 - t0) / np.where(f0 != f1, f0 - f1, 1.0), t1)
    idx = np.flatnonzero(live)[rows]
    out[idx] = tm
    return out


def plant_hits(
    o: FloatArray, rays: FloatArray, plants: PlantField, t_lim: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Ray length to the nearest plant cylinder (side, top or bottom) and whether it is a weed."""
    n = len(rays)
    t_best = np.full(n, np.inf)
    weed = np.zeros(n, bool)
    if len(plants) == 0:
        return t_best, weed
    reach = float(t_lim.max()) + plants.max_radius
    cand = np.asarray(plants.tree.query_ball_point(o[:2], reach), dtype=np.int64)
    if len(cand) == 0:
        return t_best, weed
    rel = plants.xy[cand] - o[:2]
    dist = np.hypot(rel[:, 0], rel[:, 1])
    rad = plants.radius[cand]
    # a cylinder whose disc holds the camera, seen by rays of any azimuth: from below or above
    # it, its cap; from inside it, the wall or cap the ray leaves through (as Embree's cones)
    for k in cand[dist <= rad]:
        z0, z1, r2 = plants.z[k], plants.top[k], plants.radius[k] ** 2
        cx, cy = o[0] - plants.xy[k, 0], o[1] - plants.xy[k, 1]
        dz = rays[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            if z0 <= o[2] <= z1:
                a = rays[:, 0] ** 2 + rays[:, 1] ** 2
                b = cx * rays[:, 0] + cy * rays[:, 1]
                side = (-b + np.sqrt(b * b - a * (cx * cx + cy * cy - r2))) / a
                cap = np.where(dz > 0, (z1 - o[2]) / dz, np.where(dz < 0, (z0 - o[2]) / dz, np.inf))
                tc = np.fmin(np.where(a > 0, side, np.inf), cap)
                ok = tc > 0
            else:
                tc = ((z0 if o[2] < z0 else z1) - o[2]) / dz
                px, py = cx + tc * rays[:, 0], cy + tc * rays[:, 1]
                ok = (tc > 0) & (px * px + py * py <= r2)
        ok &= tc < t_best
        t_best[ok] = tc[ok]
        weed[ok] = plants.is_weed[k]
    heading = math.atan2(float(rays[:, 1].mean()), float(rays[:, 0].mean()))
    az_p = np.angle(np.exp(1j * (np.arctan2(rel[:, 1], rel[:, 0]) - heading)))
    keep = (dist > rad) & (np.abs(az_p) < math.radians(100))
    cand, rel, dist, rad, az_p = cand[keep], rel[keep], dist[keep], rad[keep], az_p[keep]
    if len(cand) == 0:
        return t_best, weed
    half = np.arcsin(np.clip(rad / dist, 0.0, 1.0))
    az_r = np.angle(np.exp(1j * (np.arctan2(rays[:, 1], rays[:, 0]) - heading)))
    order = np.argsort(az_r, kind="stable")
    az_sorted = az_r[order]
    lo = np.searchsorted(az_sorted, az_p - half, side="left")
    hi = np.searchsorted(az_sorted, az_p + half, side="right")
    counts = hi - lo
    total = int(counts.sum())
    if total == 0:
        return t_best, weed
    pl = np.repeat(np.arange(len(cand)), counts)
    offset = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    ray = order[np.repeat(lo, counts) + offset]
    # Elevation cull: a ray can only meet a cylinder if its slope dz/dh lies between the
    # lowest and highest slopes of the cylinder's points as seen from the camera. Most pairs
    # of the azimuth test fail it (a short plant 5 m away spans a few pixel rows).
    zb_c, zt_c = plants.z[cand] - o[2], plants.top[cand] - o[2]
    near, far = dist - rad, dist + rad
    s_lo = zb_c / np.where(zb_c < 0, near, far)
    s_hi = zt_c / np.where(zt_c >= 0, near, far)
    slope = rays[:, 2] / np.hypot(rays[:, 0], rays[:, 1])
    s_ray = slope[ray]
    sel = (s_ray >= s_lo[pl] - 1e-9) & (s_ray <= s_hi[pl] + 1e-9)
    ray, pl = ray[sel], pl[sel]
    if len(ray) == 0:
        return t_best, weed
    d = rays[ray]
    ox, oy = -rel[pl, 0], -rel[pl, 1]
    r2 = rad[pl] ** 2
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (ox * d[:, 0] + oy * d[:, 1])
    c = ox * ox + oy * oy - r2
    disc = b * b - 4 * a * c
    with np.errstate(invalid="ignore", divide="ignore"):
        t_side = (-b - np.sqrt(disc)) / (2 * a)
    zb, zt = zb_c[pl] + o[2], zt_c[pl] + o[2]
    z_side = o[2] + t_side * d[:, 2]
    side_ok = (disc >= 0) & (t_side > 0) & (z_side >= zb) & (z_side <= zt)
    with np.errstate(invalid="ignore", divide="ignore"):
        t_cap = (zt - o[2]) / d[:, 2]
        cx, cy = ox + t_cap * d[:, 0], oy + t_cap * d[:, 1]
    cap_ok = (d[:, 2] < 0) & (t_cap > 0) & (cx * cx + cy * cy <= r2)
    t_pair = np.where(side_ok, t_side, np.inf)
    t_pair = np.where(cap_ok, np.minimum(t_pair, t_cap), t_pair)
    # a leaf band above the camera is seen from below
    with np.errstate(invalid="ignore", divide="ignore"):
        t_bot = (zb - o[2]) / d[:, 2]
        bx, by = ox + t_bot * d[:, 0], oy + t_bot * d[:, 1]
    bot_ok = (d[:, 2] > 0) & (t_bot > 0) & (bx * bx + by * by <= r2)
    t_pair = np.where(bot_ok, np.minimum(t_pair, t_bot), t_pair)
    ok = np.isfinite(t_pair)
    if not ok.any():
        return t_best, weed
    ray, t_pair, pl = ray[ok], t_pair[ok], pl[ok]
    np.minimum.at(t_best, ray, t_pair)
    winner = t_pair == t_best[ray]
    weed[ray[winner]] = plants.is_weed[cand[pl[winner]]]
    return t_best, weed
