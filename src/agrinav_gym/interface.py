"""The env -> policy contract: what a controller may know about the robot and its observations.

A policy is built from the env's spaces and a frozen ``RobotInterface`` (footprint, limits,
camera intrinsics and extrinsics, observation layouts) — never from the simulator or the env's
config object. Observation vectors are laid out once here, with decoders the policies import,
so the env and every controller agree on which number means what.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

#: Field order of each vector observation (units: SI, angles rad).
GPS_FIELDS = ("east", "north", "up", "fix_code", "fix_age")  # antenna fix (ENU m), code, age s
IMU_FIELDS = ("fx", "fy", "fz", "wx", "wy", "wz", "roll", "pitch", "sin_yaw", "cos_yaw")
ODOM_FIELDS = ("v", "w")  # wheel-odometry forward speed m/s, yaw rate rad/s
ROUTE_POINT_FIELDS = ("x", "y", "furrow")  # robot-frame route point (m) and its furrow flag

#: The observation keys an env can offer (``observations=[...]``), each one ``ObservationModel``.
OBS_GPS, OBS_IMU, OBS_ODOM, OBS_ROUTE, OBS_DEPTH = "gps", "imu", "odom", "route", "depth"
OBSERVATION_KEYS = (OBS_GPS, OBS_IMU, OBS_ODOM, OBS_ROUTE, OBS_DEPTH)

#: GNSS fix modes, worst to best: a receiver's current fix (``info["gnss_mode"]``) is one of
#: these; its best mode (``gnss.mode``: what its corrections allow) one of ``RECEIVER_MODES``.
GNSS_NONE, GNSS_STANDALONE = "none", "standalone"
GNSS_RTK_FLOAT, GNSS_RTK_FIXED = "rtk_float", "rtk_fixed"
FIX_LEVELS = (GNSS_NONE, GNSS_STANDALONE, GNSS_RTK_FLOAT, GNSS_RTK_FIXED)
RECEIVER_MODES = (GNSS_RTK_FIXED, GNSS_RTK_FLOAT, GNSS_STANDALONE)
#: GNSS fix codes in the ``gps`` observation (NMEA GGA-like: higher is better). With no fix the
#: last position is held and reads as the lowest quality; its growing fix age tells it apart
#: (a code of its own would change the space the shipped checkpoints were trained on).
FIX_CODES = {GNSS_NONE: 0, GNSS_STANDALONE: 0, GNSS_RTK_FLOAT: 1, GNSS_RTK_FIXED: 2}


@dataclass(frozen=True)
class CameraModel:
    """A pinhole depth camera on the robot: intrinsics, extrinsics and valid range.

    Pixel (u, v) has its ray (in the camera body frame x forward, y left, z up) along
    (1, −(u − cx)/fx, −(v − cy)/fy); ``pitch`` tilts the optical axis down about the body y
    axis; ``position`` is the optical centre in base_link. Depth images are z-depth along the
    optical axis in metres, 0 where invalid.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    position: tuple[float, float, float]
    pitch: float
    min_range: float
    max_range: float

    @classmethod
    def from_fov(
        cls,
        width: int,
        height: int,
        hfov: float,
        vfov: float,
        position: tuple[float, float, float],
        pitch: float,
        min_range: float,
        max_range: float,
    ) -> CameraModel:
        return cls(
            width,
            height,
            0.5 * width / math.tan(hfov / 2),
            0.5 * height / math.tan(vfov / 2),
            0.5 * (width - 1),
            0.5 * (height - 1),
            position,
            pitch,
            min_range,
            max_range,
        )

    @property
    def K(self) -> FloatArray:
        """OpenCV intrinsic matrix (optical frame: x right, y down, z forward)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def rotation(self) -> FloatArray:
        """Camera body frame (x forward, y left, z up) -> base_link."""
        c, s = math.cos(self.pitch), math.sin(self.pitch)
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])

    @property
    def T_base_optical(self) -> FloatArray:
        """4×4 transform of the optical frame (x right, y down, z forward) in base_link."""
        body_from_optical = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        T = np.eye(4)
        T[:3, :3] = self.rotation @ body_from_optical
        T[:3, 3] = self.position
        return T

    def pixel_rays(self) -> FloatArray:
        """(H·W, 3) unnormalised rays in the camera body frame, row-major, x component 1."""
        u, v = np.meshgrid(np.arange(self.width) - self.cx, np.arange(self.height) - self.cy)
        return np.stack([np.ones(u.size), -u.ravel() / self.fx, -v.ravel() / self.fy], axis=1)


@dataclass(frozen=True)
class RobotInterface:
    """What a controller may know about the robot: geometry, limits, sensors, layouts."""

    footprint: tuple[float, float]  # nav footprint length, width (m), centred on base_link
    wheel_radius: float
    track: float
    wheelbase: float
    base_height: float  # base_link above the ground under the wheels, m
    v_max: float  # forward speed at action +1, m/s
    w_max: float  # yaw rate at action +1, rad/s
    a_max: float  # linear acceleration limit, m/s²
    alpha_max: float  # angular acceleration limit, rad/s²
    control_dt: float  # s between actions
    camera: CameraModel
    route_points: int  # K points in the ``route`` observation
    route_spacing: float  # m of route arc length between them
    gnss_antenna: tuple[float, float, float]  # antenna lever arm in base_link, m

    def twist_to_action(self, v: float, w: float) -> NDArray[np.float32]:
        """A body twist (m/s, rad/s) as the env's normalized action, clipped to [-1, 1]."""
        a = np.array([v / self.v_max, w / self.w_max])
        return np.clip(a, -1.0, 1.0).astype(np.float32)


# ----------------------------------------------------------------------------- decoders


class Imu(NamedTuple):
    specific_force: FloatArray  # (3,) body frame, m/s²
    rate: FloatArray  # (3,) body frame, rad/s
    roll: float
    pitch: float
    yaw: float


class Odom(NamedTuple):
    v: float
    w: float


class Gps(NamedTuple):
    enu: FloatArray  # (3,) antenna fix, m
    fix_code: int
    age: float


def decode_imu(obs: NDArray[np.float32]) -> Imu:
    o = np.asarray(obs, np.float64)
    return Imu(o[0:3], o[3:6], float(o[6]), float(o[7]), math.atan2(float(o[8]), float(o[9])))


def decode_odom(obs: NDArray[np.float32]) -> Odom:
    return Odom(float(obs[0]), float(obs[1]))


def decode_gps(obs: NDArray[np.float32]) -> Gps:
    o = np.asarray(obs, np.float64)
    return Gps(o[0:3], round(float(o[3])), float(o[4]))


def decode_route(obs: NDArray[np.float32]) -> tuple[FloatArray, NDArray[np.bool_]]:
    """(K, 2) robot-frame route points ahead of the robot and their furrow flags."""
    r = np.asarray(obs, np.float64).reshape(-1, len(ROUTE_POINT_FIELDS))
    return r[:, :2], r[:, 2] > 0.5
