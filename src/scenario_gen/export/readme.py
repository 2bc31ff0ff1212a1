"""The README.md each export carries: what is in the folder and how to open it."""

from __future__ import annotations

from typing import Any

from ..model import Scenario
from ..vertical import of_scenario
from .gazebo import GazeboSummary


def _head(scn: Scenario, what: str) -> str:
    g = scn.geo
    return (
        f"# {scn.spec.name} (seed {scn.seed}) — {what}\n\n"
        f"Written by `agrinav export`. Datum (ENU origin): lat {g.lat:.8f}, lon {g.lon:.8f}, "
        f"alt {g.alt:.3f} m; x east, y north, z up, metres. {len(scn.plants)} plants, "
        f"route {scn.route.length:.1f} m.\n\n"
        f"Heights (the datum's alt and every altitude written here): "
        f"{of_scenario(scn.info).label()}.\n\n![layout](preview.png)\n\n"
    )


def gazebo_section(g: GazeboSummary) -> str:
    plants = (
        f"{g.plants} plants merged into {g.tiles} static tiles (`models/agrinav_tile_*`: real "
        "plant meshes at exact pose and size as per-colour binary STL; the crops' stem proxies "
        "as one collision mesh of 8-sided prisms per tile)"
        if g.mode == "tiles"
        else f"{g.plants} plants, one `<include>` each with the scenario's pose "
        "(x y z roll pitch yaw, R = Rz·Ry·Rx); one model per species/growth holds the mesh "
        "and texture, size variants 2 % apart reuse it (height within 1 %)"
    )
    hm = (
        "- `worlds/field_heightmap.sdf` — Gazebo Sim only: the terrain as a 16-bit heightmap "
        "resampled to a (2^n+1)² grid (Gazebo Classic reads heightmap images as 8-bit).\n"
        if len(g.worlds) > 2
        else ""
    )
    obstacles = ""
    if g.obstacles:
        counts = ", ".join(f"{n} {k}" for k, n in g.obstacles.items())
        obstacles = f"- Obstacles ({counts}; {g.obstacle_triangles:,} triangles): " + (
            "one static model each in the worlds, named `<kind>_<id>` (the id is the row "
            "of the scenario's `obstacles.csv`) at the obstacle's pose, its visual and "
            "collision its own mesh (`models/agrinav_obstacles/meshes/<kind>_<id>.stl`, in its "
            "own frame), "
            "coloured by kind; `models/agrinav_obstacles/model.sdf` holds them all as one "
            "model to insert elsewhere.\n"
            if g.obstacle_mode == "models"
            else f"merged into {g.obstacle_tiles} static tiles "
            "(`models/agrinav_obstacle_tile_*`: the meshes at their poses, one STL per "
            "kind as the visuals, coloured by kind, and one collision mesh per tile).\n"
        )
    return f"""## Gazebo

- `worlds/field.sdf` — Gazebo Sim (Fortress, Garden, Harmonic; system plugins use the
  Fortress names, which Harmonic still accepts; for Ionic and later replace
  `ignition-gazebo-` by `gz-sim-` and `ignition::gazebo` by `gz::sim`).
- `worlds/field_classic.world` — Gazebo Classic 11 (`heading_deg` 180 compensates Classic's
  rotated GPS frame, gazebo-classic bug report 2022; the poses are identical).
{hm}- `models/` — `agrinav_terrain` (textured COLLADA mesh, also the collision) and {plants}.
  Triangles in the plants: {g.triangles:,}.
{obstacles}
```bash
. setup.bash                       # sets GAZEBO_MODEL_PATH and the Gazebo Sim resource paths
gz sim worlds/field.sdf            # Garden and later  (Fortress: ign gazebo worlds/field.sdf)
gazebo worlds/field_classic.world  # Gazebo Classic 11
```

A NavSat/GPS sensor in either world reports the lat/lon of `plants.csv`/`route.csv` for the
same ENU position (checked with libsdformat and ignition-math's SphericalCoordinates).
"""


def gazebo_readme(scn: Scenario, g: GazeboSummary) -> str:
    return _head(scn, "Gazebo world") + gazebo_section(g)


def nav2_readme(scn: Scenario, g: GazeboSummary, info: dict[str, Any]) -> str:
    from .ros_config import FOLLOW_RETRIES, REPLAN_HZ
    from .ros_robot import Nav2Robot, marking_range

    lat, lon = scn.geo.lat, scn.geo.lon
    robot: Nav2Robot = info["robot"]
    d, c, gn, imu = robot.drive, robot.camera, robot.gnss, robot.imu
    x, y, z, yaw = info["spawn"]
    w, h = info["depth_image"]
    base = info["base_height"]
    chi = d.skid_factor
    fp, cm = robot.dwb["FollowPath"], robot.dwb["local_costmap"]
    vl = cm["voxel_layer"]
    src = vl["depth_camera"]
    rs = robot.dwb.get("rotation_shim") or {}
    shim = (
        " Nav2's RotationShimController stands in front of it (`FollowPath` is the shim, DWB "
        f"its `primary_controller`): on a new plan more than {rs['angular_dist_threshold']:g} "
        f"rad off the heading it turns in place at {rs['rotate_to_heading_angular_vel']:g} "
        "rad/s first."
        if rs.get("enabled")
        else ""
    )
    same = (
        f", which is the same {fp['prune_distance']:g} m, so they drive alike"
        if fp["prune_distance"] == fp["forward_prune_distance"]
        else f" ({fp['prune_distance']:g} m here): use Humble 1.1.7 or later"
    )
    rows = [
        ("robot/summit_xl.urdf", "agrinav_gym's Summit-XL, as the simulator reads it"),
        (
            "robot/summit_xl_gazebo.urdf",
            f"the same plus, for Gazebo Sim: a `base_footprint` root {base:.2f} m under base_link "
            "(the ground under the wheels), the camera and antenna mounts from the env's config, "
            "the sensors, tyre friction, the skid-steer drive and joint states",
        ),
        (
            "config/bridge.yaml",
            "ros_gz_bridge: `/clock`, the sensors, the drive's odometry and command, joint states",
        ),
        (
            "config/sensor_covariances.yaml",
            "the standard deviations `scripts/sensor_covariances.py` stamps on the bridged IMU, "
            "GNSS and wheel odometry",
        ),
        (
            "config/ekf.yaml`, `config/navsat_transform.yaml",
            "robot_localization: ekf_local (odom → base_footprint), ekf_global (map → odom), "
            "navsat_transform (map frame = this export's ENU frame, "
            f"`datum: [{lat:.10f}, {lon:.10f}, 0.0]`)",
        ),
        ("config/nav2_params.yaml", f"Nav2 with DWB as benchmarked ({robot.controller})"),
        (
            "config/nav2_params_nav2_defaults.yaml",
            "the same with DWB as Nav2 Humble ships it (dwb:nav2: its nav2_params.yaml with the "
            "Summit-XL's limits and footprint)",
        ),
        (
            "behavior_trees/follow_route.xml`, `behavior_trees/navigate_to_pose.xml",
            "bt_navigator's trees: the route follower's (NavigateThroughPoses) and one for a "
            "single goal (NavigateToPose, e.g. from RViz); no recoveries that need Nav2's "
            "behavior server, which the bundle does not start",
        ),
        (
            "scripts/follow_route.py`, `scripts/sensor_covariances.py",
            "the bundle's two ROS 2 programs (rclpy; standard library and PyYAML otherwise)",
        ),
        ("launch/agrinav_field.launch.py", "all of the above (ROS 2 Humble Python launch)"),
    ]
    files = "| file | what |\n|---|---|\n" + "".join(f"| `{f}` | {what} |\n" for f, what in rows)
    return (
        _head(scn, "ROS 2 / Nav2 bundle")
        + f"""The source paper's experiment in Gazebo Sim: the Summit-XL follows the GPS waypoints
through this maize field with Nav2's DWB controller as AgriNav benchmarks it
({robot.controller}), localised by robot_localization from its simulated GNSS, IMU and wheel
odometry, seeing the crop with its RealSense D455 depth camera.

## Run it (ROS 2 Humble, Gazebo Sim Fortress)

```bash
sudo apt install ros-humble-ros-gz ros-humble-navigation2 ros-humble-robot-localization
sudo apt install ros-humble-robot-state-publisher   # ros-humble-ros-gz brings Gazebo Fortress
source /opt/ros/humble/setup.bash
. setup.bash                                          # model paths for Gazebo
ros2 launch launch/agrinav_field.launch.py            # everything; the robot drives the route
ros2 launch launch/agrinav_field.launch.py headless:=true record:=track.csv
ros2 launch launch/agrinav_field.launch.py controller:=nav2_defaults   # DWB as Nav2 ships it
ros2 launch launch/agrinav_field.launch.py follow:=false  # all but the follower
```

The launch file starts Gazebo Sim with `worlds/field.sdf` and spawns
`robot/summit_xl_gazebo.urdf` at the route start (base_link at x {x:.3f}, y {y:.3f},
z {z:.3f} m, yaw {yaw:.4f} rad); then ros_gz_bridge, robot_state_publisher,
`scripts/sensor_covariances.py`, robot_localization (ekf_local, ekf_global, navsat_transform),
Nav2 (controller_server, planner_server, bt_navigator, their lifecycle manager) and
`scripts/follow_route.py`. The follower first sends every GPS waypoint through
navsat_transform's `fromLL` and stops if one lands more than 5 cm from its ENU position (the
datum is wrong); then it moves Nav2's goals along the route until the route's end is reached
(exit 0) or Nav2 gives up, progress stalls for 60 s or localisation is lost (exit 1).
`record:=FILE` keeps the robot's poses with their cross-track error, to score with the
paper's metrics: `agrinav_gym.metrics.cross_track_metrics(poses, path_xy, labels=segment)`
against `reference_path.csv`.

## Files

{files}
## How it reproduces the benchmark

**The route is the plan.** The benchmark's DWB takes the route ahead of the robot as its global
plan: {robot.route_points} points {robot.route_spacing} m apart from the robot's estimated
position on the route, re-read every step. Nav2 Humble has no behaviour-tree node that turns
poses into a path without a planner, and no `followGpsWaypoints` (Iron and later); the GPS
waypoints alone would also lose the headland turns between them. So the follower sends those
same route points as a NavigateThroughPoses goal, moved on as the robot advances (found on
`reference_path.csv` as the benchmark's route tracker finds it), and the tree replans through
them at {REPLAN_HZ:g} Hz: NavFn joins consecutive points on an obstacle-free rolling global
costmap, i.e. with straight lines, so the path is the route to a cell (5 cm). Obstacles are the
local costmap's business, as in the benchmark. A FollowPath failure (no legal trajectory)
clears the local costmap and retries, the benchmark's one recovery, up to
{FOLLOW_RETRIES} times; there is no spin, back-up or wait.

**DWB** under Nav2's names from AgriNav's configuration `{robot.controller}` (docs/dwb.md):
every value of `dwb_nav2.yaml` with that configuration's changes (plan pruning
{fp["prune_distance"]:g} m behind and {fp["forward_prune_distance"]:g} m ahead, footprint
padding {cm["footprint_padding"]:g} m, obstacles between {src["min_obstacle_height"]:g} and
{vl["max_obstacle_height"]:g} m in the voxel layer, at most {fp["max_vel_x"]:g} m/s) and the
robot's limits ({d.v_max} m/s, {d.w_max} rad/s, {d.a_max} m/s², {d.alpha_max} rad/s²) and
footprint (0.724 × 0.616 m).{shim} Controller {d.control_hz} Hz; local costmap rolling 3 × 3 m
at 5 cm, a voxel layer on the depth camera's cloud and inflation. `forward_prune_distance` is
declared from Nav2 Humble 1.1.7 (June 2023); earlier releases cut the plan's far end at
`prune_distance`{same}. The cloud's heights are measured from `base_footprint` in the odometry
plane (robot_localization's `two_d_mode`), i.e. above the wheels' plane, as the benchmark's
costmap measures them (its 0.175 m ground rejection).

**Sensors** (`robot/summit_xl_gazebo.urdf`; Fortress plugin names, see below):

- IMU (Xsens MTi-300 model) at {imu.rate_hz} Hz, the rate the env reads it, white noise from
  the datasheet densities (gyro {imu.gyro_noise_deg_s_rthz} °/s/√Hz, accelerometer
  {imu.accel_noise_ug_rthz:g} µg/√Hz); orientation in ENU (yaw 0 = east). Gazebo adds no bias
  and no orientation error; the covariances say the env's (0.2° roll and pitch, 1° heading).
- GNSS (u-blox ZED-F9P, {gn.mode}) at {gn.rate_hz} Hz on the mast {abs(gn.antenna_x):.2f} m behind
  and {gn.antenna_z:.2f} m above base_link, white noise σ {gn.sigma_h * 1000:.1f} mm per
  horizontal axis (Gazebo applies it to latitude and longitude in degrees: the value is σ
  over the metres per degree of latitude here, so east–west noise is cos(lat) times
  smaller). The env's time-correlated errors, 0.1 s latency and the canopy's fix modes
  (docs/localisation.md) have no Gazebo model: this is an always-RTK-fixed receiver.
- Depth camera (RealSense D455) at its mount ({c.x} m ahead, {c.z} m above base_link,
  pitched {c.pitch_deg:g}° down), {c.rate_hz} Hz, {c.hfov_deg:g}° × {c.vfov_deg:g}°,
  {c.min_range}–{c.max_range} m. The env's {c.width} × {c.height} image has non-square pixels;
  Gazebo's depth camera has square ones (Fortress ignores lens intrinsics for depth cameras),
  so the bundle keeps the width and both fields of view: {w} × {h}. Noise: one σ for every
  depth, the D455 model's at the voxel layer's marking range ({marking_range(robot):g} m:
  z²·s/(f·B)); the env's grows with z².
- Drive: Gazebo's DiffDrive on the four wheel joints (skid-steer: two per side) with the
  URDF's wheel radius 0.11 m and track 0.470 m, limited to the env's speeds and accelerations,
  publishing odometry at {d.control_hz} Hz; tyre–soil friction μ = {d.friction} on the wheels.
  The simulator widens the track by χ = {chi:.2f} ({chi * 0.47:.2f} m) so that commanded yaw
  rates are met on its soil (docs/physics.md); set `wheel_separation` to that in the drive
  plugin to command the robot as the simulator does. How much a skid-steer slips in Gazebo
  depends on its contact model, not on AgriNav's tyre model: the wheel odometry's yaw rate is
  therefore not fused; the EKFs take the gyro's, as the benchmarked DWB does
  (`yaw_rate_source: imu`).

**Localisation**: two EKFs as in Nav2's GPS navigation guide. ekf_local fuses wheel odometry
(vx, and vy = 0 of a skid-steer) and the IMU (yaw, yaw rate and, with gravity removed,
horizontal specific force) in the odom frame; navsat_transform turns fixes into odometry in the
map frame; ekf_global adds it. Rates {d.control_hz} Hz (the env's control rate) and
{gn.rate_hz} Hz; process noise from the env's EKF. Gazebo's messages carry no covariances
(robot_localization would then trust every sensor alike), so `scripts/sensor_covariances.py`
republishes them with the env's: `/sim/imu` → `/imu/data`, `/sim/gps/fix` → `/gps/fix`,
`/sim/wheel/odometry` → `/wheel/odometry`. The drive's own odom → base_footprint transform is
not bridged: ekf_local publishes that one.

Frames: `map` (ENU at the datum) → `odom` → `base_footprint` → `base_link` → `imu_link`,
`gps_link`, `camera_link` (the sensors' frame ids; the cloud is in camera_link, x forward) and
the wheels (from `/joint_states`).

## Gazebo Classic 11 and newer Gazebo Sim

`sim:=classic` starts Gazebo Classic with `worlds/field_classic.world` and spawns
`robot/summit_xl.urdf` (no sensors or drive): Classic needs other plugins, which this bundle
does not write — `libgazebo_ros_diff_drive.so` (`<num_wheel_pairs>2</num_wheel_pairs>`),
`libgazebo_ros_imu_sensor.so`, `libgazebo_ros_gps_sensor.so` (for which the Classic world
says `heading_deg` 180, see "Gazebo" below) and `libgazebo_ros_camera.so` on a `depth`
sensor, each publishing to ROS itself (no bridge) with its frame in `<frame_name>`. Gazebo
Sim Garden and Harmonic read the Fortress names used here with a deprecation warning and take
the frame ids from `<gz_frame_id>`, which the URDF carries beside Fortress's
`<ignition_frame_id>` (recent Fortress releases warn once per sensor that it has both); for
Ionic and later replace `ignition-gazebo-` by `gz-sim-` and `ignition::gazebo` by `gz::sim`
here and in the world.

## What was verified, and how

This bundle has never been run with ROS: neither ROS 2 nor Gazebo is installed where it was
made. What its tests (tests/scenario_gen/export/test_nav2_bundle.py in AgriNav Gym) check:

- **libsdformat 12** (the parser Gazebo Fortress uses, through `tools/sdf_check`) loads
  `robot/summit_xl_gazebo.urdf` as Gazebo loads a spawned model, with warnings and unknown
  elements as errors (the frame-id elements aside): the link and joint graph, masses, the
  three sensors at their mounts with their rates, topics, frame ids, noise and camera, the
  friction, and the drive's joints, track and radius as the URDF has them. `worlds/field.sdf`
  passes the same checker with the systems the sensors need.
- **Every parameter name and its type** in `config/*.yaml` and in the launch file's
  parameter dictionaries is one the Humble packages declare: Nav2 1.1.0 to 1.1.20 and the
  humble branch, robot_localization 3.4.0 to humble-devel, ros_gz_bridge's and
  ros_gz_sim create's (read from their sources into tests/data/ros_humble, with the commits).
  The one name newer than Humble's first release is `forward_prune_distance` (above).
- **The bridge**: each pair of message types is one ros_gz_bridge converts, each Gazebo topic
  is one a sensor or plugin of the robot publishes (or, for the command, subscribes) with
  that message, and the ROS topics meet their consumers (the covariance relay, the voxel
  layer, controller_server's `cmd_vel`).
- **The behaviour tree**: its nodes are registered by every Humble release of Nav2 or by
  BehaviorTree.CPP 3.8, with only the ports they declare; planner, controller and goal
  checker IDs exist in the parameters.
- **The launch file** parses, and run against stand-in `launch`/`launch_ros` modules starts
  the nodes above with files that exist, parameter sections named after the nodes, the
  lifecycle manager's node list, remappings that join the EKFs and navsat_transform, and the
  spawn 2 cm above the ground; `controller:=`, `headless:=`, `follow:=` and `sim:=classic` too.
- **The follower's goals** are the env's route observation points (to 5 mm) and its tracker
  gives the env's arc length and cross-track error; the GPS waypoints agree with their ENU
  positions through the datum.
- The values are the benchmark's: DWB and the costmap equal AgriNav's configuration with the
  robot's values; the EKFs' rates, frames and process noise and the covariances equal the
  env's sensor and EKF models.

Not verified: anything at run time — that Gazebo's skid-steer turns as the simulator's does,
that the nodes start in a good order and find each other's transforms in time, QoS, message
rates under load, the two Python programs against real rclpy, and how Nav2 drives here. The
first run should watch `ros2 topic hz /depth_camera/points /odometry/global`, `tf2_monitor`
and the follower's log.

## Waypoints

- `config/gps_waypoints.yaml` — {info["waypoints"]} sparse GPS waypoints in the format of Nav2's
  GPS waypoint follower demo (`waypoints: [{{latitude, longitude, yaw}}]`, yaw in radians,
  ENU: 0 = east, counter-clockwise): every lane entry and exit, the apex of every headland
  turn, and the end of the lead-out. Iron and later can follow them with
  `BasicNavigator.followGpsWaypoints`; here the follower checks them and drives the route
  through them.
- `config/waypoints_enu.yaml` — the same poses as x, y, yaw in the ENU frame (the map frame).
- `reference_path.csv` — the dense reference path ({len(scn.route)} points, ≤ 0.1 m apart; x, y, z
  ENU, lat, lon, alt, yaw, segment furrow/headland, lane, arc length s, turn type, direction
  +1 forward / -1 reverse): the route the follower drives and what a recorded run is scored
  against.

"""
        + gazebo_section(g)
    )


def gis_readme(scn: Scenario, info: dict[str, Any]) -> str:
    utm = (
        f"- `{info['utm_tif']}` — the same terrain resampled (bilinear) into the datum's UTM "
        f"zone, {info['utm_crs']}, for tools that need an EPSG code; at the plants it departs "
        f"from the terrain by up to {info['utm_error_mm']:.1f} mm (resampling: terrain.tif is "
        "the exact one).\n"
        if info.get("utm_tif")
        else "- No UTM copy: the datum lies outside UTM's latitudes (-80° to 84°).\n"
    )
    dem = (
        f"- `{info['dem_tif']}` — the same terrain resampled (bilinear) into the source DEM's "
        f"CRS {info['dem_crs']}, to overlay on the DEM.\n"
        if info.get("dem_tif")
        else ""
    )
    obstacles, obstacle_json = "", ""
    if info["layers"].get("obstacles"):
        counts = ", ".join(f"{n} {k}" for k, n in scn.obstacles.counts().items())
        obstacles = (
            f"- `layers.gpkg` layer `obstacles` ({counts}): each obstacle's footprint "
            "(length × width about its centre, turned by its yaw) as a polygon on the ground, "
            "with `obstacle_id` (its row in the scenario's `obstacles.csv`), `kind`, "
            "`length_m`, `width_m`, `height_m` and its pose: roll/pitch/yaw and ENU x/y/z.\n"
        )
        obstacle_json = ", `obstacles.geojson`"
    geojson = "- `field.geojson`, `rows.geojson`, `plants.geojson`, `route.geojson`" + obstacle_json
    return (
        _head(scn, "GIS layers")
        + f"""## Files

- `terrain.tif` — elevation (float32, metres, the heights above), one pixel per
  terrain node, in a local CRS whose x/y are the scenario's ENU x/y: {info["crs_name"]}
  (`crs_local.wkt`). Over this field it matches ENU to {info["crs_error_mm"]:.2f} mm. NoData
  is -9999 in every GeoTIFF here, so a reprojection (`gdalwarp -t_srs EPSG:...`) leaves NoData,
  not 0 m, outside the terrain.
{utm}{dem}- `layers.gpkg` — layers `field` (polygon), `rows` (planted rows), `plants` (points with
  species, stage, height, roll/pitch/yaw and ENU x/y/z) and `route` (furrow/headland
  segments), WGS84 lon/lat (EPSG:4326) with the heights above.
{obstacles}{geojson} — the same layers as
  RFC 7946 GeoJSON, one geometry type per file, so `ogr2ogr` converts each to GeoPackage or
  Shapefile.

Open in QGIS: drag `terrain.tif` and `layers.gpkg` into the map (QGIS reprojects on the fly);
Raster ▸ Analysis ▸ Hillshade on `terrain.tif` gives the relief of `preview.png`.
"""
    )


def mesh_readme(scn: Scenario, files: list[str]) -> str:
    listing = "\n".join(f"- `{f}`" for f in files)
    obstacles = ""
    if any(f.startswith("obstacles.") for f in files):
        counts = ", ".join(f"{n} {k}" for k, n in scn.obstacles.counts().items())
        obstacles = f"""
Obstacles ({counts}): `obstacles.*`, each named `<kind>_<id>` (the id is the row of the
scenario's `obstacles.csv`) and coloured by kind. GLB and COLLADA: one node per obstacle
holding its mesh in its own frame, the node's transform its pose; OBJ: one object per
obstacle, vertices in ENU; PLY (no names in the format): one mesh in ENU whose faces carry
`obstacle` (the id) and `kind` (the index the header's `comment kind` lines name).
"""
    return (
        _head(scn, "meshes")
        + f"""Terrain (and, if asked, the plants merged) in the scenario's ENU frame, metres.
glTF/GLB files are Y-up as the format requires (x east, y up, z south); the others are Z-up
(x east, y north, z up; COLLADA files say so: `<up_axis>Z_UP</up_axis>`).

{listing}
{obstacles}"""
    )
