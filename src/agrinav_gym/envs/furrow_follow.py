"""Follow one lane between two crop rows."""

from __future__ import annotations

from typing import ClassVar

from ..env import AgriNavEnv, env_creator
from ..interface import OBS_DEPTH, OBS_IMU, OBS_ODOM


class FurrowFollowEnv(AgriNavEnv):
    """
    ## Description
    A Summit-XL skid-steer robot (pybullet, 240 Hz physics, 20 Hz control) must drive the full
    length of one lane — the furrow between two crop rows of a generated scenario — keeping
    to its centreline. The lane is drawn at random from the scenario's inner lanes each reset.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: normalized body twist (v, ω), scaled by
    ``config.robot.v_max`` (1.0 m/s) and ``w_max`` (1.5 rad/s) and rate-limited by the
    acceleration limits (0.6 m/s², 1.5 rad/s²). Values outside [-1, 1] are clipped; NaN or inf
    raises ``ValueError``.

    ## Observation Space
    ``Dict`` of the selected sensors (default ``gps, imu, odom, route``):
    ``gps`` (5,): ENU antenna fix (m), fix mode (2 RTK fixed, 1 float, 0 standalone or none:
    the last fix held, its age growing), fix age (s); modes follow the canopy over the antenna;
    ``imu`` (10,): specific force (m/s²), angular rate (rad/s), roll, pitch, sin/cos heading —
    all body frame with MTi-300 noise; ``odom`` (2,): wheel-odometry v (m/s), ω (rad/s);
    ``route`` (3·K,): the next K = 10 route points, 0.4 m apart, in the robot frame of the
    *estimated* pose (``config.localisation``: an EKF over GNSS + IMU + odometry by default,
    never ground truth unless ``ideal`` is asked for), each with a furrow flag;
    ``depth`` (1, 48, 64): D455-like z-depth in metres, 0 = invalid.

    ## Rewards
    A sum of named parts, each in ``info["rewards"]``, weights in ``config.reward``:
    ``progress`` (+ route progress per step, 1 at full speed; with
    ``config.reward.progress.cte_scale`` = k it is weighted in furrows by
    exp(−|cte| / (k · corridor)), so that only distance driven on the line pays),
    ``cte`` (−(cte / corridor)², cross-track error from the **true** pose),
    ``heading`` (−|heading error| / π), ``crop_contact`` (−per crop newly touched),
    ``action_rate`` (−‖aₜ − aₜ₋₁‖²) and ``terminal`` (+10 on success, −10 on failure).

    ## Starting State
    At rest 0.3 m into the lane, laterally offset by N(0, 0.03 m) and turned by N(0, 3°)
    (clipped), tilted with the terrain: ``reset`` lets the robot settle on its tyres, wheels
    held, before the first observation, so the IMU reads gravity from the first step.

    ## Episode End
    Terminated on success (lane end reached within 0.3 m), leaving the corridor (|cte| > half
    the row spacing), tipping over (roll or pitch > 60°), hitting more than 10 crops or, with
    ``config["task"]["progress_time"]`` set, moving less than ``progress_radius`` in that time
    (Nav2's progress checker); truncated by ``max_episode_steps`` (1500). Obstacles (stones,
    litter, fallen stalks: the spec's ``obstacles`` section) never end an episode: the robot
    drives over what it can and stalls at what it cannot. Every ``info`` carries
    ``crops_hit``, ``obstacles_hit`` (distinct obstacles the footprint touched) and the
    episode's running ``metrics`` (path-weighted and per-pose RMSE, MAE, max, in-furrow /
    headland RMSE, completion, crops hit, obstacles hit in all and
    ``obstacles_hit_by_kind``), so the last one holds the final values however the episode
    ended; a terminating step also names its ``termination`` (success,
    corridor, off_terrain, tip_over, crops_hit, progress). Stepping after a termination, or
    after the env's own truncation (``config.task.seconds_per_metre``), raises
    ``gymnasium.error.ResetNeeded``.

    ## Arguments
    ``scenario`` (Scenario, scenario directory or preset name; default ``"default"``),
    ``scenario_overrides`` (spec overrides for a preset), ``scenario_seed``, ``randomize``
    (ranges re-drawn each reset, e.g. ``{"crop.stage": [1, 5], "gnss.mode": {"choices":
    ["rtk_fixed", "rtk_float"]}}``), ``scenario_seeds`` (the ``[low, high)`` range randomized
    scenarios draw their seed from: disjoint ranges make disjoint train/test splits),
    ``bank`` (a directory of saved scenarios sampled each reset), ``observations``,
    ``config`` (nested overrides of ``EnvConfig``; unknown keys are errors), ``render_mode``
    (``rgb_array`` chase view, ``human`` GUI).
    ``reset(options={"scenario": ..., "lane": i})`` switches scenario or lane. The scenario
    option is a Scenario, a folder or a preset name; a name is generated as the preset itself
    (seed 0, without this env's ``scenario_overrides``, ``scenario_seed`` or ``randomize``:
    pass a Scenario, e.g. ``scenario_gen.generate(spec, seed)``, for anything else). A fixed
    field env keeps the new scenario for later resets; a bank or a randomized scenario key
    draws again at the next reset without the option.

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

    task_name: ClassVar[str] = "FurrowFollow"


class FurrowFollowDepthEnv(FurrowFollowEnv):
    """
    ## Description
    ``FurrowFollow`` from the depth camera alone: the lane must be found in the D455-like depth
    image; no GNSS and no route observation. The default camera draws plants as proxies fitted
    to the crop meshes (``config.camera.proxy_fit`` names the table); for crops at or above the
    camera's 0.66 m they do not give the meshes' outcome (docs/camera.md, "Two tables"), so
    use ``camera.model="mesh"`` there.

    ## Action Space
    As ``AgriNav/FurrowFollow-v3``.

    ## Observation Space
    Default ``depth`` (1, 48, 64) metres, ``imu`` (10,), ``odom`` (2,).

    ## Rewards
    As ``AgriNav/FurrowFollow-v3`` (computed from the true pose).

    ## Starting State
    As ``AgriNav/FurrowFollow-v3``.

    ## Episode End
    As ``AgriNav/FurrowFollow-v3``.

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

    default_observations: ClassVar[tuple[str, ...]] = (OBS_DEPTH, OBS_IMU, OBS_ODOM)


make_furrow_follow = env_creator(FurrowFollowEnv)
make_furrow_follow_depth = env_creator(FurrowFollowDepthEnv)
