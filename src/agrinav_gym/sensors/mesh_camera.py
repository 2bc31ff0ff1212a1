"""The D455 on the plant meshes: depth, RGB, semantic and instance images by Embree ray casting.

One ray per pixel from the depth origin (the left imager) against the terrain tiles and the
instanced plant meshes and the obstacles of a ``MeshScene`` gives z-depth, the semantic class
(soil / crop / weed / robot / obstacle, 0 where nothing is within range) and the instance: the
plant's index (the row of plants.csv) on crop and weed pixels, the obstacle's (the row of
obstacles.csv) on obstacle pixels. The stereo model of ``d455`` then invalidates what the pair
cannot match: the right imager's occlusion shadow (candidate pixels from the epipolar test,
each confirmed by an exact ray from the right imager), points outside the right imager's view,
and the range limits; noise is
σ_z = z²·s/(f·B) with this mode's focal length, each pixel's draw computed from one key a
frame takes from the episode's ``rng`` (``pixel_noise``).
RGB is cast again from the colour camera's pose (59 mm along the baseline) and shaded.

The robot is rigid and the camera fixed on it, so its own parts appear in its camera at a
constant mask and depth: cast once in base_link, merged per frame at no cost (with the default
mast nothing of the robot is in view).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

from ..config import CameraConfig
from ..interface import CameraModel
from ..render import native, pixel_noise, raster_view, shading
from ..render.classes import OBSTACLE, OTHER, ROBOT, SOIL
from ..render.embree import Caster, Scene, device
from ..render.mesh_scene import MeshScene, SceneHits, bilinear
from ..render.plant_meshes import Prototype, hit_uv, rotation_rpy, sample_texture
from ..render.robot_mesh import robot_prototype
from ..render.shading import SOIL_RGB, Lighting
from . import d455
from .camera import DepthFrame, FieldView, corner_pixels

RGB_FAR = 2.0  # × max_range: how far the colour camera sees geometry before the haze
#: ``renderer="auto"`` rasterises frames this large: below it a frame's few rays cost less
#: than drawing every triangle in view (benchmarks/bench_mesh_camera.py, docs/camera.md)
RASTER_MIN_PIXELS = 100_000


@dataclass(frozen=True)
class PixelRays:
    """A pinhole's unit rays in base_link, the cosine to its optical axis, its mount."""

    body: FloatArray  # (n, 3)
    forward: FloatArray  # (n,)
    mount: FloatArray  # (3,)
    column: FloatArray  # (n,) pixel column
    edge: NDArray[np.int64]  # the corner pixels (the view's hull)
    columns: NDArray[np.float32]  # (3, n) the body rays' components, contiguous

    @classmethod
    def of(cls, m: CameraModel) -> PixelRays:
        d = m.pixel_rays()
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        col = np.tile(np.arange(m.width, dtype=np.float64), m.height)
        edge = corner_pixels(m.width, m.height)
        body = d @ m.rotation.T
        cols = np.ascontiguousarray(body.T, np.float32)
        return cls(body, d[:, 0].copy(), np.asarray(m.position, float), col, edge, cols)

    def world(self, rot: FloatArray, pos: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Camera origin and float32 world rays; the rotation is done per component because a
        float64 (n, 3) @ (3, 3) product hits a slow BLAS path (≈ 100 ms at 848 × 480)."""
        return pos + rot @ self.mount, rotate(self.columns, rot)


class MeshCamera(Lighting):
    """``model`` gives intrinsics and mount (``RobotInterface.camera``); ``cfg`` the sensor."""

    def __init__(self, cfg: CameraConfig, model: CameraModel, threads: int = 1) -> None:
        self.cfg = cfg
        self.model = model
        self.rays = PixelRays.of(model)
        self.color = d455.color_model(model)
        self.color_rays = PixelRays.of(self.color)
        self.right = np.asarray(d455.offset_model(model, cfg.baseline).position, float)
        self.fx = model.fx  # the image's: the stereo geometry (shadows) is in its pixels
        # the sensor mode's sets the noise, as the proxy camera's does: a 64 × 48 image is
        # resampled from that mode, not matched in its own pixels (20 × the noise)
        self.f_noise = d455.noise_focal(cfg.native_width, cfg.hfov_deg)
        self.threads = threads
        self._init_lighting(SOIL_RGB)
        self._robot: dict[str, tuple[FloatArray, NDArray[np.int32]] | None] = {}
        self._faces: tuple[MeshScene, FaceTable] | None = None
        self._geometry: tuple[MeshScene, raster_view.SceneGeometry] | None = None
        self._bands = raster_view.Bands(model.height, threads)
        self._work: raster_view.FrameBuffers | None = None
        if cfg.renderer == "raster":
            native.require("camera.renderer='raster'")

    @property
    def rasterises(self) -> bool:
        """Whether frames are drawn by the rasteriser (``cfg.renderer``, image size, build)."""
        r = self.cfg.renderer
        if r == "raster":
            return True
        if r == "raycast":
            return False
        return native.available() and self.model.width * self.model.height >= RASTER_MIN_PIXELS

    def noise_sigma(self, z: FloatArray) -> FloatArray:
        return d455.noise_sigma(z, self.f_noise, self.cfg.subpixel, self.cfg.baseline)

    # ------------------------------------------------------------------ rendering
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
        return self.draw(rot, pos, field.meshes, rng, rgb, labels)

    def draw(
        self,
        rot: FloatArray,
        pos: FloatArray,
        scene: MeshScene,
        rng: np.random.Generator | None,
        rgb: bool = False,
        labels: bool = False,
        view: bool = True,
        stereo: bool = True,
    ) -> DepthFrame:
        """``render`` on a mesh scene the caller holds;
        ``view=False`` when the caller has already made the scene cover this camera's view;
        ``stereo=False`` skips the stereo pair's invalid pixels (the geometry's own depth)."""
        if self.rasterises and not scene.cutouts:  # the rasteriser knows no cut-outs
            return self._render_raster(rot, pos, scene, rng, rgb, labels, stereo)
        scene.caster.threads = self.threads
        c = self.cfg
        o, d = self.rays.world(rot, pos)
        far = c.max_range + 0.05
        if view:
            scene.view(self._view_points(rot, pos, rgb))
        hits = self._cast(scene, "depth", o, d, far / self.rays.forward)
        t = hits.t
        z = t * self.rays.forward
        hit = np.isfinite(z)
        h, w = self.model.height, self.model.width
        bad = np.zeros(len(z), bool)
        if stereo:
            bad = d455.outside_right_imager(self.rays.column, z, self.fx, c.baseline)
            zt = np.where(hit, z, np.inf).reshape(h, w)
            cand = d455.shadow_candidates(zt, self.fx, c.baseline).ravel() & hit & ~bad
        else:
            cand = np.zeros(len(z), bool)
        if cand.any():
            seg = o + d[cand] * t[cand, None] - self.right_world(rot, pos)
            length = np.linalg.norm(seg, axis=1)
            tfar = 1.0 - (0.01 + 0.002 * length) / length  # stop short of the surface itself
            bad[cand] = scene.occluded(self.right_world(rot, pos), seg, 0.0, tfar)
        zn = z.copy()
        if rng is not None and c.subpixel > 0:  # one draw a frame, whatever the scene
            noise = pixel_noise.normals(pixel_noise.frame_key(rng), len(z))
            zn[hit] += self.noise_sigma(z[hit]) * noise[hit]
        valid = hit & ~bad & (zn >= c.min_range) & (zn <= c.max_range)
        frame = DepthFrame(np.where(valid, zn, 0.0).astype(np.float32).reshape(h, w))
        if labels:
            in_range = hit & (z <= c.max_range)
            frame.label = np.where(in_range, hits.label, OTHER).astype(np.uint8).reshape(h, w)
            frame.instance = np.where(in_range, hits.plant, -1).astype(np.int32).reshape(h, w)
        if rgb:
            oc, dc = self.color_rays.world(rot, pos)
            rfar = RGB_FAR * c.max_range
            ch = self._cast(scene, "color", oc, dc, rfar / self.color_rays.forward)
            frame.rgb = shading.to_u8(self.shade(scene, oc, dc, ch, rot, rfar)).reshape(h, w, 3)
            if labels:
                frame.rgb_label = ch.label.reshape(h, w)
                frame.rgb_instance = ch.plant.reshape(h, w)
        return frame

    def _render_raster(
        self,
        rot: FloatArray,
        pos: FloatArray,
        scene: MeshScene,
        rng: np.random.Generator | None,
        rgb: bool,
        labels: bool,
        stereo: bool,
    ) -> DepthFrame:
        """``render`` by rasterising the views (raster_view): the same frame. Three stages,
        each over two bands of rows with ``threads`` > 1: draw the depth, right and colour
        views; resolve them and prepare the stereo test; decide the stereo pair, finish the
        depth with its noise (each valid pixel's draw from the frame's key, as the ray-cast
        path takes it) and the labels, and shade the colour."""
        c, m = self.cfg, self.model
        h, w = m.height, m.width
        n = h * w
        if self._geometry is None or self._geometry[0] is not scene:
            self._geometry = (scene, raster_view.SceneGeometry(scene))
        geo = self._geometry[1]
        geo.near(self._view_points(rot, pos, rgb))
        far = c.max_range + 0.05
        rfar = RGB_FAR * c.max_range
        o = scene.origin
        cam = raster_view.camera_params(m, rot, pos, o, far)
        cam_r = raster_view.camera_params(m, rot, pos, o, far, c.baseline)
        cam_c = raster_view.camera_params(self.color, rot, pos, o, rfar)
        fwd, fwd_c = self.rays.forward, self.color_rays.forward
        if self._work is None:  # kept: fresh 40 MB a frame would be page faults every frame
            self._work = raster_view.FrameBuffers(n)
        vl, vr, vc, left, col, bad = self._work.parts()
        scratch = self._work.stereo
        if labels:  # the label outputs, fresh each frame, are written where they are resolved
            left = replace(left, label=np.empty(n, np.uint8), plant=np.empty(n, np.int32))
            if rgb:
                col = replace(col, label=np.empty(n, np.uint8), plant=np.empty(n, np.int32))
        key = None  # one draw a frame, whatever the scene; the pixels' draws in finish_depth
        if rng is not None and c.subpixel > 0:
            key = pixel_noise.frame_key(rng)
        bands = self._bands

        def draw(r0: int, r1: int) -> None:
            if rgb and bands.threaded:
                # one imager's view whole per thread and the colour view split between them:
                # a band must sift through all of a view's triangles, so whole views waste less
                whole = (cam, vl) if r0 == 0 else (cam_r, vr) if stereo else None
                if whole is not None:
                    geo.draw(whole[0], whole[1], 0, h)
                geo.draw(cam_c, vc, r0, r1)
                return
            geo.draw(cam, vl, r0, r1)
            if stereo:
                geo.draw(cam_r, vr, r0, r1)
            if rgb:
                geo.draw(cam_c, vc, r0, r1)

        def resolve(r0: int, r1: int) -> None:
            geo.resolve(cam, fwd, vl, left, True, self._robot_hits("depth"), r0, r1)
            if stereo:
                geo.stereo_prepare(w, h, self.fx, c.baseline, left, fwd, scratch, r0, r1)
            if rgb:
                geo.resolve(cam_c, fwd_c, vc, col, False, self._robot_hits("color"), r0, r1)

        if not stereo:
            bad[:] = 0
        depth = np.empty(n, np.float32)
        pixels = np.empty((n, 3), np.uint8)
        k_sigma = c.subpixel / (self.f_noise * c.baseline)
        robot = None
        if rgb and self._robot_hits("color") is not None:
            pr = robot_prototype(False)
            robot = (np.ascontiguousarray(rot, np.float64), pr.face_rgb, pr.normals)
        par = geo.shading_params(self.soil_rgb, self.light, rfar)

        def finish(r0: int, r1: int) -> None:
            if stereo:
                geo.stereo(
                    cam, fwd, c.baseline, d455.NEAREST_OCCLUDER, left, vl, vr, scratch, bad,
                    r0, r1,
                )  # fmt: skip
            raster_view.finish_depth(
                left, fwd, key, k_sigma, c.min_range, c.max_range, bad, labels, depth,
                r0 * w, r1 * w,
            )  # fmt: skip
            if rgb:
                geo.shade(cam_c, fwd_c, col, vc, par, robot, pixels, r0, r1)

        bands.run("draw", draw)
        bands.run("resolve", resolve)
        bands.run("finish", finish)
        frame = DepthFrame(depth.reshape(h, w))
        if labels:
            frame.label = left.label.reshape(h, w)
            frame.instance = left.plant.reshape(h, w)
        if rgb:
            frame.rgb = pixels.reshape(h, w, 3)
            if labels:
                frame.rgb_label = col.label.reshape(h, w)
                frame.rgb_instance = col.plant.reshape(h, w)
        return frame

    def right_world(self, rot: FloatArray, pos: FloatArray) -> FloatArray:
        out: FloatArray = pos + rot @ self.right
        return out

    def _view_points(self, rot: FloatArray, pos: FloatArray, rgb: bool) -> FloatArray:
        pts = [pos + rot @ self.rays.mount, self.right_world(rot, pos)]
        e = self.rays.edge
        far = (self.cfg.max_range + 0.05) / self.rays.forward[e]
        pts += list(pos + rot @ self.rays.mount + (self.rays.body[e] * far[:, None]) @ rot.T)
        if rgb:
            e = self.color_rays.edge
            far = RGB_FAR * self.cfg.max_range / self.color_rays.forward[e]
            oc = pos + rot @ self.color_rays.mount
            pts += [oc, *list(oc + (self.color_rays.body[e] * far[:, None]) @ rot.T)]
        return np.asarray(pts)[:, :2]

    def _cast(
        self, scene: MeshScene, which: str, o: FloatArray, d: FloatArray, tfar: Any
    ) -> SceneHits:
        hits = scene.cast(o, d, 0.0, tfar, refine=which == "depth")
        robot = self._robot_hits(which)
        if robot is not None:
            rt, prim = robot
            closer = rt < hits.t
            hits.t[closer] = rt[closer]
            hits.label[closer] = ROBOT
            hits.plant[closer] = -1
            hits.proto[closer] = -1
            hits.prim[closer] = prim[closer]
        return hits

    def _robot_hits(self, which: str) -> tuple[FloatArray, NDArray[np.int32]] | None:
        """The robot in its own camera: constant per pixel (rigid mount), cast once."""
        if which not in self._robot:
            rays = self.rays if which == "depth" else self.color_rays
            sc = robot_scene()
            h = Caster(device()).intersect(
                sc, rays.mount.astype(np.float32), rays.body.astype(np.float32)
            )
            t = h.t.astype(np.float64)
            self._robot[which] = (t, h.prim.copy()) if np.isfinite(t).any() else None
        return self._robot[which]

    # ------------------------------------------------------------------ colour
    def shade(
        self,
        scene: MeshScene,
        o: FloatArray,
        d: FloatArray,
        hits: SceneHits,
        rot: FloatArray,
        far: float,
        robot: tuple[FloatArray, FloatArray] | None = None,
    ) -> FloatArray:
        """Linear RGB in [0, 1] for each ray; ``robot`` (rot, pos) places the robot's mesh."""
        out = shading.sky(d)
        t = hits.t
        hit = np.isfinite(t)
        ground_far = ~hit & (d[:, 2] < 0)  # beyond the loaded tiles: distant ground in haze
        if ground_far.any():
            base = self.soil_rgb * (shading.AMBIENT + 0.4)
            out[ground_far] = shading.haze(base[None, :], np.array([far]), far)
        oo = np.broadcast_to(o, d.shape)
        soil = hits.label == SOIL
        if soil.any():
            p = oo[soil] + d[soil] * t[soil, None]
            alb = shading.soil_albedo(p[:, 0], p[:, 1], self.soil_rgb, scene.seed)
            _, hx, hy = bilinear(scene.terrain, p[:, 0], p[:, 1])
            n = np.column_stack([-hx, -hy, np.ones_like(hx)])
            out[soil] = shading.haze(shading.lambert(alb, n, d[soil], self.light), t[soil], far)
        plant = hits.plant >= 0
        if plant.any():
            table = self._face_table(scene)
            k, prim = hits.proto[plant], hits.prim[plant]
            flat = table.offset[k] + prim
            alb = table.rgb[flat].astype(np.float64) / 255.0
            for j in table.textured:
                sel = k == j
                if sel.any():
                    alb[sel] = _texel(
                        table.protos[j], prim[sel], hits.u[plant][sel], hits.v[plant][sel]
                    )
            # a plant's normals turn with its pose; an obstacle's mesh is already in place
            n = table.normal[flat].copy()
            on_plant = hits.label[plant] != OBSTACLE
            if on_plant.any():
                pl = scene.plants
                assert pl is not None
                ids = hits.plant[plant][on_plant]
                r = rotation_rpy(pl.roll[ids], pl.pitch[ids], pl.yaw[ids])
                n[on_plant] = np.einsum("nij,nj->ni", r, n[on_plant])
            lit = shading.lambert(alb, n, d[plant], self.light)
            out[plant] = shading.haze(lit, t[plant], far)
        bot = hits.label == ROBOT
        if bot.any():
            pr = robot_prototype(False)
            alb = pr.face_rgb[hits.prim[bot]].astype(np.float64) / 255.0
            r = rot if robot is None else robot[0]
            n = rotate(np.ascontiguousarray(pr.normals[hits.prim[bot]].T), r)
            out[bot] = shading.lambert(alb, n, d[bot], self.light)
        return out

    def _face_table(self, scene: MeshScene) -> FaceTable:
        if self._faces is None or self._faces[0] is not scene:
            self._faces = (scene, FaceTable.of(scene.prototypes))
        return self._faces[1]


def rotate(columns: NDArray[np.float32], rot: FloatArray) -> Any:
    """(n, 3) float32 vectors ``rot @ v`` from their components ``columns`` (3, n)."""
    r = np.asarray(rot, np.float32)
    c0, c1, c2 = columns
    out = np.empty((columns.shape[1], 3), np.float32)
    for i in range(3):
        out[:, i] = c0 * r[i, 0] + c1 * r[i, 1] + c2 * r[i, 2]
    return out


@dataclass(frozen=True)
class FaceTable:
    """All prototypes' face colours and normals in one array (prototype k from offset[k])."""

    protos: tuple[Prototype, ...]
    offset: NDArray[np.int64]
    rgb: NDArray[np.uint8]
    normal: FloatArray
    textured: tuple[int, ...]

    @classmethod
    def of(cls, protos: tuple[Prototype, ...]) -> FaceTable:
        counts = [len(p.faces) for p in protos]
        offset = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        return cls(
            protos,
            offset,
            np.concatenate([p.face_rgb for p in protos]),
            np.concatenate([p.normals for p in protos]).astype(np.float64),
            tuple(k for k, p in enumerate(protos) if p.texture is not None),
        )


def _texel(p: Prototype, prim: NDArray[np.int64], u: Any, v: Any) -> FloatArray:
    assert p.uv is not None and p.texture is not None
    uv = hit_uv(p, prim, u, v)
    out: FloatArray = sample_texture(p.texture, uv[:, 0], uv[:, 1]).astype(np.float64) / 255.0
    return out


_ROBOT_SCENES: dict[int, Scene] = {}


def robot_scene() -> Scene:
    """The robot (without its camera housing) in base_link, one scene per process."""
    dev = device()
    sc = _ROBOT_SCENES.get(id(dev))
    if sc is None:
        pr = robot_prototype(False)
        sc = Scene(dev, "high")
        sc.attach_triangles(0, pr.vertices, pr.faces)
        sc.commit()
        _ROBOT_SCENES.clear()
        _ROBOT_SCENES[id(dev)] = sc
    return sc
