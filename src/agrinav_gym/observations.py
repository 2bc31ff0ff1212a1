"""One observation model per observation key: its space and how a step's data becomes it.

Models read a ``Snapshot`` of the step (sensor readings, the *estimated* pose, the route, and —
for the camera — the true pose the sensor sees from). Vector layouts are those of
``interface`` (GPS_FIELDS, IMU_FIELDS, ...). Readings saturate at the sensors' measurement
ranges, as real ones do. Every call returns a fresh array. A new observation is a new
``ObservationModel`` subclass decorated with ``@observation``: no shared code changes.
"""

from __future__ import annotations

import ctypes
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

import numpy as np
from gymnasium import spaces

from scenario_gen import Scenario
from scenario_gen.arrays import F32
from scenario_gen.errors import InputError

from .config import EnvConfig
from .estimation import Readings
from .interface import (
    FIX_CODES,
    OBS_DEPTH,
    OBS_GPS,
    OBS_IMU,
    OBS_ODOM,
    OBS_ROUTE,
    ODOM_FIELDS,
    RobotInterface,
)
from .render import native
from .robot import RobotState
from .routes import RoutePath, Tracker
from .sensors import make_camera
from .sensors.camera import Camera, DepthFrame, FieldView

G20, RATE = 20 * 9.81, math.radians(450.0)  # MTi-300 ranges: ±20 g, ±450 °/s


@dataclass(frozen=True)
class Snapshot:
    """What the observation models may read after a control step."""

    state: RobotState  # ground truth: only sensors (the camera) may use it
    readings: Readings
    estimate: tuple[float, float, float]  # estimated x, y, yaw
    route: RoutePath
    scenario: Scenario
    field: FieldView  # what the cameras see
    rng: np.random.Generator
    step: int  # control steps since reset (0 at reset)
    start: tuple[float, float, float]  # where the robot was put down (x, y, yaw): the
    # episode's start, or where an intervention put it back on the route
    start_arc: float  # that pose's arc length along the route


class ObservationModel(ABC):
    key: ClassVar[str]

    def __init__(self, cfg: EnvConfig, robot: RobotInterface) -> None:
        self.cfg = cfg
        self.robot = robot

    @abstractmethod
    def space(self) -> spaces.Box: ...

    def reset(self, snap: Snapshot) -> None:  # noqa: B027  (stateless models need nothing)
        pass

    @abstractmethod
    def encode(self, snap: Snapshot) -> F32: ...

    def extras(self) -> dict[str, Any]:
        """What this model adds to ``info`` beside the observation (images, for a camera)."""
        return {}

    def set_lighting(  # noqa: B027  (only a camera is lit)
        self, soil_rgb: Any | None, azimuth_deg: float, elevation_deg: float
    ) -> None:
        """The episode's soil colour and sun, for models that render."""


class VectorObservation(ObservationModel):
    """A float32 vector saturated at the sensor's range [low, high]."""

    low: ClassVar[tuple[float, ...]]
    high: ClassVar[tuple[float, ...]]

    def __init__(self, cfg: EnvConfig, robot: RobotInterface) -> None:
        super().__init__(cfg, robot)
        # the bounds as numpy compares them (float64), converted once instead of every step
        self._low, self._high = np.asarray(self.low), np.asarray(self.high)
        self._inside = inner_bounds(self.low, self.high)

    def space(self) -> spaces.Box:
        return spaces.Box(np.asarray(self.low, np.float32), np.asarray(self.high, np.float32))

    def saturate(self, v: F32) -> F32:
        np.minimum(np.maximum(v, self._low, out=v), self._high, out=v)
        return v

    def pack(self, values: list[float]) -> F32:
        """``values`` as float32, saturated: where every value is well inside its range (the
        usual case) saturation changes nothing and is skipped."""
        out = np.array(values, np.float32)
        for v, (lo, hi) in zip(values, self._inside, strict=True):
            if not lo < v < hi:
                return self.saturate(out)
        return out


def inner_bounds(low: tuple[float, ...], high: tuple[float, ...]) -> list[tuple[float, float]]:
    """Per value, a range a little inside [low, high]: a float64 strictly inside it rounds to a
    float32 inside [low, high] (float32 rounding moves a value by at most 2⁻²⁴ of it)."""
    return [
        (lo + 1e-6 * max(1.0, abs(lo)), hi - 1e-6 * max(1.0, abs(hi)))
        for lo, hi in zip(low, high, strict=True)
    ]


OBSERVATION_MODELS: dict[str, type[ObservationModel]] = {}
T = TypeVar("T", bound=type[ObservationModel])


def observation(cls: T) -> T:
    OBSERVATION_MODELS[cls.key] = cls
    return cls


@observation
class GpsObservation(VectorObservation):
    """ENU antenna fix (m, ±10 km), fix code (FIX_CODES), fix age (s, up to 60)."""

    key: ClassVar[str] = OBS_GPS
    low = (-1e4, -1e4, -1e4, min(FIX_CODES.values()), 0.0)
    high = (1e4, 1e4, 1e4, max(FIX_CODES.values()), 60.0)

    def encode(self, snap: Snapshot) -> F32:
        r = snap.readings
        e, n, u = r.gnss_enu.tolist()
        return self.pack([e, n, u, FIX_CODES[r.gnss_mode], min(r.gnss_age, 60.0)])


@observation
class ImuObservation(VectorObservation):
    """Body specific force (m/s²), angular rate (rad/s), roll, pitch, sin/cos heading."""

    key: ClassVar[str] = OBS_IMU
    low = (-G20,) * 3 + (-RATE,) * 3 + (-math.pi, -math.pi, -1.0, -1.0)
    high = (G20,) * 3 + (RATE,) * 3 + (math.pi, math.pi, 1.0, 1.0)

    def encode(self, snap: Snapshot) -> F32:
        r = snap.readings
        roll, pitch, yaw = r.rpy.tolist()
        values = [*r.accel.tolist(), *r.gyro.tolist(), roll, pitch, math.sin(yaw), math.cos(yaw)]
        return self.pack(values)


@observation
class OdomObservation(VectorObservation):
    """Wheel-odometry forward speed (m/s, ±10) and yaw rate (rad/s, ±20)."""

    key: ClassVar[str] = OBS_ODOM
    low = (-10.0, -20.0)
    high = (10.0, 20.0)

    def encode(self, snap: Snapshot) -> F32:
        values = np.asarray(snap.readings.odom, np.float64).tolist()
        assert len(values) == len(ODOM_FIELDS)
        return self.pack(values)


@observation
class RouteObservation(ObservationModel):
    """The next K route points, ``route_spacing`` apart along the route from the *estimated*
    pose's projection, in the estimated robot frame (±100 m), each with a furrow flag.

    With ``task.waypoint_goals`` the points stop at the next of the route's GPS waypoints (the
    scenario's ``info["route_goals"]``) until the estimated pose comes within
    ``task.goal_tolerance`` of it: the plan a Nav2 controller gets for one waypoint's goal."""

    key: ClassVar[str] = OBS_ROUTE

    def __init__(self, cfg: EnvConfig, robot: RobotInterface) -> None:
        super().__init__(cfg, robot)
        k = robot.route_points
        self.offsets = robot.route_spacing * np.arange(1, k + 1)
        self.low = np.tile(np.array([-100.0, -100.0, 0.0], np.float32), k)
        self.high = np.tile(np.array([100.0, 100.0, 1.0], np.float32), k)
        ((self._lo, self._hi),) = inner_bounds((-100.0,), (100.0,))
        self.tracker: Tracker | None = None
        self._points: native.RoutePointsArgs | None = None
        #: the waypoints still ahead, (arc, x, y), the next first (task.waypoint_goals)
        self.goals: list[tuple[float, float, float]] = []
        self.goal_passed = False  # the last encode passed a goal
        self._goals_on = cfg.task.waypoint_goals
        self._offs = np.array(self.offsets, np.float64)  # offsets cut at the next goal

    def space(self) -> spaces.Box:
        return spaces.Box(self.low, self.high)

    def reset(self, snap: Snapshot) -> None:
        self.tracker = Tracker(snap.route)
        self.tracker.reset_at(snap.start_arc, snap.start[0], snap.start[1])
        self.goals = self._goals(snap) if self._goals_on else []
        self._offs[:] = self.offsets
        self._points = None
        if native.available():  # the kernel route_points, else the Python below (its twin)
            self._out = np.empty(3 * len(self.offsets), np.float32)
            self._points = native.RoutePointsArgs(
                route=snap.route.native, s=0.0, n=len(self.offsets), offsets=self._offs,
                x=0.0, y=0.0, cos_yaw=1.0, sin_yaw=0.0, lo=-100.0, hi=100.0, out=self._out,
            )  # fmt: skip
            self._call = native.kernel("route_points")
            self._ref = ctypes.byref(self._points)

    def _goals(self, snap: Snapshot) -> list[tuple[float, float, float]]:
        """The route's waypoints past the start, as (arc, x, y); the route's end is the last."""
        idx = snap.scenario.info.get("route_goals")
        route = snap.route
        n = len(route.xy)
        if not isinstance(idx, list) or n != len(snap.scenario.route.xy):
            raise InputError(
                "config.task.waypoint_goals",
                True,
                "needs the FieldRoute task on a route planned through GPS waypoints "
                "(route.waypoints); allowed: false here",
            )
        if not all(isinstance(i, int) and 0 <= i < n for i in idx) or idx != sorted(idx):
            raise InputError(
                "scenario info.route_goals", idx, f"allowed: increasing indices below {n}"
            )
        tol = self.cfg.task.goal_tolerance
        return [
            (float(route.arc[i]), float(route.xy[i, 0]), float(route.xy[i, 1]))
            for i in idx
            if snap.start_arc + tol < route.arc[i] < route.length
        ]

    def _next_goal_arc(self, s: float, ex: float, ey: float) -> None:
        """Pass the goals the estimate has reached, then cut the offsets at the next one."""
        tol = self.cfg.task.goal_tolerance
        self.goal_passed = False
        while self.goals and math.hypot(ex - self.goals[0][1], ey - self.goals[0][2]) <= tol:
            self.goals.pop(0)
            self.goal_passed = True
        if self.goals:
            np.minimum(self.offsets, self.goals[0][0] - s, out=self._offs)
        else:
            self._offs[:] = self.offsets

    def skip_goal(self) -> bool:
        """The follower gave the next waypoint up and sends the one after (stop_on_failure
        false): False when the next goal is the route's end, which cannot be skipped."""
        if not self.goals:
            return False
        self.goals.pop(0)
        return True

    def encode(self, snap: Snapshot) -> F32:
        assert self.tracker is not None
        ex, ey, yaw = snap.estimate
        _, s, _ = self.tracker.update(ex, ey)
        if self._goals_on:
            self._next_goal_arc(s, ex, ey)
        a = self._points
        if a is not None:
            a.s, a.x, a.y, a.cos_yaw, a.sin_yaw = s, ex, ey, math.cos(yaw), math.sin(yaw)
            status = self._call(self._ref)
            if status:
                raise native.failed("route_points", status)
            return self._out.copy()
        pts, furrow = snap.route.lookup_points([s + o for o in self._offs.tolist()])
        c, sn = math.cos(yaw), math.sin(yaw)
        rel = ((pts - (ex, ey)) @ np.array([[c, -sn], [sn, c]])).tolist()  # world -> robot
        values: list[float] = []
        inside = True
        lo, hi = self._lo, self._hi
        for (x, y), f in zip(rel, furrow, strict=True):
            values += (x, y, 1.0 if f else 0.0)
            inside = inside and lo < x < hi and lo < y < hi
        flat = np.array(values, np.float32)
        if not inside:  # saturate (the flags are 0 or 1: inside their range)
            np.minimum(np.maximum(flat, self.low, out=flat), self.high, out=flat)
        return flat


@observation
class DepthObservation(ObservationModel):
    """D455-like z-depth (1, H, W) in metres, 0 = invalid, at ``camera.rate_hz``; the frame's
    RGB, segmentation and (mesh camera) instance ids of plants and obstacles, when enabled, go
    to ``info``.

    ``camera.model`` picks the fidelity: the analytic proxy (``DepthCamera``) or the crop meshes
    (``MeshCamera`` over the scenario's ``MeshScene``)."""

    key: ClassVar[str] = OBS_DEPTH

    def __init__(self, cfg: EnvConfig, robot: RobotInterface) -> None:
        super().__init__(cfg, robot)
        c = cfg.camera
        self.camera: Camera = make_camera(c, robot.camera)
        self.every = max(1, round(cfg.robot.control_hz / cfg.camera.rate_hz))
        self.frame: DepthFrame | None = None

    def space(self) -> spaces.Box:
        c = self.cfg.camera
        return spaces.Box(0.0, c.max_range, (1, c.height, c.width), np.float32)

    def reset(self, snap: Snapshot) -> None:
        self.frame = None

    def set_lighting(self, soil_rgb: Any | None, azimuth_deg: float, elevation_deg: float) -> None:
        self.camera.set_lighting(soil_rgb, azimuth_deg, elevation_deg)

    def encode(self, snap: Snapshot) -> F32:
        if self.frame is None or snap.step % self.every == 0:
            c = self.cfg.camera
            s = snap.state
            self.frame = self.camera.render(
                s.rot, s.pos, snap.field, snap.rng, rgb=c.rgb, labels=c.segmentation
            )
        return self.frame.depth[None].copy()

    def extras(self) -> dict[str, Any]:
        """The current frame's RGB and segmentation, for ``info``."""
        out: dict[str, Any] = {}
        if self.frame is not None and self.frame.rgb is not None:
            out["rgb"] = self.frame.rgb.copy()
        if self.frame is not None and self.frame.label is not None:
            out["segmentation"] = self.frame.label.copy()
        if self.frame is not None and self.frame.instance is not None:
            out["instance"] = self.frame.instance.copy()
        return out
