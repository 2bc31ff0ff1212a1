"""Environment configuration: frozen, typed, validated dataclasses (unknown keys are errors).

Units are SI; ``*_deg`` fields are degrees, as their names say. Every default is a physical
fact from design.md "Physical facts" or a documented choice.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

from scenario_gen.errors import InputError
from scenario_gen.schema import from_mapping, merge, to_mapping
from scenario_gen.schema import param as _f

from .interface import GNSS_RTK_FIXED, RECEIVER_MODES


@dataclass(frozen=True)
class RobotConfig:
    v_max: float = _f(1.0, "forward speed at action +1, m/s (controller limit 1.5)", 0.05, 1.5)
    w_max: float = _f(1.5, "yaw rate at action +1, rad/s (controller limit 3)", 0.05, 3.0)
    a_max: float = _f(0.6, "linear acceleration limit, m/s² (Summit-XL controller)", 0.01, 10)
    alpha_max: float = _f(
        1.5, "angular acceleration limit, rad/s² (Summit-XL controller)", 0.01, 50
    )
    # A skid-steer's controller widens the track by χ so commanded yaw rates are met (ROS
    # diff_drive_controller's wheel_separation_multiplier); null: χ derived from the soil model
    # (sim.tyres.in_place_turn_ratio), as if calibrated on this soil.
    skid_factor: float | None = _f(
        None, "track multiplier χ of the wheel-speed command (null: from the soil)", 1.0, 10
    )
    wheel_force: float = _f(80.0, "wheel motor torque limit, N·m", 1, 1000)
    physics_hz: int = _f(
        240,
        "physics rate, Hz (a multiple of control_hz; the soil's stiffness and damping set "
        "a minimum, 148 Hz for the default soil, named in their errors)",
        10,
        2000,
    )
    control_hz: int = _f(20, "control rate, Hz (Nav2 controller frequency)", 1, 200)
    solver_iterations: int = _f(10, "pybullet constraint solver iterations", 1, 200)
    camera_x: float = _f(0.25, "camera position ahead of base_link, m", -1, 1)
    camera_height: float = _f(0.55, "camera height above base_link (mast ≈ 0.5 m), m", 0.1, 3)
    camera_pitch_deg: float = _f(25.0, "camera pitch below the horizon, degrees", -30, 90)


@dataclass(frozen=True)
class SoilConfig:
    """Tyre–soil contact (sim.tyres, docs/physics.md): every wheel force comes from these."""

    friction: float = _f(
        0.6, "peak tyre–soil traction coefficient μ (grass, firm soil ≈ 0.5–0.8)", 0.05, 3
    )
    rolling_resistance: float = _f(
        0.06, "motion resistance ratio c_rr (firm soil 0.04–0.08, tilled 0.1–0.2)", 0.0, 0.5
    )
    shear_modulus: float = _f(
        0.025, "Janosi–Hanamoto shear deformation modulus K, m (soils ≈ 0.01–0.05)", 0.002, 0.2
    )
    contact_length: float = _f(
        0.1, "tyre–soil contact length l (shear relaxation length), m", 0.01, 0.5
    )
    # The Summit-XL's tread is 0.15 m wide (its URDF's wheel cylinder); 0 keeps the point
    # contact every registered env was measured with (docs/physics.md "Tread width").
    contact_width: float = _f(
        0.0,
        "tyre–soil contact width across the tread, m (0: a point contact under the wheel "
        "centre; the Summit-XL's tread: 0.15)",
        0.0,
        0.5,
    )
    # A ground that yields (docs/physics.md "Ridges that yield"): each disc of the tread bears
    # at most the soil's bearing capacity on the slope under it; null keeps the rigid ground
    # every registered env was measured with. Wong's measured soils: sim.terramechanics.
    cohesion_kpa: float | None = _f(
        None,
        "Mohr–Coulomb cohesion c of the ground, kPa: each tread disc bears at most the soil's "
        "bearing capacity on the slope under it (needs contact_width > 0; null: a rigid ground)",
        0.0,
        200.0,
    )
    friction_angle_deg: float = _f(
        29.0, "Mohr–Coulomb internal friction angle φ of the ground, degrees", 1.0, 45.0
    )
    bulk_density: float = _f(
        1.3, "bulk density of the tilled ground, t/m³ (cultivated topsoil ≈ 1.1–1.6)", 0.5, 2.5
    )
    vertical_stiffness: float = _f(
        6.0e4, "tyre + soil vertical stiffness per wheel, N/m", 5.0e3, 3.0e5
    )
    damping_ratio: float = _f(0.3, "vertical damping ratio ζ of each wheel's corner", 0.0, 2.0)
    shear_damping: float = _f(
        0.05, "soil viscosity time of the shear deflection (damps stiction at rest), s", 0.0, 1.0
    )

    def at_defaults(self, *names: str) -> bool:
        """Whether the fields ``names`` hold their defaults: a check that fails with them so
        names what the user changed (the physics rate, another soil value) instead."""
        return all(getattr(self, n) == getattr(SoilConfig, n) for n in names)


#: the plantings the proxy camera's parameters are fitted on (``render.proxy_params``)
PROXY_PLANTINGS = ("ridged", "flat")
#: ``camera.proxy_fit``'s choices: a table by name, or ``auto``, each field's nearest one
PROXY_FIT_CHOICES = (*PROXY_PLANTINGS, "auto")


@dataclass(frozen=True)
class CameraConfig:
    model: str = _f(
        "proxy",
        "'proxy': analytic cylinders fitted to the crop meshes (fast, RL); 'mesh': the crop "
        "meshes themselves, ray-cast with Embree (D455 stereo model, RGB, instance ids)",
        choices=("proxy", "mesh"),
    )
    proxy_fit: str = _f(
        "ridged",
        "proxy: the plant parameters fitted to the meshes on 'ridged' lanes (0.12 m ridges, the "
        "camera in the furrow; every published proxy-camera result used them), on 'flat' "
        "planting (the default fields'), or 'auto': per field, the table nearer its ridge "
        "height (ridged from 0.06 m; docs/camera.md)",
        choices=PROXY_FIT_CHOICES,
    )
    width: int = _f(64, "image width, pixels (848 for datasets)", 8, 1280)
    height: int = _f(48, "image height, pixels (480 for datasets)", 6, 800)
    hfov_deg: float = _f(87.0, "horizontal field of view (D455 depth)", 10, 170)
    vfov_deg: float = _f(58.0, "vertical field of view (D455 depth)", 10, 170)
    min_range: float = _f(0.4, "closest valid depth, m (D455 ≈ 0.4)", 0.0, 10)
    max_range: float = _f(6.0, "farthest valid depth, m (D455 ideal range)", 0.5, 50)
    subpixel: float = _f(0.08, "stereo subpixel accuracy s in σ = z²·s/(f·B)", 0.0, 1)
    baseline: float = _f(0.095, "stereo baseline B, m (D455 95 mm)", 0.01, 1)
    native_width: int = _f(
        1280,
        "width of the sensor mode the image is resampled from: its focal length sets the "
        "stereo noise (both camera models; D455 1280 × 720)",
        64,
        4096,
    )
    rate_hz: int = _f(
        20, "update rate, Hz (a divisor of control_hz where the env observes depth)", 1, 200
    )
    rgb: bool = _f(False, "also produce an RGB image (info['rgb']); needs the depth observation")
    segmentation: bool = _f(
        False,
        "also produce a mask (needs the depth observation) 0 other, 1 soil, 2 crop, 3 weed, "
        "4 robot, 5 obstacle "
        "(info['segmentation']); mesh: and instance ids, rows of plants.csv on crop and weed "
        "pixels, of obstacles.csv on obstacle pixels, -1 elsewhere (info['instance'])",
    )
    threads: int = _f(
        1, "mesh: threads rendering a frame (1 for RL, where envs run in parallel)", 1, 64
    )
    renderer: str = _f(
        "auto",
        "mesh: 'raster' draws the views with the compiled rasteriser, 'raycast' casts one ray "
        "per pixel with Embree (the same images); 'auto' rasterises frames of at least "
        "100,000 pixels where the compiled kernels are built",
        choices=("auto", "raster", "raycast"),
    )


@dataclass(frozen=True)
class GnssFixConfig:
    """Fix-mode model (sensors.fixmode, docs/localisation.md): canopy over the antenna and
    multipath decide RTK fixed / float / standalone / no fix."""

    model: str = _f(
        "canopy",
        "canopy: the mode follows the sky the crop leaves; constant: the sky stays open (the "
        "best mode, but for multipath slips, multipath_mtbf_s)",
        choices=("canopy", "constant"),
    )
    elevation_mask_deg: float = _f(10.0, "satellites below this elevation are not used", 0, 60)
    foliage_db_per_m: float = _f(
        2.0,
        "L-band signal loss per metre of path through crop canopy, dB/m (sources: mature "
        "maize ≈ 0.4-1.5, tree crowns ≈ 1-2; 2 is assumed, the upper end: "
        "docs/localisation.md)",
        0.0,
        50.0,
    )
    foliage_profile: str = _f(
        "uniform",
        "foliage across each plant's canopy: uniform, or stalk (density 2(1 - r²/ρ²): leaves "
        "thin towards the canopy's edge, so the lane centre sees more sky than the row; "
        "assumed)",
        choices=("uniform", "stalk"),
    )
    carrier_db: float = _f(
        3.0, "foliage loss up to which carrier phase stays usable for RTK, dB", 0, 60
    )
    code_db: float = _f(15.0, "foliage loss up to which code (a position) is tracked, dB", 0, 60)
    fixed_sky: float = _f(0.5, "carrier-tracked sky fraction RTK fixed needs", 0.0, 1.0)
    float_sky: float = _f(0.25, "carrier-tracked sky fraction RTK float needs", 0.0, 1.0)
    standalone_sky: float = _f(0.1, "code-tracked sky fraction a standalone fix needs", 0.0, 1.0)
    loss_s: float = _f(0.5, "mean time to drop to the supported mode, s", 0.01, 100)
    acquire_standalone_s: float = _f(1.0, "mean time from no fix to standalone, s", 0.01, 600)
    acquire_float_s: float = _f(3.0, "mean time from standalone to RTK float, s", 0.01, 600)
    acquire_fixed_s: float = _f(
        10.0, "mean time from float to fixed (ambiguity resolution), s", 0.01, 600
    )
    multipath_mtbf_s: float = _f(
        600.0,
        "mean time between multipath slips fixed -> float under open sky, s (assumed; the "
        "sensitivity suite sweeps 40 s to none)",
        1,
        1e6,
    )
    azimuth_cells: int = _f(24, "sky model azimuth cells", 4, 360)
    elevation_cells: int = _f(6, "sky model elevation cells above the mask", 1, 90)
    update_m: float = _f(0.5, "recompute the sky when the antenna has moved this far, m", 0, 10)
    # Receiver faults under canopy (docs/localisation.md "GNSS faults"), all off by default.
    across_row_update_m: float | None = _f(
        None,
        "recompute the sky when the antenna has moved this far across the rows, m, so that the "
        "mode follows the antenna's place between the rows (null: update_m in every direction)",
        0.01,
        10,
    )
    refix_sky_exponent: float = _f(
        0.0,
        "re-fix slows with the clean sky: mean time from float to fixed is acquire_fixed_s / "
        "q_carrier^k (0: today's constant; assumed, swept 0-3)",
        0.0,
        10.0,
    )
    jump_rate_hz: float = _f(
        0.0,
        "multipath position jumps per second in float and standalone, times the foliage-"
        "covered sky fraction 1 - q_carrier, 1/s (0: off; assumed, swept 0-0.2)",
        0.0,
        10.0,
    )
    jump_float_m: float = _f(
        0.3, "RMS horizontal size of a multipath jump in RTK float, m", 0.0, 50.0
    )
    jump_standalone_m: float = _f(
        2.0, "RMS horizontal size of a multipath jump in a standalone fix, m", 0.0, 100.0
    )
    jump_duration_s: float = _f(
        2.0, "mean time a multipath jump lasts (reflection geometry changes), s", 0.05, 600
    )
    false_fix_prob: float = _f(
        0.0,
        "probability that an ambiguity fix is wrong (wrong integers, reported as RTK fixed "
        "with its optimistic accuracy) when the clean sky is just enough to fix (q_carrier = "
        "fixed_sky), falling linearly to 0 under open sky (0: off; swept 0-0.3)",
        0.0,
        1.0,
    )
    false_fix_m: float = _f(0.3, "RMS horizontal offset of a wrong-integer fix, m", 0.0, 10.0)
    false_fix_duration_s: float = _f(
        20.0,
        "mean time until the receiver detects a wrong fix and drops to float, s",
        0.1,
        3600,
    )

    @property
    def faults(self) -> bool:
        """Whether any receiver fault is switched on (they draw from a stream of their own)."""
        return self.jump_rate_hz > 0.0 or self.false_fix_prob > 0.0


@dataclass(frozen=True)
class GnssConfig:
    mode: str = _f(
        GNSS_RTK_FIXED,
        "best fix mode of the receiver setup (rtk_*: with base-station corrections)",
        choices=RECEIVER_MODES,
    )
    rate_hz: int = _f(10, "update rate, Hz (ZED-F9P up to 20; a divisor of control_hz)", 1, 20)
    latency_s: float = _f(
        0.1, "delay from a fix's epoch to its arrival at the robot's computer, s", 0.0, 2.0
    )
    fix: GnssFixConfig = dc_field(default_factory=GnssFixConfig)
    baseline_km: float = _f(1.0, "distance to the RTK base station, km (the 1 ppm term)", 0, 100)
    antenna_x: float = _f(-0.25, "antenna position behind base_link (rear mast), m", -1, 1)
    antenna_height: float = _f(0.60, "antenna height above base_link, m", 0, 3)


@dataclass(frozen=True)
class ImuConfig:
    gyro_noise_deg_s_rthz: float = _f(0.01, "gyro noise density, °/s/√Hz (MTi-300)", 0, 10)
    gyro_bias_deg_h: float = _f(
        10.0, "gyro bias std, °/h (Gauss-Markov; MTi-300 in-run bias stability)", 0, 1e4
    )
    accel_noise_ug_rthz: float = _f(60.0, "accelerometer noise density, µg/√Hz", 0, 1e5)
    accel_bias_ug: float = _f(15.0, "accelerometer bias std, µg (Gauss-Markov)", 0, 1e5)
    bias_tau_s: float = _f(300.0, "correlation time of the Gauss-Markov biases, s", 1, 1e6)
    roll_pitch_rms_deg: float = _f(0.2, "orientation estimate error, roll/pitch RMS", 0, 10)
    heading_rms_deg: float = _f(1.0, "orientation estimate error, heading RMS", 0, 45)
    orientation_tau_s: float = _f(10.0, "correlation time of the orientation error, s", 0.05, 1e5)


@dataclass(frozen=True)
class OdomConfig:
    noise: float = _f(0.01, "relative std of each wheel speed reading", 0, 1)


#: robot_localization's process_noise_covariance diagonal for x, y, yaw, vx, vy, vyaw, ax, ay:
#: its default (``FilterBase::reset`` in src/filter_base.cpp and params/ekf.yaml, humble-devel)
RL_PROCESS_NOISE = (0.05, 0.05, 0.06, 0.025, 0.025, 0.02, 0.01, 0.01)
#: the same default for the variables only the 3D filter carries: z, roll, pitch, vz, vroll,
#: vpitch, az
RL_PROCESS_NOISE_3D = (0.06, 0.03, 0.03, 0.04, 0.01, 0.01, 0.015)


@dataclass(frozen=True)
class RobotLocalizationConfig:
    """``localisation.kind: robot_localization``: robot_localization's ``ekf_node`` (Humble) in
    ``two_d_mode`` (or, with ``two_d_mode`` false, its full 3D filter) with
    ``navsat_transform_node``, configured as Nav2's GPS tutorial does
    (``odom0`` twist vx, vy, vyaw; ``imu0`` yaw; ``odom1`` the GPS odometry x, y). Defaults are
    robot_localization's own or the drivers' documented values (docs/localisation.md)."""

    two_d_mode: bool = _f(
        True,
        "ekf_node's two_d_mode (Nav2's GPS tutorial): x, y, yaw on a plane, roll and pitch "
        "zero, so navsat_transform removes the antenna offset through yaw only; false: the full "
        "15-variable filter, the IMU's roll and pitch fused, the offset removed through the "
        "filter's whole attitude (what a user on tilted or ridged ground can set)",
    )
    process_noise: tuple[float, float, float, float, float, float, float, float] = _f(
        RL_PROCESS_NOISE,
        "process_noise_covariance diagonal for x, y, yaw, vx, vy, vyaw, ax, ay, per second "
        "(robot_localization scales it by the step; its Humble default)",
        0.0,
        100.0,
    )
    process_noise_3d: tuple[float, float, float, float, float, float, float] = _f(
        RL_PROCESS_NOISE_3D,
        "process_noise_covariance diagonal for z, roll, pitch, vz, vroll, vpitch, az, per "
        "second (two_d_mode false only; robot_localization's Humble default)",
        0.0,
        100.0,
    )
    initial_covariance: float = _f(
        1e-9,
        "initial_estimate_covariance of the variables no first reading sets (the "
        "accelerations; in 3D also z and the roll and pitch rates), "
        "robot_localization's default",
        0.0,
        1e6,
    )
    odom_twist_variance: tuple[float, float, float] = _f(
        (0.001, 0.001, 0.01),
        "variance of the odometry's vx (m²/s²), vy and vyaw (rad²/s²) as the diff-drive "
        "controller reports it (twist_covariance_diagonal: ros2_controllers' suggested start; "
        "its default 0 is floored to 1e-9 by robot_localization)",
        0.0,
        100.0,
    )
    imu_yaw_sigma_deg: float = _f(
        1.0,
        "yaw std in the IMU driver's orientation covariance, degrees (the MTi-300 heading spec; "
        "the Xsens driver's default 0 is floored to 1e-9)",
        0.0,
        180.0,
    )
    imu_roll_pitch_sigma_deg: float = _f(
        0.2,
        "roll and pitch std in the IMU driver's orientation covariance, degrees, fused when "
        "two_d_mode is false (the MTi-300's dynamic roll/pitch spec)",
        0.0,
        90.0,
    )
    fuse_imu_yaw_rate: bool = _f(
        False, "also fuse the gyro's yaw rate (imu0_config vyaw; all three rates in 3D)"
    )
    imu_yaw_rate_sigma_deg_s: float = _f(
        0.05, "yaw-rate std in the IMU driver's angular velocity covariance, °/s", 0.0, 100.0
    )
    fuse_imu_acceleration: bool = _f(
        False,
        "also fuse the accelerometer's horizontal specific force with gravity removed through "
        "the IMU's roll and pitch (imu0_config ax, ay; imu0_remove_gravitational_acceleration; "
        "in 3D az too)",
    )
    imu_accel_sigma: float = _f(
        0.05,
        "std in the IMU driver's linear_acceleration_covariance, m/s² (0.2° of attitude error "
        "left after removing gravity: the Nav2 export's value)",
        1e-4,
        10.0,
    )
    imu_accel_rejection_threshold: float | None = _f(
        None,
        "imu0_linear_acceleration_rejection_threshold, Mahalanobis distance (null: never)",
        0.0,
        1e6,
    )
    gps_lever_arm: bool = _f(
        False,
        "a base_link -> gps transform exists, so navsat_transform removes the antenna offset "
        "(rotated by the filter's yaw); false: the fix is taken as base_link's position",
    )
    odom_rejection_threshold: float | None = _f(
        None,
        "odom0_twist_rejection_threshold: Mahalanobis distance beyond which a reading is "
        "dropped (null: never, robot_localization's default)",
        0.0,
        1e6,
    )
    imu_rejection_threshold: float | None = _f(
        None, "imu0_pose_rejection_threshold (and _twist_), Mahalanobis distance", 0.0, 1e6
    )
    gps_rejection_threshold: float | None = _f(
        None, "odom1_pose_rejection_threshold for the GPS odometry, Mahalanobis distance", 0.0, 1e6
    )
    smooth_lagged_data: bool = _f(
        False,
        "revert to the state before a late reading and replay (false, the default: a reading "
        "older than the filter's last one is fused into the current state as if current)",
    )
    history_length_s: float = _f(
        0.0, "history kept for smooth_lagged_data, s (robot_localization's default 0)", 0.0, 10.0
    )


@dataclass(frozen=True)
class LocalisationConfig:
    """Which pose the policies get (estimation/, docs/localisation.md) and the EKF's model.

    ``ekf`` (also named ``ekf-oracle``): a robot_localization-style EKF fusing GNSS (with its
    latency), IMU and wheel odometry whose noise models are the simulator's own — an upper
    bound; ``robot_localization``: robot_localization as a Nav2 user runs it; ``blend``: each
    fix through the lever arm, odometry between fixes, no filter; ``ideal``: ground truth — for
    debugging only, no real robot has it.
    """

    kind: str = _f(
        "ekf",
        "estimator of the pose policies see (ekf-oracle: another name for ekf)",
        choices=("ekf", "ekf-oracle", "robot_localization", "blend", "ideal"),
    )
    init_position_sigma: float = _f(
        0.5, "std of the start position when there is no fix at the start, m", 0.0, 100
    )
    init_yaw_sigma_deg: float = _f(3.0, "prior std of the start heading, degrees", 0.0, 180)
    pose_noise: float = _f(1e-4, "process noise density of x and y, m²/s", 0.0, 10)
    yaw_noise: float = _f(1e-5, "process noise density of the heading, rad²/s", 0.0, 10)
    velocity_noise: float = _f(0.01, "process noise density of vx and vy, m²/s³", 0.0, 100)
    accel_noise: float = _f(
        0.4, "random-walk density of ax, ay, (m/s²)²/s (0.6 m/s² limit reached in ≈ 1 s)", 0, 100
    )
    yaw_accel_noise: float = _f(
        2.25, "random-walk density of the yaw rate, (rad/s)²/s (1.5 rad/s² limit)", 0, 1000
    )
    odom_speed_rel: float = _f(0.03, "odometry speed white noise relative to speed", 0.0, 1.0)
    odom_scale_sigma: float = _f(
        0.1, "prior std of the odometry speed scale error (slip, tyre deflection)", 0.0, 1.0
    )
    odom_scale_noise: float = _f(
        1e-4, "random-walk density of the odometry speed scale error, 1/s", 0.0, 1.0
    )
    odom_yaw_rel: float = _f(0.15, "odometry yaw-rate std relative to it (after χ)", 0.0, 1.0)
    odom_floor: float = _f(0.01, "odometry speed and yaw-rate std floor, m/s and rad/s", 1e-4, 1)
    lateral_sigma: float = _f(
        0.05, "std of the skid-steer's zero lateral velocity pseudo-measurement, m/s", 1e-3, 10
    )
    gyro_sigma_deg_s: float = _f(
        0.05, "yaw-rate std of the gyro at the control rate, °/s", 1e-4, 10
    )
    use_accel: bool = _f(True, "fuse the accelerometer's horizontal specific force")
    accel_sigma: float = _f(
        0.05, "accelerometer std after removing gravity (0.2° attitude error), m/s²", 1e-3, 10
    )
    heading_bias_deg: float = _f(1.0, "IMU heading error std (MTi-300: 1° RMS), degrees", 0.0, 45)
    heading_bias_tau_s: float = _f(10.0, "correlation time of the IMU heading error, s", 0.05, 1e5)
    gnss_white: float = _f(0.003, "white part of each GNSS fix's error, m", 1e-4, 10)
    gnss_tau_rtk_fixed_s: float = _f(5.0, "correlation time of RTK-fixed errors, s", 0.05, 1e4)
    gnss_tau_rtk_float_s: float = _f(30.0, "correlation time of RTK-float errors, s", 0.05, 1e4)
    gnss_tau_standalone_s: float = _f(60.0, "correlation time of standalone errors, s", 0.05, 1e4)
    history_s: float = _f(1.0, "oldest fix age processed (older ones are dropped), s", 0.05, 10)
    robot_localization: RobotLocalizationConfig = dc_field(
        default_factory=RobotLocalizationConfig,
        metadata={"doc": "the robot_localization estimator's parameters (kind robot_localization)"},
    )


@dataclass(frozen=True)
class TaskConfig:
    corridor: float | None = _f(
        None, "max |cross-track error| in a furrow, m (null: half the row spacing)", 0.01, 10
    )
    headland_corridor: float = _f(1.0, "max |cross-track error| on the headland, m", 0.05, 20)
    max_crops_hit: int = _f(10, "episode fails after this many distinct crops hit", 0, 10**6)
    max_tilt_deg: float = _f(60.0, "roll or pitch beyond this is a tip-over", 5, 90)
    # A 0.62 m robot in 0.76 m rows (preset narrow-rows) has ≈7 cm to spare each side: a larger
    # start offset would begin many episodes in the crop.
    start_lateral_std: float = _f(0.03, "start pose lateral perturbation std, m", 0, 5)
    start_heading_std_deg: float = _f(3.0, "start pose heading perturbation std", 0, 90)
    route_points: int = _f(10, "waypoints in the route observation", 1, 100)
    route_spacing: float = _f(0.4, "arc-length spacing of route observation points, m", 0.05, 10)
    success_tolerance: float = _f(0.3, "route end reached within this arc length, m", 0.01, 10)
    # Nav2 Humble's SimpleProgressChecker (nav2_controller): required_movement_radius 0.5 m,
    # movement_time_allowance 10 s. Off by default: the paper and ood suites turn it on.
    progress_time: float | None = _f(
        None,
        "episode fails when the robot stays within progress_radius for this long, s "
        "(Nav2's progress checker; null: never)",
        0.5,
        3600,
    )
    progress_radius: float = _f(
        0.5, "distance the robot must move within progress_time, m (Nav2: 0.5)", 0.01, 10
    )
    # A robot that keeps Nav2's progress checker quiet moves progress_radius every progress_time
    # (0.05 m/s): a limit of progress_time / progress_radius seconds per metre of route (20)
    # never ends an episode such a robot would finish, whatever its speed.
    seconds_per_metre: float | None = _f(
        None,
        "the episode is truncated after this many seconds per metre of its route "
        "(null: the registered step limit only)",
        0.1,
        3600,
    )
    # Nav2's waypoint follower sends each GPS waypoint as its own NavigateToPose goal, so the
    # plan the controller follows ends at the next waypoint until the goal checker passes it
    # (nav2_waypoint_follower, nav2_controller SimpleGoalChecker: xy_goal_tolerance 0.25 m).
    waypoint_goals: bool = _f(
        False,
        "a route planned through GPS waypoints (route.waypoints) is handed over a leg at a time "
        "as Nav2's waypoint follower does: the route observation ends at the next waypoint "
        "until the estimated pose is within goal_tolerance of it",
    )
    goal_tolerance: float = _f(
        0.25, "waypoint_goals: a waypoint is reached this close, m (Nav2: 0.25)", 0.01, 5
    )
    # Humble's default behaviour tree (agrinav_gym/recoveries.py): number_of_retries 6.
    recoveries: bool = _f(
        False,
        "a progress-check failure runs Nav2's recovery behaviours (clear the costmap and "
        "retry; then clear both, spin, wait, back up in turn) instead of ending the episode, "
        "which fails after recovery_retries of them for one goal; needs progress_time",
    )
    recovery_retries: int = _f(6, "recoveries: round-robin recoveries per goal (Nav2: 6)", 0, 100)
    # nav2_waypoint_follower's stop_on_failure: true in its code, false in Humble's
    # nav2_params.yaml (the follower then reports the waypoint missed and goes on)
    stop_on_failure: bool = _f(
        True,
        "waypoint_goals with recoveries: a waypoint the tree gives up on ends the episode "
        "(true) or is counted in missed_waypoints and the next one sent (false); the route's "
        "end always ends it",
    )


@dataclass(frozen=True)
class RenderConfig:
    width: int = _f(640, "rgb_array frame width, pixels (640: rows legible in a video)", 64, 1920)
    height: int = _f(480, "rgb_array frame height, pixels", 48, 1080)
    distance: float = _f(3.5, "chase camera distance behind the robot, m", 0.5, 50)
    elevation: float = _f(3.5, "chase camera height above the robot, m", 0.0, 50)


@dataclass(frozen=True)
class LightingConfig:
    """The soil colour and the sun the cameras and the chase view shade with."""

    soil_rgb: tuple[float, float, float] | None = _f(
        None, "soil colour, RGB in [0, 1] (null: the default soil, 0.45 0.33 0.22)", 0.0, 1.0
    )
    sun_azimuth_deg: float = _f(33.7, "sun azimuth, degrees counter-clockwise from east", -360, 360)
    sun_elevation_deg: float = _f(68.4, "sun elevation above the horizon, degrees", 0, 90)


@dataclass(frozen=True)
class EnvConfig:
    robot: RobotConfig = dc_field(default_factory=RobotConfig)
    soil: SoilConfig = dc_field(default_factory=SoilConfig)
    camera: CameraConfig = dc_field(default_factory=CameraConfig)
    render: RenderConfig = dc_field(default_factory=RenderConfig)
    lighting: LightingConfig = dc_field(default_factory=LightingConfig)
    gnss: GnssConfig = dc_field(default_factory=GnssConfig)
    imu: ImuConfig = dc_field(default_factory=ImuConfig)
    odom: OdomConfig = dc_field(default_factory=OdomConfig)
    localisation: LocalisationConfig = dc_field(default_factory=LocalisationConfig)
    task: TaskConfig = dc_field(default_factory=TaskConfig)
    #: reward term name -> its parameters (``rewards.REWARD_TERMS``), weights included
    reward: dict[str, Any] = dc_field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: Any) -> EnvConfig:
        from .rewards import build_reward_terms

        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise InputError("config", data, "allowed: a mapping of config sections (or None)")
        data = merge({}, data, "config")
        terms = build_reward_terms(data.pop("reward", None))
        cfg: EnvConfig = from_mapping(cls, data, "config.")
        cfg = dataclasses.replace(cfg, reward=terms)
        cfg.check()
        return cfg

    def to_dict(self) -> dict[str, Any]:
        from .rewards import reward_terms_to_dict

        out = to_mapping(dataclasses.replace(self, reward={}))
        out["reward"] = reward_terms_to_dict(self.reward)
        return out

    def check(self) -> None:
        r = self.robot
        if r.physics_hz % r.control_hz:
            raise InputError(
                "config.robot.physics_hz",
                r.physics_hz,
                f"allowed: a multiple of control_hz ({r.control_hz})",
            )
        # the camera's rate is checked by an env that observes depth (no camera, no rate)
        if r.control_hz % self.gnss.rate_hz:
            raise InputError(
                "config.gnss.rate_hz",
                self.gnss.rate_hz,
                f"allowed: a divisor of robot.control_hz ({r.control_hz})",
            )
        # The tyres' vertical springs are integrated explicitly at the physics rate: a 6.5 kg
        # wheel on stiffness k oscillates at √(k/m); keep √(k/m)·Δt ≤ 1 (stable below 2).
        k_max, k = 6.5 * r.physics_hz**2, self.soil.vertical_stiffness
        need = math.ceil(math.sqrt(k / 6.5))
        if k > k_max and self.soil.at_defaults("vertical_stiffness"):
            raise InputError(
                "config.robot.physics_hz",
                r.physics_hz,
                f"allowed with soil.vertical_stiffness {k:g} N/m: at least {need} (slower, the "
                "tyres' vertical springs are not integrated stably)",
            )
        if k > k_max:
            raise InputError(
                "config.soil.vertical_stiffness",
                self.soil.vertical_stiffness,
                f"allowed: at most {k_max:.3g} N/m at robot.physics_hz {r.physics_hz} (this "
                f"stiffness's springs need physics_hz >= {need})",
            )
        if self.gnss.latency_s > self.localisation.history_s:
            raise InputError(
                "config.gnss.latency_s",
                self.gnss.latency_s,
                f"allowed: at most localisation.history_s ({self.localisation.history_s} s)",
            )
        fix = self.gnss.fix
        # the chain tests fixed before float and carrier before code: an order the other way
        # round would leave a threshold without effect
        if fix.float_sky > fix.fixed_sky:
            raise InputError(
                "config.gnss.fix.float_sky",
                fix.float_sky,
                f"allowed: at most fixed_sky ({fix.fixed_sky:g}): RTK float needs no more sky "
                "than fixed",
            )
        if fix.carrier_db > fix.code_db:
            raise InputError(
                "config.gnss.fix.carrier_db",
                fix.carrier_db,
                f"allowed: at most code_db ({fix.code_db:g}): carrier phase is lost before the "
                "code",
            )
        if self.camera.min_range >= self.camera.max_range:
            raise InputError(
                "config.camera.min_range", self.camera.min_range, "allowed: below max_range"
            )
        if self.task.recoveries and self.task.progress_time is None:
            raise InputError(
                "config.task.recoveries",
                True,
                "recovers from what the progress checker finds; allowed: with "
                "task.progress_time set (Nav2: 10 s)",
            )
