"""The route follower of an AgriNav Nav2 bundle (ROS 2 Humble), written by agrinav export.

    python3 scripts/follow_route.py [--record track.csv] --ros-args -p use_sim_time:=true

(the launch file starts it). What it does, in order:

1. Checks the GPS chain: once navsat_transform publishes (its transform is made), each GPS
   waypoint of ``config/gps_waypoints.yaml`` goes through its ``fromLL`` service and must
   land on its ENU position from ``config/waypoints_enu.yaml`` (the map frame is the export's
   ENU frame at the datum); a miss over ``--gps-tolerance`` stops it.
2. Drives the route: every ``1/--rate`` s it finds the robot (tf map -> base_footprint) on
   ``reference_path.csv`` as the benchmark's route tracker does and, when the robot has moved
   on, sends bt_navigator a NavigateThroughPoses goal holding the ``--points`` route poses
   ``--spacing`` m apart ahead of it (the points of the benchmark's route observation; the
   last goal is the route's end once it is that near). The behaviour tree plans through them
   and DWB follows; each new goal preempts the last. Humble has no followGpsWaypoints, and the
   route between GPS waypoints holds the headland turns the waypoints alone do not say.
3. Ends when Nav2 reports the route's end reached (exit 0), or on a failure, a stall of
   ``--stall`` s (a goal bt_navigator rejects because it is not active yet is sent again
   meanwhile) or a lost localisation (exit 1). ``--record`` writes the robot's pose and its
   cross-track error at every tick, for the paper's metrics
   (``agrinav_gym.metrics.cross_track_metrics``).

Standard library, PyYAML and the Humble packages only; rclpy is imported in ``main``.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
MAP_FRAME = "map"
BASE_FRAME = "base_footprint"
GPS_ODOMETRY = "/odometry/gps"  # navsat_transform's output


@dataclass(frozen=True)
class Route:
    """The reference path: points, cumulative arc length and each segment's heading."""

    x: list[float]
    y: list[float]
    s: list[float]

    @property
    def length(self) -> float:
        return self.s[-1]

    def heading(self, k: int) -> float:
        """Direction of the segment leaving point ``k`` (the last point: the last segment's)."""
        k = min(max(k, 0), len(self.x) - 2)
        return math.atan2(self.y[k + 1] - self.y[k], self.x[k + 1] - self.x[k])

    def segment(self, s: float) -> int:
        """The segment holding arc length ``s`` (clamped to the route)."""
        lo, hi = 0, len(self.s) - 2
        while lo < hi:  # last k with s[k] <= s
            mid = (lo + hi + 1) // 2
            if self.s[mid] <= s:
                lo = mid
            else:
                hi = mid - 1
        return lo

    def pose_at(self, s: float) -> tuple[float, float, float]:
        """(x, y, yaw) at arc length ``s`` on the route (clamped to its ends)."""
        s = min(max(s, 0.0), self.length)
        k = self.segment(s)
        seg = self.s[k + 1] - self.s[k]
        u = 0.0 if seg <= 0 else (s - self.s[k]) / seg
        x = self.x[k] + u * (self.x[k + 1] - self.x[k])
        y = self.y[k] + u * (self.y[k + 1] - self.y[k])
        return x, y, self.heading(k)


def load_route(path: Path) -> Route:
    """``reference_path.csv``: x, y in the map frame; arc length recomputed from them."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if len(rows) < 2:
        raise ValueError(f"{path}: a route needs at least two points")
    x = [float(r["x"]) for r in rows]
    y = [float(r["y"]) for r in rows]
    s = [0.0]
    for i in range(1, len(x)):
        s.append(s[-1] + math.hypot(x[i] - x[i - 1], y[i] - y[i - 1]))
    return Route(x, y, s)


class Tracker:
    """The nearest route segment to a moving point, searched from the last match forward and
    back while the distance shrinks (agrinav_gym.routes.Tracker): the route's continuity keeps
    it on the robot's lane where a global nearest point could jump to the next one."""

    def __init__(self, route: Route) -> None:
        self.route = route
        self.k = 0

    def _seg(self, k: int, x: float, y: float) -> tuple[float, float, float]:
        r = self.route
        ax, ay, dx, dy = r.x[k], r.y[k], r.x[k + 1] - r.x[k], r.y[k + 1] - r.y[k]
        px, py = x - ax, y - ay
        l2 = dx * dx + dy * dy
        u = 0.0 if l2 <= 0 else min(max((px * dx + py * dy) / l2, 0.0), 1.0)
        ex, ey = px - u * dx, py - u * dy
        return ex * ex + ey * ey, u, dx * py - dy * px

    def update(self, x: float, y: float) -> tuple[float, float]:
        """(signed cross-track error, arc length) of the point; left of the route positive."""
        last = len(self.route.x) - 2
        k = min(self.k, last)
        best = self._seg(k, x, y)
        for step in (1, -1):
            j = k + step
            while 0 <= j <= last:
                cand = self._seg(j, x, y)
                if cand[0] > best[0] + 1e-12:
                    break
                k, best = j, cand
                j += step
        self.k = k
        d2, u, cross = best
        s = self.route.s[k] + u * (self.route.s[k + 1] - self.route.s[k])
        return math.copysign(math.sqrt(d2), cross), s


def goals_ahead(
    route: Route, s0: float, points: int, spacing: float
) -> list[tuple[float, float, float]]:
    """The route poses ``spacing`` apart ahead of arc length ``s0`` (``points`` of them, as
    the route observation), ending with the route's end once it is nearer."""
    out = []
    for k in range(1, points + 1):
        s = s0 + k * spacing
        if s >= route.length - 1e-9:
            out.append(route.pose_at(route.length))
            break
        out.append(route.pose_at(s))
    return out


def load_waypoints(gps: Path, enu: Path) -> list[tuple[float, float, float, float]]:
    """(latitude, longitude, x, y) of every waypoint, from the two waypoint files."""
    import yaml

    g = yaml.safe_load(gps.read_text())["waypoints"]
    e = yaml.safe_load(enu.read_text())["waypoints"]
    if len(g) != len(e):
        raise ValueError(f"{gps} and {enu} hold different numbers of waypoints")
    return [(a["latitude"], a["longitude"], b["x"], b["y"]) for a, b in zip(g, e, strict=True)]


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``yaw`` about z."""
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--route", default=str(ROOT / "reference_path.csv"))
    p.add_argument("--gps-waypoints", default=str(ROOT / "config" / "gps_waypoints.yaml"))
    p.add_argument("--enu-waypoints", default=str(ROOT / "config" / "waypoints_enu.yaml"))
    p.add_argument("--points", type=int, default=10, help="route poses per goal")
    p.add_argument("--spacing", type=float, default=0.4, help="m of route between them")
    p.add_argument("--rate", type=float, default=5.0, help="Hz: how often the goal moves on")
    p.add_argument("--gps-tolerance", type=float, default=0.05, help="m: fromLL vs ENU")
    p.add_argument("--stall", type=float, default=60.0, help="s without 0.1 m of progress")
    p.add_argument("--record", default="", help="CSV of the robot's poses (none: not kept)")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:  # pragma: no cover - needs ROS 2
    import rclpy
    from action_msgs.msg import GoalStatus
    from geographic_msgs.msg import GeoPoint
    from geometry_msgs.msg import PoseStamped
    from nav2_msgs.action import NavigateThroughPoses
    from nav_msgs.msg import Odometry
    from rclpy.action import ActionClient
    from rclpy.node import Node
    from rclpy.time import Time
    from robot_localization.srv import FromLL
    from tf2_ros import Buffer, TransformException, TransformListener

    argv = list(sys.argv if argv is None else argv)
    rclpy.init(args=argv)
    args = parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    route = load_route(Path(args.route))
    waypoints = load_waypoints(Path(args.gps_waypoints), Path(args.enu_waypoints))
    node = Node("agrinav_route_follower")
    log = node.get_logger()
    tf = Buffer()
    TransformListener(tf, node)
    from_ll = node.create_client(FromLL, "fromLL")
    nav = ActionClient(node, NavigateThroughPoses, "navigate_through_poses")

    def wait(future: Any) -> Any:
        rclpy.spin_until_future_complete(node, future)
        return future.result()

    log.info("waiting for navsat_transform's fromLL and bt_navigator")
    while not from_ll.wait_for_service(timeout_sec=1.0):
        pass
    while not nav.wait_for_server(timeout_sec=1.0):
        pass
    # navsat_transform answers fromLL only once its transform is good: it has published then
    fixes: list[Any] = []
    sub = node.create_subscription(Odometry, GPS_ODOMETRY, fixes.append, 1)
    log.info(f"waiting for navsat_transform's first {GPS_ODOMETRY}")
    while rclpy.ok() and not fixes:
        rclpy.spin_once(node, timeout_sec=1.0)
    node.destroy_subscription(sub)
    worst = 0.0
    for k, (lat, lon, x, y) in enumerate(waypoints):
        req = FromLL.Request()
        req.ll_point = GeoPoint(latitude=lat, longitude=lon, altitude=0.0)
        p = wait(from_ll.call_async(req)).map_point
        miss = math.hypot(p.x - x, p.y - y)
        worst = max(worst, miss)
        log.info(f"GPS waypoint {k}: fromLL ({p.x:.3f}, {p.y:.3f}) m, ENU off by {miss:.3f} m")
    if worst > args.gps_tolerance:
        log.error(
            f"navsat_transform's map frame is {worst:.3f} m off the export's ENU frame "
            f"(> {args.gps_tolerance} m): check the datum in config/navsat_transform.yaml"
        )
        return 1
    tracker = Tracker(route)
    record = open(args.record, "w", newline="") if args.record else None
    writer = csv.writer(record) if record else None
    if writer:
        writer.writerow(["t", "x", "y", "yaw", "s", "cross_track"])
    # one goal at a time counts: its sequence number (a preempted goal ends ABORTED)
    state: dict[str, Any] = {"seq": 0, "sent_k": -1, "final": False}
    state["result"], state["rejected"] = None, False
    best: dict[str, Any] = {"s": -1.0, "t": None}

    def on_result(seq: int, future: Any) -> None:
        if seq == state["seq"]:
            state["result"] = future.result().status

    def on_accept(seq: int, future: Any) -> None:
        handle = future.result()
        if seq != state["seq"]:
            return
        if not handle.accepted:  # bt_navigator not active yet: the loop sends it again
            state["rejected"] = True
            return
        handle.get_result_async().add_done_callback(lambda f: on_result(seq, f))

    def send(s0: float) -> None:
        goal = NavigateThroughPoses.Goal()
        poses = goals_ahead(route, s0, args.points, args.spacing)
        for x, y, yaw in poses:
            ps = PoseStamped()
            ps.header.frame_id = MAP_FRAME
            ps.header.stamp = node.get_clock().now().to_msg()
            ps.pose.position.x, ps.pose.position.y = x, y
            q = ps.pose.orientation
            q.x, q.y, q.z, q.w = yaw_quaternion(yaw)
            goal.poses.append(ps)
        state["seq"] += 1
        seq = state["seq"]
        state["final"] = poses[-1] == route.pose_at(route.length)
        state["result"] = None
        nav.send_goal_async(goal).add_done_callback(lambda f: on_accept(seq, f))

    located = False
    code = 1
    period = 1.0 / args.rate
    while rclpy.ok():
        rclpy.spin_once(node, timeout_sec=period)
        now = node.get_clock().now()
        try:
            t = tf.lookup_transform(MAP_FRAME, BASE_FRAME, Time())
        except TransformException:
            if located:
                log.error("lost the map -> base_footprint transform")
                break
            continue
        tr, rot = t.transform.translation, t.transform.rotation
        yaw = math.atan2(2 * (rot.w * rot.z + rot.x * rot.y), 1 - 2 * (rot.y**2 + rot.z**2))
        if not located:
            located = True
            # start on the first half of the route, as the benchmark's tracker does
            tracker.k = min(
                range(max(1, (len(route.x) - 1) // 2)),
                key=lambda i: (route.x[i] - tr.x) ** 2 + (route.y[i] - tr.y) ** 2,
            )
        cte, s = tracker.update(tr.x, tr.y)
        if writer:
            writer.writerow([f"{now.nanoseconds * 1e-9:.3f}", tr.x, tr.y, yaw, s, cte])
        k = int(s // args.spacing)
        if state["rejected"]:
            state["rejected"], state["sent_k"], state["final"] = False, -1, False
        if k != state["sent_k"] and not state["final"]:
            send(s)
            state["sent_k"] = k
        if s > best["s"] + 0.1:
            best["s"], best["t"] = s, now
        elif best["t"] is not None and (now - best["t"]).nanoseconds * 1e-9 > args.stall:
            log.error(f"no progress for {args.stall:.0f} s at {s:.1f} m of {route.length:.1f} m")
            break
        result = state["result"]
        if result == GoalStatus.STATUS_SUCCEEDED and state["final"]:
            log.info(f"route end reached ({route.length:.1f} m)")
            code = 0
            break
        if result in (GoalStatus.STATUS_ABORTED, GoalStatus.STATUS_CANCELED):
            log.error(f"Nav2 gave up at {s:.1f} m of {route.length:.1f} m (status {result})")
            break
        if result == GoalStatus.STATUS_SUCCEEDED:
            state["sent_k"] = -1  # reached the window's end before the next one: send again
    if record:
        record.close()
    node.destroy_node()
    rclpy.shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
