"""The Summit-XL as the rest of the package sees it: geometry read from its URDF, its true state
after a physics step, and the interface a policy is given.

One module so physics, sensors, rendering and policies cannot disagree about the robot.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib import resources

from scenario_gen.arrays import FloatArray

from .config import EnvConfig
from .interface import CameraModel, RobotInterface

URDF_PACKAGE = "agrinav_gym.assets"
URDF_NAME = "summit_xl.urdf"


def urdf_text() -> str:
    return resources.files(URDF_PACKAGE).joinpath(URDF_NAME).read_text()


def urdf_path() -> str:
    return str(resources.files(URDF_PACKAGE).joinpath(URDF_NAME))


@dataclass(frozen=True)
class RobotGeometry:
    """Facts read from the packaged URDF, so Python and the model cannot disagree."""

    wheel_radius: float
    wheel_width: float
    track: float
    wheelbase: float
    # length, width: the 0.724 x 0.616 m nav footprint (design.md, "Physical facts")
    footprint: tuple[float, float]
    chassis: tuple[float, float, float]  # collision box size (x, y, z), m
    frames: dict[str, tuple[float, float, float]]  # sensor link origins in base_link
    mass: float  # total, kg (every link's inertial mass)

    @property
    def contact_rects(self) -> tuple[tuple[float, float, float, float], ...]:
        """The chassis box and the four wheels seen from above: (cx, cy, half_x, half_y)."""
        hx, hy = 0.5 * self.wheelbase, 0.5 * self.track
        wheels = tuple(
            (sx * hx, sy * hy, self.wheel_radius, 0.5 * self.wheel_width)
            for sx in (1, -1)
            for sy in (1, -1)
        )
        return ((0.0, 0.0, 0.5 * self.chassis[0], 0.5 * self.chassis[1]), *wheels)

    @classmethod
    def from_urdf(cls) -> RobotGeometry:
        root = ET.fromstring(urdf_text())
        joints = {str(j.get("name")): j for j in root.iter("joint")}

        def xyz(name: str) -> tuple[float, float, float]:
            o = joints[name].find("origin")
            assert o is not None
            a, b, c = (float(v) for v in o.get("xyz", "0 0 0").split())
            return a, b, c

        fl, br = xyz("front_left_wheel_joint"), xyz("back_right_wheel_joint")
        cyl = root.find(".//link[@name='front_left_wheel']/visual//cylinder")
        box = root.find(".//link[@name='base_link']/collision//box")
        assert cyl is not None and box is not None
        chassis = tuple(float(v) for v in str(box.get("size")).split())
        frames = {n[: -len("_joint")]: xyz(n) for n in joints if n.endswith("link_joint")}
        mass = sum(float(str(m.get("value"))) for m in root.iter("mass"))
        return cls(
            float(str(cyl.get("radius"))),
            float(str(cyl.get("length"))),
            fl[1] - br[1],
            fl[0] - br[0],
            (0.724, 0.616),
            (chassis[0], chassis[1], chassis[2]),
            frames,
            mass,
        )


@dataclass(frozen=True)
class RobotState:
    """Ground truth of the robot after a physics step (for sensors, rewards, metrics only)."""

    pos: FloatArray  # (3,) base_link in ENU, m
    rot: FloatArray  # (3, 3) base_link -> world
    rpy: FloatArray  # (3,) roll, pitch, yaw, rad
    vel: FloatArray  # (3,) world-frame linear velocity, m/s
    ang: FloatArray  # (3,) world-frame angular velocity, rad/s
    wheels: list[float]  # wheel speeds, rad/s (fl, fr, bl, br)


def robot_interface(cfg: EnvConfig, geo: RobotGeometry) -> RobotInterface:
    r, c, g = cfg.robot, cfg.camera, cfg.gnss
    camera = CameraModel.from_fov(
        c.width,
        c.height,
        math.radians(c.hfov_deg),
        math.radians(c.vfov_deg),
        (r.camera_x, 0.0, r.camera_height),
        math.radians(r.camera_pitch_deg),
        c.min_range,
        c.max_range,
    )
    return RobotInterface(
        geo.footprint,
        geo.wheel_radius,
        geo.track,
        geo.wheelbase,
        geo.wheel_radius,
        r.v_max,
        r.w_max,
        r.a_max,
        r.alpha_max,
        1.0 / r.control_hz,
        camera,
        cfg.task.route_points,
        cfg.task.route_spacing,
        (g.antenna_x, 0.0, g.antenna_height),
    )
