"""One pybullet client per env: the terrain heightfield, the Summit-XL and the obstacles.

The wheels touch the ground through ``sim.tyres`` (explicit tyre–soil forces on the terrain's
bilinear surface); the heightfield window is the ground the chassis would hit. Obstacles
(stones, litter, fallen stalks) are static bodies that the wheels and the chassis both meet
(``sim.obstacle_bodies``: collision groups keep the wheels off the heightfield).
"""

from __future__ import annotations

import math
import os
import sys
import weakref
from typing import Any

import numpy as np
import pybullet as p

from scenario_gen import Terrain
from scenario_gen.obstacles import Obstacles

from ..config import RobotConfig, SoilConfig
from ..robot import RobotGeometry, RobotState, urdf_path
from .obstacle_bodies import (
    WHEEL_FRICTION,
    WHEEL_GROUP,
    WHEEL_MASK,
    ObstacleBodies,
    ShapeKey,
)
from .quiet import quiet
from .tyres import TyreModel, check_bearing, check_corner_stability, in_place_turn_ratio

WHEEL_JOINTS = (
    "front_left_wheel_joint",
    "front_right_wheel_joint",
    "back_left_wheel_joint",
    "back_right_wheel_joint",
)


#: When ``World.settle`` calls the robot at rest (m/s, rad/s, consecutive physics steps) and
#: how long it waits at most (s).
SETTLED_SPEED = 1e-4
SETTLED_RATE = 1e-4
SETTLED_STEPS = 24
SETTLE_SECONDS = 10.0
#: Obstacle collision shapes a world holds before it resets itself at the next ``load``:
#: pybullet frees a used shape only with the whole simulation (≈ 26 KB each, ≈ 50 MB here).
SHAPE_LIMIT = 2048


class World:
    """The physics client with terrain, robot and obstacles; rebuilt only when the terrain
    changes, the obstacles replaced when the scenario's are others (``set_obstacles``)."""

    def __init__(
        self, robot: RobotConfig, soil: SoilConfig | None = None, gui: bool = False
    ) -> None:
        self.cfg = robot
        self.soil = soil if soil is not None else SoilConfig()
        if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            # pybullet's GUI blocks forever without an X display instead of failing
            from scenario_gen.errors import InputError

            raise InputError(
                "render_mode",
                "human",
                "needs a display (DISPLAY is unset); use render_mode='rgb_array' headless",
            )
        self.geometry = RobotGeometry.from_urdf()
        g = self.geometry
        check_corner_stability(self.soil, 0.25 * g.mass, 1.0 / robot.physics_hz)
        check_bearing(self.soil)
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        # an env dropped without close() (a notebook cell run again, a sweep) gives its client
        # back when it is collected: each one holds tens of MB
        self._release = weakref.finalize(self, _disconnect, self.client)
        self._release.atexit = False  # the process's exit frees it anyway
        self.tyres = TyreModel(self.soil, g.wheel_radius, 0.25 * g.mass, 1.0 / robot.physics_hz)
        self.skid_factor = (
            robot.skid_factor
            if robot.skid_factor is not None
            else 1.0 / in_place_turn_ratio(self.soil, g.wheelbase, g.track)
        )
        self._terrain: Terrain | None = None
        self.robot = -1
        self.wheels: list[int] = []
        self.visuals_loaded = False
        self.obstacles: ObstacleBodies | None = None  # None: no obstacles, no extra work
        self._obstacles_of: Obstacles | None = None
        self._shapes: dict[ShapeKey, int] = {}  # the obstacles' collision shapes in the client
        # the robot's reach from base_link, a bound for any tilt: the wheel spheres' and the
        # footprint's farthest corners
        self._reach = g.wheel_radius + max(
            math.hypot(abs(cx) + hx, abs(cy) + hy) for cx, cy, hx, hy in g.contact_rects
        )
        self._chassis_drop = 0.0  # chassis bottom below base_link, m (read at the first load)

    # ------------------------------------------------------------------ building
    def load(self, terrain: Terrain, row_angle: float | None = None) -> None:
        """(Re)build the world for ``terrain``; a no-op when it is the same terrain object (and
        the obstacles' shapes have not reached ``SHAPE_LIMIT``)."""
        if terrain is self._terrain and len(self._shapes) < SHAPE_LIMIT:
            return
        cid = self.client
        p.resetSimulation(physicsClientId=cid)
        p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 0, physicsClientId=cid)
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setPhysicsEngineParameter(
            fixedTimeStep=1.0 / self.cfg.physics_hz,
            numSolverIterations=self.cfg.solver_iterations,
            enableConeFriction=0,
            deterministicOverlappingPairs=1,
            # two shapes collide when (groupA & maskB) and (groupB & maskA): the collision
            # groups of sim/obstacle_bodies.py mean what they say (this pybullet's default is
            # "or", under which a wheel would meet the heightfield)
            collisionFilterMode=0,
            physicsClientId=cid,
        )
        self._terrain = terrain
        self.tyres.reset(terrain)
        self.patch = TerrainPatch(cid, terrain, self.soil.friction, row_angle, self._reach)
        self.robot = -1
        if self.obstacles is not None:  # resetSimulation removed their bodies and shapes
            self.obstacles.forget()
        self.obstacles, self._obstacles_of = None, None
        self._shapes = {}
        base_z = float(terrain.heights.max()) + 1.0
        self._spawn_robot([0, 0, base_z], [0, 0, 0, 1])
        (_, _, low), _ = p.getAABB(self.robot, -1, physicsClientId=cid)
        self._chassis_drop = base_z - float(low)
        p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 1, physicsClientId=cid)
        self.visuals_loaded = False

    def set_obstacles(self, obstacles: Obstacles) -> None:
        """Make ``obstacles`` (a scenario's) the world's; a no-op when they are the ones it has.
        Call after ``load``: the bodies appear around the robot when it is placed."""
        if obstacles is self._obstacles_of:
            return
        if self.obstacles is not None:
            self.obstacles.clear()
        self.obstacles = (
            ObstacleBodies(self.client, obstacles, self._reach, self._shapes)
            if len(obstacles)
            else None
        )
        self._obstacles_of = obstacles

    def place_robot(self, x: float, y: float, yaw: float, terrain: Terrain) -> None:
        """Put the robot at rest on the ground at (x, y) facing ``yaw``.

        Height and tilt come from the ground under each wheel, not under the centre: in a
        furrow the wheels stand on the ridge flanks, centimetres above the lane's bottom, and a
        robot spawned into them is thrown by the penetration recovery.
        """
        g = self.geometry
        c, s = math.cos(yaw), math.sin(yaw)
        fx, ly = 0.5 * g.wheelbase, 0.5 * g.track
        local = [(fx, ly), (fx, -ly), (-fx, ly), (-fx, -ly)]  # fl, fr, bl, br
        wx = np.array([x + c * a - s * b for a, b in local])
        wy = np.array([y + s * a + c * b for a, b in local])
        # the lowest point of each wheel sphere may sit a little beside its axle: sample a ring
        ring = np.linspace(0, 2 * math.pi, 8, endpoint=False)
        rx = wx[:, None] + 0.5 * g.wheel_radius * np.cos(ring)[None, :]
        ry = wy[:, None] + 0.5 * g.wheel_radius * np.sin(ring)[None, :]
        h = np.maximum(terrain.height_at(wx, wy), terrain.height_at(rx, ry).max(axis=1))
        obstacles = self.obstacles
        if obstacles is not None:  # a wheel put down on a stone stands on its top
            for k in range(4):
                top = obstacles.top_over(
                    float(wx[k]), float(wy[k]), c, s, g.wheel_radius, g.wheel_radius
                )
                if top is not None and top > h[k]:
                    h[k] = top
        fl, fr, bl, br = (float(v) for v in h)
        roll = math.atan2(0.5 * (fl + bl) - 0.5 * (fr + br), g.track)
        pitch = math.atan2(0.5 * (bl + br) - 0.5 * (fl + fr), g.wheelbase)
        # each axle's height offset from the base under that tilt; the centre goes where the
        # worst-fitting wheel just clears its ground
        dz = np.array(
            [-math.sin(pitch) * a + math.cos(pitch) * math.sin(roll) * b for a, b in local]
        )
        z = float(np.max(h - dz)) + g.wheel_radius + 0.005
        if obstacles is not None:  # nor may the chassis be put down into a tall one
            _, _, hx, hy = g.contact_rects[0]
            top = obstacles.top_over(x, y, c, s, hx, hy)
            if top is not None:
                z = max(z, top + self._chassis_drop + 0.005)
        q = p.getQuaternionFromEuler([roll, pitch, yaw])
        self.patch.follow(x, y, force=True)
        # A fresh body: resetting the old one would keep its contact manifolds and warm-start
        # impulses, and the first steps of an episode would depend on the one before.
        self._spawn_robot([x, y, z], q)
        if obstacles is not None:
            obstacles.rebuild(x, y)
        self.tyres.reset(terrain)
        self.drive(0.0, 0.0)

    def settle(self) -> int:
        """Physics steps, the wheels held (zero command), until the robot rests on the ground:
        its base's speed below ``SETTLED_SPEED`` and its rotation below ``SETTLED_RATE`` for
        ``SETTLED_STEPS`` steps in a row (at most ``SETTLE_SECONDS``). Placed a few mm above
        the ground, it drops onto the tyres' springs and rocks on them for ≈ 1 s (on ridge
        flanks the tyres can chatter for up to ≈ 9 s); an episode that started there would
        read that bounce in its first IMU samples (specific force 0.02 … 27 m/s² before 9.8).
        Returns the physics steps taken."""
        cid, robot = self.client, self.robot
        self.drive(0.0, 0.0)
        calm = 0
        most = round(SETTLE_SECONDS * self.cfg.physics_hz)
        for k in range(1, most + 1):
            self.step(1)
            lin, ang = p.getBaseVelocity(robot, physicsClientId=cid)
            still = math.hypot(*lin) < SETTLED_SPEED and math.hypot(*ang) < SETTLED_RATE
            calm = calm + 1 if still else 0
            if calm >= SETTLED_STEPS:
                return k
        return most

    def _spawn_robot(self, pos: list[float], quat: Any) -> None:
        cid = self.client
        if self.robot >= 0:
            p.removeBody(self.robot, physicsClientId=cid)
        with quiet():  # the URDF merger prints a line per link from C
            self.robot = p.loadURDF(
                urdf_path(), pos, quat, flags=p.URDF_MERGE_FIXED_LINKS, physicsClientId=cid
            )
        names = [
            p.getJointInfo(self.robot, j, physicsClientId=cid)[1].decode()
            for j in range(p.getNumJoints(self.robot, physicsClientId=cid))
        ]
        self.wheels = [names.index(n) for n in WHEEL_JOINTS]
        for j in self.wheels:
            # the tyre model is the wheels' only contact with the ground; pybullet's collision
            # meets the obstacles only (sim/obstacle_bodies.py, "Collision groups")
            p.setCollisionFilterGroupMask(
                self.robot, j, WHEEL_GROUP, WHEEL_MASK, physicsClientId=cid
            )
            p.changeDynamics(self.robot, j, lateralFriction=WHEEL_FRICTION, physicsClientId=cid)

    # ------------------------------------------------------------------ stepping
    def drive(self, v: float, w: float) -> None:
        """Skid-steer: body twist -> wheel speeds through the slip-expanded track χ·track."""
        half = 0.5 * self.geometry.track * self.skid_factor * w
        r = self.geometry.wheel_radius
        left, right = (v - half) / r, (v + half) / r
        p.setJointMotorControlArray(
            self.robot,
            self.wheels,
            p.VELOCITY_CONTROL,
            targetVelocities=[left, right, left, right],
            forces=[self.cfg.wheel_force] * 4,
            physicsClientId=self.client,
        )

    def step(self, substeps: int) -> None:
        cid, robot, wheels, tyres = self.client, self.robot, self.wheels, self.tyres
        for _ in range(substeps):
            tyres.apply(cid, robot, wheels)
            p.stepSimulation(cid)

    def follow(self, x: float, y: float, heading: float | None = None) -> None:
        """Keep the terrain window, and the obstacles' where there are some, around (x, y)."""
        self.patch.follow(x, y, heading=heading)
        if self.obstacles is not None:
            self.obstacles.follow(x, y)

    def state(self) -> RobotState:
        cid = self.client
        pos, quat = p.getBasePositionAndOrientation(self.robot, physicsClientId=cid)
        lin, ang = p.getBaseVelocity(self.robot, physicsClientId=cid)
        wheels = [s[1] for s in p.getJointStates(self.robot, self.wheels, physicsClientId=cid)]
        return RobotState(
            np.asarray(pos),
            np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3),
            np.asarray(p.getEulerFromQuaternion(quat)),
            np.asarray(lin),
            np.asarray(ang),
            wheels,
        )

    def load_visuals(self, scn: Any) -> None:
        """Terrain and plant visuals for the GUI and rgb_array views, loaded once per world."""
        if self.visuals_loaded:
            return
        from .visuals import load_plant_visuals, load_terrain_visual

        load_terrain_visual(self.client, scn)
        load_plant_visuals(self.client, scn)
        self.visuals_loaded = True

    def close(self) -> None:
        if self.client >= 0:
            self._release()
            self.client = -1


def _disconnect(client: int) -> None:
    try:
        p.disconnect(physicsClientId=client)
    except p.error:
        pass


class TerrainPatch:
    """The physics ground: a heightfield window of the terrain around the robot.

    pybullet's heightfield creation grows faster than linearly with its size (≈1 s for 360k
    samples here, and a 100k-plant field's terrain holds millions), so the ground is a window
    that is refilled in place (``replaceHeightfieldIndex``) when the robot nears its edge. It
    moves by whole grid cells, so the surface under the wheels is the same bits before and
    after a move.

    Only the chassis meets this ground (the tyre model is the wheels' contact with the soil,
    ``obstacle_bodies`` "Collision groups"), so the window needs to hold the ground within the
    robot's reach, and a control step's travel more: the robot stays ``margin`` (its reach +
    ``MARGIN_M``) inside the window's edge. A refill costs pybullet ≈ 0.3 µs a sample (it
    rebuilds the shape's ray accelerator), linear in the window's area, and comes every
    ``L - a`` metres driven along the heading, ``a = 2·margin + 1`` m and a cell (the window is
    laid ahead of the robot, ``follow``), so a window costs ``L·W / (L - a)`` per metre. A
    square one costs least at ``L = 2·a``; rows that run near an axis get one ``LONG_M``
    along them and ``2·margin + 2`` across (a metre of room each side of the lane before a
    refill). Where and when the window moves changes nothing the robot feels unless the
    chassis touches the ground.

    pybullet keeps a heightfield's original height range (its centring offset and its bounding
    box) when the data is replaced, so every window pins its two far corner samples to the
    terrain's global minimum and maximum: the range never changes and the body stays at one
    height. Those corners are always more than ``margin`` from the robot, beyond its reach.
    """

    LONG_M = 40.0  # a window's length along rows that run near an axis
    MARGIN_M = 1.0  # beyond the robot's reach, as the obstacles' window (WINDOW_MARGIN)

    def __init__(
        self,
        client: int,
        terrain: Terrain,
        friction: float,
        row_angle: float | None,
        reach: float,
    ) -> None:
        self.client = client
        self.terrain = terrain
        self.margin = reach + self.MARGIN_M
        m, s = self.margin, terrain.spacing
        ny, nx = terrain.shape
        wx = wy = 2.0 * (2.0 * m + 1.0 + s)
        if row_angle is not None:
            c, sn = abs(math.cos(row_angle)), abs(math.sin(row_angle))
            if max(c, sn) > 0.97:
                long, short = max(self.LONG_M, wx), 2.0 * m + 2.0
                wx, wy = (long, short) if c > sn else (short, long)
        # snapping to whole cells moves a window's centre up to a cell from where it was
        # asked to be: two cells more than the margin each side of the centre, so that a
        # move never leaves the robot past its recentre bound
        least = 2.0 * (m + 2.0 * s)
        self.nx = min(nx, math.ceil(max(wx, least) / s) + 1)
        self.ny = min(ny, math.ceil(max(wy, least) / s) + 1)
        self._half = (0.5 * (self.nx - 1) * s, 0.5 * (self.ny - 1) * s)
        self._centre = (0.0, 0.0)  # the window's centre (x, y), set by each refill
        self.i0 = self.j0 = -1
        self.shape = -1
        self.body = -1
        self._zrange = (float(terrain.heights.min()), float(terrain.heights.max()))
        self._friction = friction
        self.follow(
            terrain.x0 + 0.5 * (nx - 1) * terrain.spacing,
            terrain.y0 + 0.5 * (ny - 1) * terrain.spacing,
            force=True,
        )

    def _window(self, x: float, y: float) -> tuple[int, int]:
        t = self.terrain
        ny, nx = t.shape
        j = round((x - t.x0) / t.spacing) - self.nx // 2
        i = round((y - t.y0) / t.spacing) - self.ny // 2
        return min(max(i, 0), ny - self.ny), min(max(j, 0), nx - self.nx)

    def follow(self, x: float, y: float, force: bool = False, heading: float | None = None) -> bool:
        """Recentre if (x, y) is within ``margin`` of the patch edge; True if moved.

        With a ``heading`` the new window lies ahead of the robot, which then sits ``margin``
        + 1 m (and a cell) from its trailing edge: the next move is as far away as the window
        allows.
        """
        t = self.terrain
        hx, hy = self._half
        if not force and self.shape >= 0:
            cx, cy = self._centre
            if abs(x - cx) < hx - self.margin and abs(y - cy) < hy - self.margin:
                return False
        if heading is not None and not force:
            ch, sh = math.cos(heading), math.sin(heading)
            # as far ahead as the window allows along the heading: margin + 1 m behind, and a
            # cell for the snapping
            back = self.margin + 1.0 + t.spacing
            ax = (hx - back) / max(abs(ch), 1e-9)
            ay = (hy - back) / max(abs(sh), 1e-9)
            ahead = max(0.0, min(ax, ay))
            x, y = x + ahead * ch, y + ahead * sh
        i0, j0 = self._window(x, y)
        if (i0, j0) == (self.i0, self.j0) and self.shape >= 0:
            return False
        self.i0, self.j0 = i0, j0
        h = t.heights[i0 : i0 + self.ny, j0 : j0 + self.nx].copy()
        zmin, zmax = self._zrange
        h[0, 0], h[-1, -1] = zmin, zmax
        kwargs: dict[str, Any] = {}
        if self.shape >= 0:
            kwargs["replaceHeightfieldIndex"] = self.shape
        shape = p.createCollisionShape(
            p.GEOM_HEIGHTFIELD,
            meshScale=[t.spacing, t.spacing, 1.0],
            heightfieldData=h.ravel().tolist(),
            numHeightfieldRows=self.nx,
            numHeightfieldColumns=self.ny,
            physicsClientId=self.client,
            **kwargs,
        )
        # pybullet centres a heightfield on its bounding box
        centre = [
            t.x0 + (j0 + 0.5 * (self.nx - 1)) * t.spacing,
            t.y0 + (i0 + 0.5 * (self.ny - 1)) * t.spacing,
            0.5 * (zmin + zmax),
        ]
        self._centre = (centre[0], centre[1])
        if self.body < 0:
            self.shape = shape
            # an explicit tiny visual: converting the heightfield to a render mesh costs more
            # than the heightfield itself, and rendering draws the terrain mesh separately
            vis = p.createVisualShape(
                p.GEOM_SPHERE, radius=1e-3, rgbaColor=[0, 0, 0, 0], physicsClientId=self.client
            )
            self.body = p.createMultiBody(
                0, shape, vis, basePosition=centre, physicsClientId=self.client
            )
            p.changeDynamics(
                self.body, -1, lateralFriction=self._friction, physicsClientId=self.client
            )
        else:
            p.resetBasePositionAndOrientation(
                self.body, centre, [0, 0, 0, 1], physicsClientId=self.client
            )
        return True
