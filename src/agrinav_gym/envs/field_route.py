"""The source paper's experiment: a zigzag over lanes with headland U-turns."""

from __future__ import annotations

from typing import ClassVar

from ..env import AgriNavEnv, env_creator
from ..interface import OBSERVATION_KEYS


class FieldRouteEnv(AgriNavEnv):
    """
    ## Description
    Drive the scenario's zigzag route — ``route.lanes`` lanes (2 by default) joined by headland
    U-turns, with lead-in and lead-out — as in the source paper's Summit-XL / Nav2 experiment.

    ## Action Space
    As ``AgriNav/FurrowFollow-v3``: normalized (v, ω) in [-1, 1]², clipped; NaN raises.

    ## Observation Space
    Default ``gps`` (5,), ``imu`` (10,), ``odom`` (2,), ``route`` (30,), ``depth`` (1, 48, 64);
    see ``AgriNav/FurrowFollow-v3``. Route points carry a furrow (1) / headland (0) flag.

    ## Rewards
    As ``AgriNav/FurrowFollow-v3``; the corridor is half the row spacing in furrows and
    ``config.task.headland_corridor`` (1 m) on the headland.

    ## Starting State
    At rest 0.3 m along the lead-in, perturbed as in ``AgriNav/FurrowFollow-v3``.

    ## Episode End
    Success at the route's end; failure on leaving the corridor, tipping over or hitting more
    than 10 crops; truncation by ``max_episode_steps`` (4000) or, when set, after
    ``config.task.seconds_per_metre`` × the route's length, whichever comes first. Every
    ``info`` carries the paper's running metrics (in-furrow and headland RMSE separately).

    ## Arguments
    As ``AgriNav/FurrowFollow-v3``.

    ## Version History
    * v3: at reset the robot settles on its tyres, wheels held, before the first observation
      (the IMU reads gravity from the first step); the tyre model, the EKF and the route
      tracking in compiled kernels where the extension is built (tyres and route to the bit,
      the EKF to rounding).
    * v2: fields planted flat by default (roughness, no ridges; ``ridged`` preset for
      ridge-tilled fields): in v1 the 0.12 m ridges under every field steered the robot.
    * v1: default fields drivable (1 m rows, stalk-vs-footprint contact), tyre–soil drive
      physics (yaw rate follows the command, slope traction limit), the route observation from a
      robot_localization-style EKF with GNSS latency and canopy-driven fix modes (was an ideal
      1 cm fix), depth from proxies fitted to the crop meshes (``camera.model="mesh"`` for the
      meshes themselves). Same seed, same rollout within v1; v0 rollouts are not reproduced.
    * v0: initial version.
    """

    task_name: ClassVar[str] = "FieldRoute"
    default_observations: ClassVar[tuple[str, ...]] = OBSERVATION_KEYS


make_field_route = env_creator(FieldRouteEnv)
