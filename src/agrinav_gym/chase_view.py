"""The ``rgb_array`` frame: a chase view of the crop meshes, the robot's camera inset.

The chase camera follows the robot's heading (not its roll and pitch, which would make a video
sway) from ``RenderConfig.distance`` behind and ``elevation`` above base_link, 60° vertical
field of view, looking at the ground 1 m ahead of the robot. The robot is drawn from its URDF
visuals in its true pose. The top-right inset is the robot's colour camera (the D455's RGB, as
``MeshCamera`` renders it) at a third of the frame's width.

Where the compiled kernels are built both views are rasterised (``raster_view``, as the mesh
camera draws large frames), two bands of rows at once, and only the few rays that can meet the
robot are cast with Embree (its true pose is not rigid in the chase view); elsewhere every pixel
is ray-cast with Embree, the same images more slowly (a 640 × 480 frame on 2 cores: ≈ 30 ms
rasterised, ≈ 0.4 s ray-cast; ``benchmarks/bench_video.py``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .config import CameraConfig, RenderConfig
from .interface import CameraModel
from .render import native, raster_view
from .render.classes import ROBOT
from .render.embree import Caster, device
from .render.mesh_scene import MeshScene
from .render.robot_mesh import robot_prototype
from .render.shading import Lighting, to_u8
from .robot import RobotState
from .sensors.mesh_camera import RGB_FAR, MeshCamera, PixelRays, robot_scene, rotate

VFOV_DEG = 60.0
FAR = 30.0  # m the chase camera sees geometry before the haze


class ChaseView:
    """``threads`` > 1 rasterises each view as two bands of rows at once."""

    def __init__(
        self, cfg: RenderConfig, camera: CameraModel, cam_cfg: CameraConfig, threads: int = 2
    ) -> None:
        self.cfg = cfg
        w, h = cfg.width, cfg.height
        vfov = math.radians(VFOV_DEG)
        hfov = 2 * math.atan(math.tan(vfov / 2) * w / h)
        pitch = math.atan2(cfg.elevation, cfg.distance + 1.0)
        chase = CameraModel.from_fov(
            w, h, hfov, vfov, (-cfg.distance, 0.0, cfg.elevation), pitch, 0.1, FAR
        )
        self.chase = MeshCamera(cam_cfg, chase)
        iw = max(16, w // 3)
        ih = max(9, round(iw * camera.height / camera.width * camera.fx / camera.fy))
        hf = 2 * math.atan(0.5 * camera.width / camera.fx)
        vf = 2 * math.atan(0.5 * camera.height / camera.fy)
        small = CameraModel.from_fov(
            iw, ih, hf, vf, camera.position, camera.pitch, camera.min_range, camera.max_range
        )
        self.inset = MeshCamera(cam_cfg, small)
        self.rasterises = native.available()
        self._views = [_RasterView(m, threads) for m in (chase, self.inset.color)]
        self._geometry: tuple[MeshScene, raster_view.SceneGeometry] | None = None

    def set_lighting(self, soil_rgb: object, azimuth_deg: float, elevation_deg: float) -> None:
        for cam in (self.chase, self.inset):
            cam.set_lighting(soil_rgb, azimuth_deg, elevation_deg)

    def render(self, scene: MeshScene, s: RobotState) -> NDArray[np.uint8]:
        yaw = float(s.rpy[2])
        c, sn = math.cos(yaw), math.sin(yaw)
        heading = np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])
        if self.rasterises:
            return self._render_raster(scene, s, heading)
        rays = self.chase.rays
        o, d = rays.world(heading, s.pos)
        far = FAR / rays.forward
        corners = o + (rays.body[rays.edge] * far[rays.edge, None]) @ heading.T
        pts = [o[None, :2], corners[:, :2], self.inset._view_points(s.rot, s.pos, True)]
        scene.view(np.vstack(pts))
        hits = scene.cast(o, d, 0.0, far, refine=False)
        # the robot, in its true pose: rays into base_link, against its URDF mesh
        ob = (s.rot.T @ (o - s.pos)).astype(np.float32)
        db = rotate(np.ascontiguousarray(d.T), s.rot.T)
        bot = Caster(scene.dev).intersect(robot_scene(), ob, db, 0.0, np.minimum(hits.t, FAR))
        closer = bot.t < hits.t
        hits.t[closer] = bot.t[closer]
        hits.label[closer] = ROBOT
        hits.plant[closer] = -1
        hits.prim[closer] = bot.prim[closer]
        rgb = self.chase.shade(scene, o, d, hits, s.rot, FAR, robot=(s.rot, s.pos))
        frame = to_u8(rgb).reshape(self.cfg.height, self.cfg.width, 3)
        small = self.inset.draw(s.rot, s.pos, scene, None, rgb=True, view=False).rgb
        assert small is not None
        return _with_inset(frame, small)

    def _render_raster(
        self, scene: MeshScene, s: RobotState, heading: NDArray[np.float64]
    ) -> NDArray[np.uint8]:
        if self._geometry is None or self._geometry[0] is not scene:
            self._geometry = (scene, raster_view.SceneGeometry(scene))
        geo = self._geometry[1]
        chase, inset = self._views
        far = chase.rays.forward[chase.rays.edge]
        o = s.pos + heading @ chase.rays.mount
        corners = o + (chase.rays.body[chase.rays.edge] * (FAR / far)[:, None]) @ heading.T
        geo.near(
            np.vstack([o[None, :2], corners[:, :2], self.inset._view_points(s.rot, s.pos, True)])
        )
        bot = self._robot_in_chase(heading, s)
        frame = chase.draw(geo, self.chase, heading, s.pos, FAR, bot, s.rot)
        rfar = RGB_FAR * self.inset.cfg.max_range
        own = self.inset._robot_hits("color")  # its own camera: rigid, cast once
        small = inset.draw(geo, self.inset, s.rot, s.pos, rfar, own, s.rot)
        return _with_inset(frame, small)

    def _robot_in_chase(
        self, heading: NDArray[np.float64], s: RobotState
    ) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
        """The robot's hits in the chase view, per pixel (inf where none): Embree casts only
        the pixels of the rectangle its bounding box projects to."""
        view = self._views[0]
        m, rays = view.model, view.rays
        n = m.width * m.height
        t = np.full(n, np.inf)
        prim = np.full(n, -1, np.int32)
        box = _robot_box()
        r_wc = heading @ m.rotation
        o = s.pos + heading @ rays.mount
        p = ((s.pos + box @ s.rot.T) - o) @ r_wc  # corners in the camera body frame
        if np.all(p[:, 0] > 1e-3):
            u = m.cx - m.fx * p[:, 1] / p[:, 0]
            v = m.cy - m.fy * p[:, 2] / p[:, 0]
            u0, u1 = max(int(u.min()) - 1, 0), min(int(np.ceil(u.max())) + 2, m.width)
            v0, v1 = max(int(v.min()) - 1, 0), min(int(np.ceil(v.max())) + 2, m.height)
            if u0 >= u1 or v0 >= v1:
                return t, prim
            rows = np.arange(v0, v1)[:, None] * m.width
            sel = (rows + np.arange(u0, u1)[None, :]).ravel()
        else:  # a corner at or behind the camera: every pixel
            sel = np.arange(n)
        ob = (s.rot.T @ (o - s.pos)).astype(np.float32)
        db = rotate(np.ascontiguousarray(rays.columns[:, sel]), s.rot.T @ heading)
        hits = Caster(device()).intersect(robot_scene(), ob, db, 0.0, FAR / rays.forward[sel])
        t[sel] = hits.t
        prim[sel] = hits.prim
        return t, prim


def _with_inset(frame: NDArray[np.uint8], small: NDArray[np.uint8]) -> NDArray[np.uint8]:
    ih, iw = small.shape[:2]
    frame[:ih, -iw:] = small
    frame[ih : ih + 2, -iw - 2 :] = 255  # a white rule around the inset
    frame[: ih + 2, -iw - 2 : -iw] = 255
    return frame


@lru_cache(maxsize=1)
def _robot_box() -> NDArray[np.float64]:
    """The 8 corners (base_link) of the box around the robot's mesh (read only)."""
    v = robot_prototype(False).vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    box = np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)], np.float64)
    box.flags.writeable = False
    return box


class _RasterView:
    """One rasterised colour view and its working arrays, kept between frames."""

    def __init__(self, model: CameraModel, threads: int) -> None:
        self.model = model
        self.rays = PixelRays.of(model)
        n = model.width * model.height
        self.vis = raster_view.new_vis(n)
        self.res = raster_view.new_resolved(n)
        self.bands = raster_view.Bands(model.height, threads)

    def draw(
        self,
        geo: raster_view.SceneGeometry,
        light: Lighting,
        rot: NDArray[np.float64],
        pos: NDArray[np.float64],
        far: float,
        robot: tuple[NDArray[np.float64], NDArray[np.int32]] | None,
        robot_rot: NDArray[np.float64],
    ) -> NDArray[np.uint8]:
        """The 8-bit RGB (h, w, 3) of this view with its body at ``pos``/``rot``; ``robot``:
        the robot's hits per pixel, its mesh at ``robot_rot``."""
        m, vb, res = self.model, self.vis, self.res
        w, h = m.width, m.height
        cam = raster_view.camera_params(m, rot, pos, geo.scene.origin, far)
        fwd = self.rays.forward
        par = geo.shading_params(light.soil_rgb, light.light, far)
        pr = robot_prototype(False)
        mesh = (np.ascontiguousarray(robot_rot, np.float64), pr.face_rgb, pr.normals)
        out = np.empty((w * h, 3), np.uint8)
        vb.next_frame()
        self.bands.run("draw", lambda r0, r1: geo.draw(cam, vb, r0, r1))
        self.bands.run(
            "resolve", lambda r0, r1: geo.resolve(cam, fwd, vb, res, False, robot, r0, r1)
        )
        self.bands.run(
            "shade",
            lambda r0, r1: geo.shade(
                cam, fwd, res, vb, par, mesh if robot is not None else None, out, r0, r1
            ),
        )
        return out.reshape(h, w, 3)
