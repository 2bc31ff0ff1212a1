"""Nav2's recovery behaviours around the controller, as Humble's default behaviour tree runs them.

``navigate_to_pose_w_replanning_and_recovery.xml`` (nav2_bt_navigator, Humble): FollowPath is
retried once after clearing the local costmap; when it fails again the tree runs the next
action of a round robin — clear both costmaps, ``Spin`` 1.57 rad, ``Wait`` 5 s, ``BackUp``
0.30 m at 0.05 m/s — and starts over, at most ``number_of_retries`` (6) times per goal; then
the goal fails. Here a FollowPath failure is the progress checker firing (the controller
server's SimpleProgressChecker), the behaviours move the robot whatever the policy asks
(nav2_behaviors owns ``cmd_vel`` while one runs), and clearing a costmap is announced in
``info["recovery"]`` for the policy that keeps one. A reached waypoint is a new goal: the
count starts again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: the round robin after the retried FollowPath, in the tree's order
ROUND_ROBIN = ("clear_costmaps", "spin", "wait", "backup")
#: the FollowPath subtree's own recovery before each round-robin step
CLEAR_LOCAL = "clear_local_costmap"
ABORT = "abort"
#: the waypoint follower's answer to an aborted goal with stop_on_failure false
SKIP = "skip_waypoint"
#: what clears a costmap (the policy's, when it has one)
CLEARING = (CLEAR_LOCAL, "clear_costmaps")

# nav2_behaviors (Humble) defaults and the tree's arguments
SPIN_DIST = 1.57  # rad, the tree's Spin spin_dist
SPIN_VEL = 1.0  # rad/s, behavior_server max_rotational_vel
WAIT_S = 5.0  # s, the tree's Wait wait_duration
BACKUP_DIST = 0.30  # m, the tree's BackUp backup_dist
BACKUP_SPEED = 0.05  # m/s, the tree's BackUp backup_speed
TIME_ALLOWANCE = 10.0  # s, Spin's and BackUp's default time_allowance


@dataclass
class Behaviour:
    """A running spin, wait or back-up: what it has still to do."""

    kind: str
    start: tuple[float, float, float]  # the estimated pose it started from
    elapsed: float = 0.0
    turned: float = 0.0  # spin: yaw turned so far, rad
    last_yaw: float = 0.0


class Recoveries:
    """The recovery side of the default tree for one episode (see the module docstring)."""

    def __init__(self, retries: int, dt: float) -> None:
        self.retries, self.dt = retries, dt
        self.failures = 0  # FollowPath failures of the current goal
        self.running: Behaviour | None = None

    def reset(self) -> None:
        self.failures, self.running = 0, None

    def new_goal(self) -> None:
        self.failures = 0

    def on_failure(self, pose: tuple[float, float, float]) -> str:
        """The progress checker fired: what the tree does — clear the local costmap and retry,
        start the round robin's next action, or give the goal up (``ABORT``)."""
        self.failures += 1
        if self.failures % 2 == 1:
            return CLEAR_LOCAL
        cycle = self.failures // 2 - 1  # recoveries run so far
        if cycle >= self.retries:
            return ABORT
        kind = ROUND_ROBIN[cycle % len(ROUND_ROBIN)]
        if kind in ("spin", "wait", "backup"):
            self.running = Behaviour(kind, pose, last_yaw=pose[2])
        return kind

    def twist(self, pose: tuple[float, float, float]) -> tuple[float, float] | None:
        """The body twist (m/s, rad/s) the running behaviour commands from the estimated
        ``pose``, or None once it is done (then the controller drives again)."""
        b = self.running
        if b is None:
            return None
        b.elapsed += self.dt
        done = b.elapsed > TIME_ALLOWANCE
        twist = (0.0, 0.0)
        if b.kind == "spin":
            d = (pose[2] - b.last_yaw + math.pi) % (2 * math.pi) - math.pi
            b.turned += abs(d)
            b.last_yaw = pose[2]
            done = done or b.turned >= SPIN_DIST
            twist = (0.0, SPIN_VEL)
        elif b.kind == "wait":
            done = b.elapsed >= WAIT_S
        else:  # backup
            moved = math.hypot(pose[0] - b.start[0], pose[1] - b.start[1])
            done = done or moved >= BACKUP_DIST
            twist = (-BACKUP_SPEED, 0.0)
        if done:
            self.running = None
            return None
        return twist
