"""Obstacles as pybullet bodies: the stones, litter and fallen stalks the robot can run into.

Each obstacle is a static body (mass 0) whose collision shape is the convex hull of its own
mesh's vertices (``Obstacles.local_mesh``: the mesh the cameras see; a stone is already a
convex hull, a stalk's octagonal prism and litter's box are convex), posed as the scenario
places it.

Collision groups (pybullet: two shapes collide when ``groupA & maskB`` and ``groupB & maskA``):

======== ====== ============================== ==========================================
shape    group  mask                           meets
======== ====== ============================== ==========================================
chassis  1      all (pybullet's dynamic default) the terrain and the obstacles
terrain  2      all but 2 (the static default) the chassis (the wheels' group is not in it)
obstacle 4      chassis | wheel                the chassis and the wheels
wheel    8      obstacle                       the obstacles only: the tyre model
                                               (``sim/tyres.py``) is its contact with the soil
======== ====== ============================== ==========================================

Only the obstacles near the robot are bodies. pybullet charges every body each physics step
whether anything touches it or not (measured on a 2-core x86_64: ≈ 1 µs per static multibody,
≈ 0.2 µs per static rigid body, per step; 5,000 stones far from the robot made a physics step
300 times dearer), and a field can hold thousands. So, as the terrain is a window that follows
the robot (``world.TerrainPatch``), the obstacles within ``WINDOW_MARGIN`` more than the robot's
reach are bodies, refreshed when the robot has moved half that margin: none that can touch the
robot is ever missing, and none is removed while it could. Collision shapes are made on first
use (a stone's mesh and hull cost ≈ 3 ms) and kept by the world, keyed by the obstacle's shape
and size: this pybullet cannot free a shape once a body has used it ("it is used", even after
the body is gone), so a shape lives until the simulation is reset (≈ 26 KB each; the world
resets itself at the next scenario once it holds ``world.SHAPE_LIMIT``).

An episode's physics depends on the window's history only through the bodies' creation order
(pybullet orders contact pairs by it, ``deterministicOverlappingPairs``), so ``rebuild`` makes
the window afresh, in index order, each time the robot is put down: an episode is the same
whatever episodes came before it on the same field.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
from scipy.spatial import cKDTree

from scenario_gen.obstacles import Obstacles

from .contact import footprint_boxes, rects_overlap

#: collision groups and masks (the table above)
CHASSIS_GROUP = 1  # btBroadphaseProxy::DefaultFilter: pybullet's group for a dynamic body
TERRAIN_GROUP = 2  # btBroadphaseProxy::StaticFilter: pybullet's group for a static body
OBSTACLE_GROUP = 4
WHEEL_GROUP = 8
OBSTACLE_MASK = CHASSIS_GROUP | WHEEL_GROUP
WHEEL_MASK = OBSTACLE_GROUP

#: m: obstacles this much beyond the robot's reach are bodies; the window moves when the
#: robot has gone half of it (at 1.5 m/s, 10 control steps)
WINDOW_MARGIN = 1.0
#: Coulomb friction of an obstacle's surface against a wheel (rubber on dry stone, wood or
#: plastic: 0.6-0.8 in handbooks; the lower end, assumed). pybullet multiplies the two bodies'
#: coefficients, so the wheels' own is 1 (``WHEEL_FRICTION``) and the chassis' pybullet's 0.5.
OBSTACLE_FRICTION = 0.6
WHEEL_FRICTION = 1.0

#: what makes two obstacles' collision shapes the same: kind, length, width, height, seed
ShapeKey = tuple[str, float, float, float, int]


class ObstacleBodies:
    """The obstacles of one scenario in one pybullet client, as a window around the robot."""

    def __init__(
        self, client: int, obstacles: Obstacles, reach: float, shapes: dict[ShapeKey, int]
    ) -> None:
        """``reach``: a bound on how far any part of the robot is from base_link, m;
        ``shapes``: the collision shapes the client already has (added to as needed)."""
        self.client = client
        self.obstacles = obstacles
        o = obstacles
        hl, hw = 0.5 * np.asarray(o.length, float), 0.5 * np.asarray(o.width, float)
        # a bound on how far any vertex of obstacle i is from its frame's origin, whatever its
        # tilt (a stone's buried third included: its height bounds that too)
        self._half = np.sqrt(hl**2 + hw**2 + np.asarray(o.height, float) ** 2).tolist()
        self._max_half = max(self._half, default=0.0)
        self._xy = np.column_stack([o.x, o.y])
        self._tree = cKDTree(self._xy) if len(o) else None
        self._box = footprint_boxes(o)
        self._top = (np.asarray(o.z, float) + np.asarray(o.height, float)).tolist()
        self.reach = reach
        self.shapes = shapes
        self.bodies: dict[int, int] = {}  # obstacle -> body, the window's
        self._at: tuple[float, float] | None = None  # where the window was last chosen

    def __len__(self) -> int:
        return len(self.obstacles)

    # ------------------------------------------------------------------ the window
    def wanted(self, x: float, y: float) -> list[int]:
        """The obstacles that should be bodies with the window at (x, y), in index order."""
        if self._tree is None:
            return []
        r = self.reach + self._max_half + WINDOW_MARGIN
        found = self._tree.query_ball_point((x, y), r)
        xy, half = self._xy, self._half
        out = []
        for i in sorted(int(i) for i in found):
            if math.hypot(xy[i, 0] - x, xy[i, 1] - y) <= self.reach + half[i] + WINDOW_MARGIN:
                out.append(i)
        return out

    def follow(self, x: float, y: float) -> None:
        """Keep the window around the robot at (x, y): a no-op until it has moved half the
        margin since the window was chosen."""
        at = self._at
        if at is not None and math.hypot(x - at[0], y - at[1]) <= 0.5 * WINDOW_MARGIN:
            return
        want = self.wanted(x, y)
        keep = set(want)
        for i in [i for i in self.bodies if i not in keep]:
            p.removeBody(self.bodies.pop(i), physicsClientId=self.client)
        for i in want:
            if i not in self.bodies:
                self.bodies[i] = self._body(i)
        self._at = (x, y)

    def rebuild(self, x: float, y: float) -> None:
        """The window afresh around (x, y), bodies made in index order (see the module's note
        on determinism)."""
        self.clear()
        self.follow(x, y)

    def clear(self) -> None:
        """Remove the bodies (the shapes stay: see the module's note)."""
        for b in self.bodies.values():
            p.removeBody(b, physicsClientId=self.client)
        self.bodies.clear()
        self._at = None

    def forget(self) -> None:
        """The simulation was reset (every body is gone): drop the ids."""
        self.bodies.clear()
        self._at = None

    def _body(self, i: int) -> int:
        cid, o = self.client, self.obstacles
        key = (
            str(o.kind[i]),
            float(o.length[i]),
            float(o.width[i]),
            float(o.height[i]),
            int(o.shape[i]),
        )
        shape = self.shapes.get(key)
        if shape is None:
            v, _ = o.local_mesh(i)
            # vertices without indices: pybullet makes their convex hull (btConvexHullShape)
            shape = p.createCollisionShape(p.GEOM_MESH, vertices=v.tolist(), physicsClientId=cid)
            if shape < 0:
                raise RuntimeError(f"pybullet refused obstacle {i}'s collision shape")
            self.shapes[key] = shape
        # R = Rz(yaw)·Ry(pitch)·Rx(roll) (``scenario_gen.obstacles.rotation``) is pybullet's
        # Euler convention too
        quat = p.getQuaternionFromEuler(
            [float(o.roll[i]), float(o.pitch[i]), float(o.yaw[i])], physicsClientId=cid
        )
        # maximal coordinates: a static rigid body, which costs pybullet a fifth of a static
        # multibody per step
        body = p.createMultiBody(
            0,
            shape,
            -1,
            [float(o.x[i]), float(o.y[i]), float(o.z[i])],
            quat,
            useMaximalCoordinates=True,
            physicsClientId=cid,
        )
        p.setCollisionFilterGroupMask(body, -1, OBSTACLE_GROUP, OBSTACLE_MASK, physicsClientId=cid)
        p.changeDynamics(body, -1, lateralFriction=OBSTACLE_FRICTION, physicsClientId=cid)
        return body

    # ------------------------------------------------------------------ queries
    def top_over(
        self, cx: float, cy: float, ux: float, uy: float, hx: float, hy: float
    ) -> float | None:
        """The highest obstacle top (its ground height plus its height, m) over a rectangle
        centred at (cx, cy) with length axis (ux, uy) and half sizes (hx, hy); None if no
        obstacle's footprint overlaps it."""
        if self._tree is None:
            return None
        r = math.hypot(hx, hy) + self._max_half
        best: float | None = None
        for i in self._tree.query_ball_point((cx, cy), r):
            ox, oy, oux, ouy, hl, hw = self._box[i]
            dx, dy = ox - cx, oy - cy
            # the obstacle in the rectangle's frame
            bx, by = ux * dx + uy * dy, -uy * dx + ux * dy
            bux, buy = ux * oux + uy * ouy, -uy * oux + ux * ouy
            if rects_overlap(bx, by, hx, hy, bux, buy, hl, hw):
                top = self._top[i]
                best = top if best is None else max(best, top)
        return best
