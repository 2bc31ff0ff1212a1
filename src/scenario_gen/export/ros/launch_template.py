"""The AgriNav field with the Summit-XL under Nav2 (ROS 2 Humble), written by agrinav export.

    . setup.bash
    ros2 launch launch/agrinav_field.launch.py                   # Gazebo Sim, the whole stack
    ros2 launch launch/agrinav_field.launch.py headless:=true    # ... without Gazebo's GUI
    ros2 launch launch/agrinav_field.launch.py controller:=nav2_defaults   # DWB as Nav2 ships
    ros2 launch launch/agrinav_field.launch.py follow:=false     # all but the route follower
    ros2 launch launch/agrinav_field.launch.py record:=track.csv  # the robot's poses, to score
    ros2 launch launch/agrinav_field.launch.py sim:=classic      # Gazebo Classic 11: world and
                                                                 # robot only (README)

Gazebo Sim (ros_gz_sim) with worlds/field.sdf; the Summit-XL spawned at the route start from
robot/summit_xl_gazebo.urdf (sensors, drive); ros_gz_bridge (config/bridge.yaml);
robot_state_publisher; the sensor covariances; robot_localization's two EKFs and
navsat_transform (config/ekf.yaml, config/navsat_transform.yaml); Nav2's controller, planner
and behaviour-tree navigator with their lifecycle manager (config/nav2_params*.yaml,
behavior_trees/); and the route follower (scripts/follow_route.py).
"""

import os
from typing import Any

from ament_index_python.packages import get_package_share_directory as share
from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    ExecuteProcess,
    IncludeLaunchDescription,
    OpaqueFunction,
    SetEnvironmentVariable,
)
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
MODELS = os.path.join(ROOT, "models")
CONFIG = os.path.join(ROOT, "config")
SCRIPTS = os.path.join(ROOT, "scripts")
URDF = os.path.join(ROOT, "robot", "summit_xl.urdf")  # the simulator's model, no Gazebo parts
GZ_URDF = os.path.join(ROOT, "robot", "summit_xl_gazebo.urdf")
TREES = {  # bt_navigator's two trees: no recoveries that need Nav2's behavior server
    "default_nav_through_poses_bt_xml": os.path.join(ROOT, "behavior_trees", "follow_route.xml"),
    "default_nav_to_pose_bt_xml": os.path.join(ROOT, "behavior_trees", "navigate_to_pose.xml"),
}
SPAWN_X, SPAWN_Y, SPAWN_Z, SPAWN_YAW = 0.0, 0.0, 0.13, 0.0  # route start: base_link, ENU m, rad
BASE_HEIGHT = 0.11  # base_link above base_footprint (the ground under the wheels), m
ROUTE_POINTS, ROUTE_SPACING = 10, 0.4  # the follower's goals: poses, m apart
NAV2_PARAMS = {
    "benchmarked": os.path.join(CONFIG, "nav2_params.yaml"),
    "nav2_defaults": os.path.join(CONFIG, "nav2_params_nav2_defaults.yaml"),
}
SIM_TIME = {"use_sim_time": True}


def _path(var: str) -> str:
    old = os.environ.get(var, "")
    return MODELS + (os.pathsep + old if old else "")


def _script(name: str, *args: str) -> Any:
    cmd = ["python3", os.path.join(SCRIPTS, name), *args, "--ros-args", "-p", "use_sim_time:=true"]
    return ExecuteProcess(cmd=cmd, output="screen")


def _classic(context: Any) -> list[Any]:
    """Gazebo Classic 11: the world and the simulator's URDF, no sensors or drive (README)."""
    world = os.path.join(ROOT, "worlds", "field_classic.world")
    pose = ["-x", str(SPAWN_X), "-y", str(SPAWN_Y), "-z", str(SPAWN_Z), "-Y", str(SPAWN_YAW)]
    with open(URDF) as f:
        description = f.read()
    return [
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                os.path.join(share("gazebo_ros"), "launch", "gazebo.launch.py")
            ),
            launch_arguments={"world": world}.items(),
        ),
        Node(
            package="robot_state_publisher",
            executable="robot_state_publisher",
            parameters=[{"robot_description": description, **SIM_TIME}],
            output="screen",
        ),
        Node(
            package="gazebo_ros",
            executable="spawn_entity.py",
            arguments=["-entity", "summit_xl", "-file", URDF, *pose],
            output="screen",
        ),
    ]


def _gazebo_sim(context: Any) -> list[Any]:
    headless = LaunchConfiguration("headless").perform(context).lower() in ("true", "1")
    controller = LaunchConfiguration("controller").perform(context)
    if controller not in NAV2_PARAMS:
        raise ValueError(f"controller:={controller}: one of {', '.join(NAV2_PARAMS)}")
    nav2 = NAV2_PARAMS[controller]
    world = os.path.join(ROOT, "worlds", "field.sdf")
    # base_footprint is the model's root: spawn it on the ground under base_link's start pose
    pose = ["-x", str(SPAWN_X), "-y", str(SPAWN_Y), "-z", str(SPAWN_Z - BASE_HEIGHT)]
    pose += ["-Y", str(SPAWN_YAW)]
    with open(GZ_URDF) as f:
        description = f.read()
    ekf = os.path.join(CONFIG, "ekf.yaml")
    actions = [
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                os.path.join(share("ros_gz_sim"), "launch", "gz_sim.launch.py")
            ),
            launch_arguments={"gz_args": ("-r -s " if headless else "-r ") + world}.items(),
        ),
        Node(
            package="ros_gz_sim",
            executable="create",
            arguments=["-name", "summit_xl", "-file", GZ_URDF, *pose],
            output="screen",
        ),
        Node(
            package="ros_gz_bridge",
            executable="parameter_bridge",
            parameters=[{"config_file": os.path.join(CONFIG, "bridge.yaml"), **SIM_TIME}],
            output="screen",
        ),
        Node(
            package="robot_state_publisher",
            executable="robot_state_publisher",
            parameters=[{"robot_description": description, **SIM_TIME}],
            output="screen",
        ),
        _script("sensor_covariances.py"),
        Node(
            package="robot_localization",
            executable="ekf_node",
            name="ekf_local",
            parameters=[ekf, SIM_TIME],
            remappings=[("odometry/filtered", "/odometry/local")],
            output="screen",
        ),
        Node(
            package="robot_localization",
            executable="ekf_node",
            name="ekf_global",
            parameters=[ekf, SIM_TIME],
            remappings=[("odometry/filtered", "/odometry/global")],
            output="screen",
        ),
        Node(
            package="robot_localization",
            executable="navsat_transform_node",
            name="navsat_transform",
            parameters=[os.path.join(CONFIG, "navsat_transform.yaml"), SIM_TIME],
            remappings=[
                ("imu", "/imu/data"),
                ("gps/fix", "/gps/fix"),
                ("odometry/filtered", "/odometry/global"),
                ("odometry/gps", "/odometry/gps"),
                ("gps/filtered", "/gps/filtered"),
            ],
            output="screen",
        ),
        Node(
            package="nav2_controller",
            executable="controller_server",
            name="controller_server",
            parameters=[nav2],
            output="screen",
        ),
        Node(
            package="nav2_planner",
            executable="planner_server",
            name="planner_server",
            parameters=[nav2],
            output="screen",
        ),
        Node(
            package="nav2_bt_navigator",
            executable="bt_navigator",
            name="bt_navigator",
            parameters=[nav2, TREES],
            output="screen",
        ),
        Node(
            package="nav2_lifecycle_manager",
            executable="lifecycle_manager",
            name="lifecycle_manager_navigation",
            parameters=[nav2],
            output="screen",
        ),
    ]
    if LaunchConfiguration("follow").perform(context).lower() in ("true", "1"):
        record = LaunchConfiguration("record").perform(context)
        args = ["--points", str(ROUTE_POINTS), "--spacing", str(ROUTE_SPACING)]
        args += ["--record", record] if record else []
        actions.append(_script("follow_route.py", *args))
    return actions


def _simulator(context: Any, *args: Any, **kwargs: Any) -> list[Any]:
    sim = LaunchConfiguration("sim").perform(context)
    if sim == "classic":
        return _classic(context)
    if sim != "gz":
        raise ValueError(f"sim:={sim}: gz or classic")
    return _gazebo_sim(context)


def generate_launch_description() -> Any:
    return LaunchDescription(
        [
            DeclareLaunchArgument("sim", default_value="gz", description="gz or classic"),
            DeclareLaunchArgument(
                "controller",
                default_value="benchmarked",
                description="benchmarked (config/nav2_params.yaml) or nav2_defaults",
            ),
            DeclareLaunchArgument(
                "headless", default_value="false", description="Gazebo Sim without its GUI"
            ),
            DeclareLaunchArgument(
                "follow", default_value="true", description="start the route follower"
            ),
            DeclareLaunchArgument(
                "record", default_value="", description="CSV the follower writes poses to"
            ),
            SetEnvironmentVariable("GAZEBO_MODEL_PATH", _path("GAZEBO_MODEL_PATH")),
            SetEnvironmentVariable("IGN_GAZEBO_RESOURCE_PATH", _path("IGN_GAZEBO_RESOURCE_PATH")),
            SetEnvironmentVariable("GZ_SIM_RESOURCE_PATH", _path("GZ_SIM_RESOURCE_PATH")),
            OpaqueFunction(function=_simulator),
        ]
    )
