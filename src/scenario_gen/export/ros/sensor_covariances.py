"""Sensor covariances for an AgriNav Nav2 bundle (ROS 2 Humble), written by agrinav export.

    python3 scripts/sensor_covariances.py --ros-args -p use_sim_time:=true

Gazebo's IMU, NavSat and drive messages reach ROS through ros_gz_bridge without covariances
(Fortress sets none; robot_localization replaces a zero variance with a small constant and
then trusts every sensor alike). This node republishes them with the covariances of the
simulator's sensor and EKF models, read from ``config/sensor_covariances.yaml``:

    /sim/imu            -> /imu/data         orientation, angular velocity, linear acceleration
    /sim/gps/fix        -> /gps/fix          position (DIAGONAL_KNOWN)
    /sim/wheel/odometry -> /wheel/odometry   twist: speed std relative to speed (slip and
                                             scale error) with a floor, lateral velocity,
                                             yaw rate; pose: not measured (large)

Standard library, PyYAML and the Humble packages only; rclpy is imported in ``main``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
UNMEASURED = 1.0e6  # variance of what a message carries but does not measure

TOPICS = {  # bridged topic -> published topic
    "imu": ("/sim/imu", "/imu/data"),
    "gps": ("/sim/gps/fix", "/gps/fix"),
    "odom": ("/sim/wheel/odometry", "/wheel/odometry"),
}


def diagonal(values: list[float]) -> list[float]:
    """A row-major square matrix with ``values`` on its diagonal."""
    n = len(values)
    out = [0.0] * (n * n)
    for i, v in enumerate(values):
        out[i * n + i] = v
    return out


def imu_covariances(cfg: dict[str, float]) -> tuple[list[float], list[float], list[float]]:
    """(orientation, angular velocity, linear acceleration) 3 × 3 covariances."""
    rp, hdg = math.radians(cfg["roll_pitch_sigma_deg"]), math.radians(cfg["heading_sigma_deg"])
    gyro, accel = math.radians(cfg["gyro_sigma_deg_s"]), cfg["accel_sigma"]
    return (
        diagonal([rp * rp, rp * rp, hdg * hdg]),
        diagonal([gyro * gyro] * 3),
        diagonal([accel * accel] * 3),
    )


def gps_covariance(cfg: dict[str, float]) -> list[float]:
    h, v = cfg["sigma_h"], cfg["sigma_v"]
    return diagonal([h * h, h * h, v * v])


def odom_twist_covariance(cfg: dict[str, float], v: float, w: float) -> list[float]:
    """6 × 6 twist covariance for wheel odometry reading speed ``v`` and yaw rate ``w``: the
    speed's white noise and its scale error (the sim's EKF estimates the scale; here it is
    variance), the skid-steer's zero lateral velocity, and the yaw rate's relative error."""
    floor = cfg["odom_floor"]
    rel = math.hypot(cfg["odom_speed_rel"], cfg["odom_scale_sigma"])
    sv = max(floor, rel * abs(v))
    sw = max(floor, cfg["odom_yaw_rel"] * abs(w))
    lat = cfg["lateral_sigma"]
    return diagonal([sv * sv, lat * lat, UNMEASURED, UNMEASURED, UNMEASURED, sw * sw])


def load(path: Path) -> dict[str, Any]:
    import yaml

    data: dict[str, Any] = yaml.safe_load(path.read_text())
    return data


def main(argv: list[str] | None = None) -> int:  # pragma: no cover - needs ROS 2
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.node import Node
    from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

    argv = list(sys.argv if argv is None else argv)
    rclpy.init(args=argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", default=str(ROOT / "config" / "sensor_covariances.yaml"))
    args = p.parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    cfg = load(Path(args.config))
    node = Node("agrinav_sensor_covariances")
    orientation, rate, accel = imu_covariances(cfg["imu"])
    fix = gps_covariance(cfg["gps"])
    odom_cfg = cfg["odom"]
    pose = diagonal([UNMEASURED] * 6)

    imu_pub = node.create_publisher(Imu, TOPICS["imu"][1], 10)
    gps_pub = node.create_publisher(NavSatFix, TOPICS["gps"][1], 10)
    odom_pub = node.create_publisher(Odometry, TOPICS["odom"][1], 10)

    def on_imu(msg: Any) -> None:
        msg.orientation_covariance = orientation
        msg.angular_velocity_covariance = rate
        msg.linear_acceleration_covariance = accel
        imu_pub.publish(msg)

    def on_gps(msg: Any) -> None:
        msg.position_covariance = fix
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        msg.status.service = NavSatStatus.SERVICE_GPS
        gps_pub.publish(msg)

    def on_odom(msg: Any) -> None:
        t = msg.twist.twist
        msg.twist.covariance = odom_twist_covariance(odom_cfg, t.linear.x, t.angular.z)
        msg.pose.covariance = pose
        odom_pub.publish(msg)

    node.create_subscription(Imu, TOPICS["imu"][0], on_imu, 10)
    node.create_subscription(NavSatFix, TOPICS["gps"][0], on_gps, 10)
    node.create_subscription(Odometry, TOPICS["odom"][0], on_odom, 10)
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
