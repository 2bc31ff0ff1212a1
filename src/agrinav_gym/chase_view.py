"""The ``rgb_array`` frame: a chase view ray-traced over the crop meshes, the robot's camera inset.

The chase camera follows the robot's heading (not its roll and pitch, which would make a video
sway) from ``RenderConfig.distance`` behind and ``elevation`` above base_link, 60° vertical
field of view, looking at the ground 1 m ahead of the robot. The robot is drawn from its URDF
visuals in its true pose. The top-right inset is the robot's colour camera (the D455's RGB, as
``MeshCamera`` renders it) at a third of the frame's width.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .config import CameraConfig, RenderConfig
from .interface import CameraModel
from .render.classes import ROBOT
from .render.embree import Caster
from .render.mesh_scene import MeshScene
from .render.shading import to_u8
from .robot import RobotState
from .sensors.mesh_camera import MeshCamera, robot_scene, rotate

VFOV_DEG = 60.0
FAR = 30.0  # m the chase camera sees geometry before the haze


class ChaseView:
    def __init__(self, cfg: RenderConfig, camera: CameraModel, cam_cfg: CameraConfig) -> None:
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

    def set_lighting(self, soil_rgb: object, azimuth_deg: float, elevation_deg: float) -> None:
        for cam in (self.chase, self.inset):
            cam.set_lighting(soil_rgb, azimuth_deg, elevation_deg)

    def render(self, scene: MeshScene, s: RobotState) -> NDArray[np.uint8]:
        yaw = float(s.rpy[2])
        c, sn = math.cos(yaw), math.sin(yaw)
        heading = np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])
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
        ih, iw = small.shape[:2]
        frame[:ih, -iw:] = small
        frame[ih : ih + 2, -iw - 2 :] = 255  # a white rule around the inset
        frame[: ih + 2, -iw - 2 : -iw] = 255
        return frame
