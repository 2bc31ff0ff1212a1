"""The analytic depth camera (the fast proxy of the D455): terrain and plant cylinders.

pybullet's own camera costs 6-42 ms a frame (design.md, "Measured facts to design around"); this
casts one ray per pixel against the terrain's bilinear height surface and against the plants as
vertical capped cylinders (``PlantField``; obstacles as stand-ins of the same cylinders). Where
the compiled kernels are built (render/native.py) one call per frame intersects both exactly in
double precision (csrc/proxycast.c: the bilinear surface cell by cell as a quadratic in t, the
cylinders through a grid of cells); elsewhere both go through Embree in one query
(``MeshScene``): the terrain's triangles bracket each crossing and Newton puts it on the
bilinear surface, the cylinders are Embree's capped cones of equal radii. The tests hold the
same geometry in plain numpy (``tests/agrinav_gym/oracles.py``) as the reference both fast
paths are checked against.

Depth is z-depth along the optical axis, as the D455 reports it. Noise follows the stereo
error law σ_z = z²·s / (f·B) with the native sensor's focal length; pixels outside
[min_range, max_range] or without a hit read 0.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Terrain
from scenario_gen.arrays import FloatArray

from ..config import CameraConfig
from ..interface import CameraModel
from ..render import native, pixel_noise
from ..render.classes import CROP, OBSTACLE, OTHER, SOIL, WEED
from ..render.embree import Scene
from ..render.mesh_scene import MeshScene
from ..render.proxy_geometry import ProxyGeometry
from ..render.proxy_plants import PlantField
from ..render.shading import SOIL_RGB, Lighting
from . import d455
from .camera import DepthFrame, FieldView, corner_pixels

#: the proxy's flat colours by class (OTHER: sky; SOIL is shaded; ROBOT is never drawn here;
#: OBSTACLE: a stone's grey-brown, the commonest obstacle)
PROXY_RGB = np.array(
    [
        [0.62, 0.76, 0.94],
        [0.0, 0.0, 0.0],
        [0.22, 0.55, 0.16],
        [0.62, 0.62, 0.2],
        [0.0, 0.0, 0.0],
        [0.47, 0.43, 0.38],
    ]
)


class DepthCamera(Lighting):
    """``model`` gives intrinsics and mount (the public ``RobotInterface.camera``); ``cfg`` the
    sensor's noise, range and outputs."""

    def __init__(self, cfg: CameraConfig, model: CameraModel) -> None:
        self.cfg = cfg
        self.model = model
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
        self.f_native = d455.noise_focal(cfg.native_width, cfg.hfov_deg)
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
        field: FieldView,
        rng: np.random.Generator | None,
        *,
        rgb: bool = False,
        labels: bool = False,
    ) -> DepthFrame:
        return self.draw(rot, pos, field.terrain, field.proxies, rng, rgb, labels)

    def draw(
        self,
        rot: FloatArray,
        pos: FloatArray,
        terrain: Terrain,
        plants: PlantField,
        rng: np.random.Generator | None,
        rgb: bool = False,
        labels: bool = False,
    ) -> DepthFrame:
        """``render`` on a terrain and proxy plants the caller holds."""
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
            native.call(
                native.FinishDepthArgs(
                    i0=0, i1=len(t), t=t, forward=self.forward, **pixel_noise.kernel_args(key),
                    k_sigma=cfg.subpixel / (self.f_native * cfg.baseline),
                    min_range=cfg.min_range, max_range=cfg.max_range, bad=None, depth=depth,
                    label=None, plant=None,
                )
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
        k = np.where(on, h.prim, 0)
        weed = plants.is_weed[k] if len(plants.radius) else on
        obstacle = plants.is_obstacle[k] if len(plants.radius) else on
        cls = np.where(obstacle, OBSTACLE, np.where(weed, WEED, CROP))
        lab = np.where(on, cls, h.label).astype(np.uint8)
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
        out = PROXY_RGB[lab]
        soil = lab == SOIL
        if soil.any():
            hit = o + rays[soil] * t[soil, None]
            n = terrain.normal_at(hit[:, 0], hit[:, 1])
            out[soil] = self.soil_rgb * (0.35 + 0.65 * np.clip(n @ self.light, 0, 1))[:, None]
        plant = (lab == CROP) | (lab == WEED) | (lab == OBSTACLE)
        out[plant] *= (0.8 + 0.2 * np.clip(-rays[plant, 2], 0, 1))[:, None]
        return (np.clip(out, 0, 1) * 255).astype(np.uint8)
