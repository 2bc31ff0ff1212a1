"""The simulated robot and the benchmarked DWB as the Nav2 bundle's input (``--to nav2``).

``scenario_gen`` writes the bundle but may not read agrinav_gym's config or the policies'
YAML, so this module reads them and hands the numbers down as ``ExportOptions.nav2_robot``:
the Summit-XL's drive limits and soil (χ, μ), its sensors (rates, noise, mounts), the EKF's
measurement and process model, and the DWB configuration with the robot's values filled in
(the benchmarked ``dwb:furrow`` and Nav2's ``dwb:nav2`` reference).
"""

from __future__ import annotations

from typing import Any

from agrinav_gym.config import EnvConfig
from agrinav_gym.robot import RobotGeometry, robot_interface, urdf_path
from agrinav_gym.sensors.gnss import error_sigma
from agrinav_gym.sim.tyres import in_place_turn_ratio
from policies.dwb.params import DWBParams
from policies.dwb.policy import config_label, resolved_config
from scenario_gen.export.ros_robot import Nav2Robot
from scenario_gen.schema import to_mapping


def nav2_robot(cfg: EnvConfig | None = None, dwb: str = "furrow") -> dict[str, Any]:
    """``ExportOptions.nav2_robot`` for the env config ``cfg`` (default: the env's defaults)
    and the DWB configuration ``dwb`` (``furrow``, ``nav2`` or a YAML file of changes)."""
    cfg = cfg if cfg is not None else EnvConfig()
    geo = RobotGeometry.from_urdf()
    robot = robot_interface(cfg, geo)
    r, c, g, loc = cfg.robot, cfg.camera, cfg.gnss, cfg.localisation
    skid = (
        r.skid_factor
        if r.skid_factor is not None
        else 1.0 / in_place_turn_ratio(cfg.soil, geo.wheelbase, geo.track)
    )
    sigma = error_sigma(g)
    data = {
        "drive": {
            "control_hz": r.control_hz,
            "v_max": r.v_max,
            "w_max": r.w_max,
            "a_max": r.a_max,
            "alpha_max": r.alpha_max,
            "skid_factor": skid,
            "friction": cfg.soil.friction,
        },
        "camera": {
            "width": c.width,
            "height": c.height,
            "hfov_deg": c.hfov_deg,
            "vfov_deg": c.vfov_deg,
            "min_range": c.min_range,
            "max_range": c.max_range,
            "rate_hz": c.rate_hz,
            "x": r.camera_x,
            "z": r.camera_height,
            "pitch_deg": r.camera_pitch_deg,
            "subpixel": c.subpixel,
            "baseline": c.baseline,
            "native_width": c.native_width,
        },
        "imu": {
            "rate_hz": r.control_hz,  # the env reads the IMU every control step
            "gyro_noise_deg_s_rthz": cfg.imu.gyro_noise_deg_s_rthz,
            "accel_noise_ug_rthz": cfg.imu.accel_noise_ug_rthz,
        },
        "gnss": {
            "rate_hz": g.rate_hz,
            "sigma_h": float(sigma[0]),
            "sigma_v": float(sigma[2]),
            "mode": g.mode,
            "antenna_x": g.antenna_x,
            "antenna_z": g.antenna_height,
        },
        "localisation": {
            "init_position_sigma": loc.init_position_sigma,
            "init_yaw_sigma_deg": loc.init_yaw_sigma_deg,
            "process_noise": loc.robot_localization.process_noise,
            "odom_speed_rel": loc.odom_speed_rel,
            "odom_scale_sigma": loc.odom_scale_sigma,
            "odom_yaw_rel": loc.odom_yaw_rel,
            "odom_floor": loc.odom_floor,
            "lateral_sigma": loc.lateral_sigma,
            "gyro_sigma_deg_s": loc.gyro_sigma_deg_s,
            "use_accel": loc.use_accel,
            "accel_sigma": loc.accel_sigma,
            "roll_pitch_sigma_deg": cfg.imu.roll_pitch_rms_deg,
            "heading_sigma_deg": loc.heading_bias_deg,
            "history_s": loc.history_s,
        },
        "route_points": cfg.task.route_points,
        "route_spacing": cfg.task.route_spacing,
        "controller": f"dwb:{config_label(dwb)}",
        "dwb": resolved_config(DWBParams.load(dwb), robot),
        "dwb_reference": resolved_config(DWBParams.load("nav2"), robot),
    }
    return to_mapping(Nav2Robot.from_dict(data))


def nav2_options(dwb: str = "furrow", **data: Any) -> dict[str, Any]:
    """The export options a Nav2 bundle needs beside ``data``: the packaged URDF and the
    robot above (env defaults, the DWB configuration ``dwb``)."""
    return {**data, "robot_urdf": urdf_path(), "nav2_robot": nav2_robot(dwb=dwb)}
