"""The environment: a thin orchestrator over named parts.

``AgriNavEnv`` wires a ``ScenarioSource`` (where fields come from), a ``Task`` (route, start,
termination checks), the pybullet ``World``, the ``SensorSuite``, a ``StateEstimator``, one
``ObservationModel`` per observation key, the reward-term table and ``EpisodeMetrics``.
``reset`` and ``step`` only call them in order; each part is replaceable on its own (see
docs/design.md, "Where do I add ...?").
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import math
import os
import sys
import warnings
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from numpy.typing import NDArray

from scenario_gen import Scenario
from scenario_gen.errors import InputError

from . import rewards
from .chase_view import ChaseView
from .config import EnvConfig, GnssFixConfig
from .estimation import Readings, make_estimator
from .interface import OBS_DEPTH, OBS_GPS, OBS_IMU, OBS_ODOM, OBS_ROUTE
from .metrics import EpisodeMetrics
from .observations import OBSERVATION_MODELS, RouteObservation, Snapshot
from .recoveries import ABORT, SKIP, Recoveries
from .render.mesh_scene import SceneCache
from .render.proxy_params import planting_of
from .render.proxy_plants import PlantField
from .robot import robot_interface
from .routes import RoutePath, Tracker
from .scenarios import FixedFieldWarning, ScenarioSource
from .sensors.camera import FieldView
from .sensors.fixmode import Canopy
from .sensors.suite import SensorSuite
from .sim.contact import CropContact, ObstacleContact
from .sim.world import World
from .tasks import TASKS

Obs = dict[str, NDArray[np.float32]]


def _caller_level() -> int:
    """``warnings.warn``'s stacklevel, from the function calling this one, of the first frame
    outside agrinav_gym and gymnasium: the line that made the env (``gym.make`` or the class)."""
    frame = sys._getframe(1)
    level = 1
    while frame.f_back is not None and _package(frame) in ("agrinav_gym", "gymnasium"):
        frame = frame.f_back
        level += 1
    return level


def _package(frame: Any) -> str:
    return str(frame.f_globals.get("__name__", "")).split(".")[0]


def _display() -> bool:
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY"))


def _wrap(a: float) -> float:
    return float((a + math.pi) % (2 * math.pi) - math.pi)


class AgriNavEnv(gym.Env[Obs, NDArray[np.float32]], EzPickle):
    # "human" needs a display (pybullet's GUI blocks forever without one): headless, it is not
    # offered, so checkers and wrappers see only what works here.
    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": ["rgb_array", "human"] if _display() else ["rgb_array"],
        "render_fps": 20,
    }
    task_name: ClassVar[str]
    default_observations: ClassVar[tuple[str, ...]] = (OBS_GPS, OBS_IMU, OBS_ODOM, OBS_ROUTE)

    def __init__(
        self,
        scenario: Scenario | str | Path | None = None,
        scenario_overrides: dict[str, Any] | None = None,
        scenario_seed: int = 0,
        randomize: dict[str, Any] | None = None,
        scenario_seeds: tuple[int, int] | list[int] | None = None,
        bank: str | Path | None = None,
        observations: tuple[str, ...] | list[str] | None = None,
        config: dict[str, Any] | None = None,
        render_mode: str | None = None,
    ) -> None:
        EzPickle.__init__(
            self,
            scenario,
            scenario_overrides,
            scenario_seed,
            randomize,
            scenario_seeds,
            bank,
            observations,
            config,
            render_mode,
        )
        self._closed = True
        if render_mode is not None and render_mode not in ("rgb_array", "human"):
            raise InputError("render_mode", render_mode, "allowed: None, rgb_array, human")
        self.render_mode = render_mode
        self.observation_names = _check_observations(observations, self.default_observations)
        self.cfg = EnvConfig.from_dict(config)
        if self.cfg.task.waypoint_goals and OBS_ROUTE not in self.observation_names:
            raise InputError(
                "config.task.waypoint_goals",
                True,
                "hands the route over in the route observation, which this env does not "
                f"observe ({', '.join(self.observation_names)}); allowed: false here",
            )
        cam = self.cfg.camera
        for name, on in (("rgb", cam.rgb), ("segmentation", cam.segmentation)):
            if on and OBS_DEPTH not in self.observation_names:  # the depth camera draws them
                raise InputError(
                    f"config.camera.{name}",
                    True,
                    f"comes with the depth camera's frames (info['{name}']), which this env "
                    f"does not observe ({', '.join(self.observation_names)}); allowed: false "
                    f"here, or add '{OBS_DEPTH}' to observations",
                )
        control_hz = self.cfg.robot.control_hz
        if OBS_DEPTH in self.observation_names and control_hz % cam.rate_hz:
            raise InputError(
                "config.camera.rate_hz",
                cam.rate_hz,
                f"allowed: a divisor of robot.control_hz ({control_hz}): the camera's frame "
                "comes every few control steps",
            )
        t = self.cfg.task
        if not t.stop_on_failure and not (t.waypoint_goals and t.recoveries):
            raise InputError(
                "config.task.stop_on_failure",
                False,
                "the waypoint follower skips a waypoint only when the goals are handed over "
                "one at a time with recoveries (task.waypoint_goals and task.recoveries true); "
                "allowed: true here",
            )
        self.source = ScenarioSource(
            scenario, scenario_overrides, scenario_seed, scenario_seeds, bank, randomize
        )
        self.scenario = self.source.first
        self._check_ground(self.scenario)
        fixed = self.source.fixed_field()
        if fixed is not None:  # a notice once per env, not per reset, at the caller's line
            msg = f"{type(self).__name__}: {fixed}"
            warnings.warn(msg, FixedFieldWarning, stacklevel=_caller_level())
        self.world = World(self.cfg.robot, self.cfg.soil, gui=render_mode == "human")
        self._closed = False
        self.interface = robot_interface(self.cfg, self.world.geometry)
        self.task = TASKS[self.task_name](self.cfg.task, self.interface)
        self.dt = self.interface.control_dt
        self.substeps = self.cfg.robot.physics_hz // self.cfg.robot.control_hz
        self.sensors = SensorSuite(self.cfg, self.world.geometry, self.dt)
        loc = self.cfg.localisation
        self.estimator = make_estimator(loc.kind, loc, self.world.skid_factor, self.dt)
        self.recoveries = Recoveries(self.cfg.task.recovery_retries, self.dt)
        self.obs_models = {
            k: OBSERVATION_MODELS[k](self.cfg, self.interface) for k in self.observation_names
        }
        space = spaces.Dict({k: m.space() for k, m in self.obs_models.items()})
        self.observation_space = space  # type: ignore[assignment]
        self._obs_keys = tuple(space.spaces)
        route_model = self.obs_models.get(OBS_ROUTE)
        #: the route observation that hands the route over a goal at a time (waypoint_goals)
        self._goal_model = (
            route_model
            if self.cfg.task.waypoint_goals and isinstance(route_model, RouteObservation)
            else None
        )
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.route: RoutePath | None = None
        self._fields_of: Scenario | None = None
        self._chase: ChaseView | None = None
        self._chase_scenes = SceneCache()
        self._camera_scenes = SceneCache()  # the mesh camera's, built on first use
        light = self.cfg.lighting
        self._lighting: tuple[Any, float, float] = (
            light.soil_rgb,
            light.sun_azimuth_deg,
            light.sun_elevation_deg,
        )

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        self._check_open("reset")
        if seed is not None and (
            isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0
        ):
            raise InputError("seed", seed, "allowed: None or an integer >= 0")
        opts = self._check_options(options)
        # a reset that fails part way (a lane the drawn field lacks, a start off the terrain)
        # leaves the env as before it, with the episode ended: nothing of it carries on
        before = (self.scenario, copy.deepcopy(self._np_random), self._np_random_seed)
        try:
            return self._reset(seed, opts)
        except BaseException:
            self.scenario, self._np_random, self._np_random_seed = before
            self._ended = True
            raise

    def _reset(self, seed: int | None, opts: dict[str, Any]) -> tuple[Obs, dict[str, Any]]:
        super().reset(seed=None if seed is None else int(seed))
        rng = self.np_random
        self.scenario, env_values = self.source.sample(rng, self.scenario, opts.get("scenario"))
        self._check_ground(self.scenario)
        self._apply_env_values(env_values)
        self._build_world()
        self.route = self.task.make_route(self.scenario, rng, opts)
        shortest = self.cfg.task.success_tolerance + 1.0
        if self.route.length < shortest:  # "success" would be reported without driving
            raise InputError(
                "route",
                f"{self.route.length:.2f} m",
                f"allowed: a route of at least {shortest:g} m (success tolerance + 1 m)",
            )
        self.start = self.task.start_pose(self.route, rng, self._clearance(), self.scenario)
        self._check_start_ground(self.scenario, self.start)
        self.world.place_robot(*self.start, self.scenario.terrain)
        self.world.settle()  # at rest on the ground before the first reading
        self.tracker = Tracker(self.route)
        self.tracker.reset(self.start[0], self.start[1])
        self.metrics = EpisodeMetrics(self.route.xy, self.route.furrow)
        self._cmd, self._prev_action, self._steps = (0.0, 0.0), (0.0, 0.0), 0
        self._ended = False
        self._hit_base = 0  # crops touched before the last intervention (resume_on_route)
        self._hit: set[int] = set()
        self._obstacles_hit: set[int] = set()  # each counted once an episode
        self.state = self.world.state()
        self._anchor = (*self._xy(), 0.0)  # progress checker: where and when it last moved
        self._missed = 0  # waypoints the follower gave up on (stop_on_failure false)
        spm = self.cfg.task.seconds_per_metre
        self._step_limit = None if spm is None else math.ceil(self.route.length * spm / self.dt)
        self.recoveries.reset()
        self.readings = self.sensors.reset(self.state, rng)
        self.estimator.reset(*self.start, rng)
        self.estimator.update(self.readings, self.dt)
        self._cte, self._s, self._k = self.tracker.update(*self._xy())
        self._s0 = self._start_arc = self._s
        self.metrics.update(*self._xy(), self._s)
        snap = self._snapshot()
        for m in self.obs_models.values():
            m.reset(snap)
        if self.render_mode == "human":
            self.world.load_visuals(self.scenario)
        return self._observe(snap), self._info(None, {})

    def step(self, action: NDArray[np.float32]) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        a = self._check_action(action)
        recovery = self._behaviour()
        if recovery is not None:
            a = recovery[1]
        self._command(a)
        self.world.follow(
            float(self.state.pos[0]), float(self.state.pos[1]), float(self.state.rpy[2])
        )
        self.world.step(self.substeps)
        self._steps += 1
        self.state = self.world.state()
        self.readings = self.sensors.step(self.state, self.np_random)
        self.estimator.update(self.readings, self.dt)
        ctx = self._context(a)
        end = self.task.check(ctx)
        event = recovery[0] if recovery is not None else None
        if end == "progress" and self.cfg.task.recoveries:
            event = self.recoveries.on_failure(self.estimator.pose)
            skips = not self.cfg.task.stop_on_failure
            if event == ABORT and skips and self._goal_model is not None:
                if self._goal_model.skip_goal():
                    event = SKIP
                    self._missed += 1
                    self.recoveries.new_goal()
            if event != ABORT:
                end = None  # the tree recovers and sends FollowPath again
                self._anchor = (*self._xy(), self._steps * self.dt)
        if end is not None:
            ctx = dataclasses.replace(ctx, termination=end)
        self._ended = end is not None
        parts = rewards.evaluate(self.cfg.reward, ctx)
        self._prev_action = a
        obs = self._observe(self._snapshot())
        if self._goal_model is not None and self._goal_model.goal_passed:
            # a new goal: Nav2's controller server restarts its progress checker
            self._anchor = (*self._xy(), self._steps * self.dt)
            self.recoveries.new_goal()
        info = self._info(ctx, parts)
        if event is not None:
            info["recovery"] = event
        # Truncation is the TimeLimit wrapper's (max_episode_steps), which the env cannot see,
        # or the route's own limit (task.seconds_per_metre): the running metrics ride on every
        # step's info, so the last one is final.
        truncated = self._step_limit is not None and self._steps >= self._step_limit
        self._ended = self._ended or truncated  # ended either way: Gymnasium's contract
        return obs, float(sum(parts.values())), ctx.termination is not None, truncated, info

    def render(self) -> NDArray[np.uint8] | None:
        self._check_open("render")
        if self.render_mode != "rgb_array" or self.route is None:
            return None
        if self._chase is None:
            self._chase = ChaseView(self.cfg.render, self.interface.camera, self.cfg.camera)
        self._chase.set_lighting(*self._lighting)
        return self._chase.render(self._chase_scenes.get(self.scenario), self.state)

    def close(self) -> None:
        if not getattr(self, "_closed", True):
            self.world.close()
            self._closed = True

    # ------------------------------------------------------------------ evaluation access
    @property
    def trajectory(self) -> NDArray[np.float64]:
        """Ground-truth base positions (N, 2) of this episode: for evaluation, never policies."""
        self._check_reset("trajectory")
        return self.metrics.trajectory

    @property
    def crops_hit_ids(self) -> frozenset[int]:
        """Plant indices (rows of plants.csv) of the crops touched this episode."""
        self._check_reset("crops_hit_ids")
        return frozenset(self._hit)

    @property
    def obstacles_hit_ids(self) -> frozenset[int]:
        """Indices (rows of obstacles.csv) of the obstacles touched this episode."""
        self._check_reset("obstacles_hit_ids")
        return frozenset(self._obstacles_hit)

    def conditions(self) -> dict[str, str]:
        """What produced this episode's numbers: localisation, camera model, speed limit (and
        the tyres' tread contact and how the route is handed to the controller, when not the
        defaults)."""
        c = self.cfg.camera
        kind = "crop meshes (Embree)" if c.model == "mesh" else "analytic proxy"
        cam = f"{c.width}x{c.height} {kind}" if OBS_DEPTH in self.obs_models else "none"
        out = {
            "localisation": self._localisation_label(),
            "camera": cam,
            "speed_limit": f"{self.cfg.robot.v_max:g} m/s",
        }
        soil = self.cfg.soil
        if soil.contact_width > 0:  # absent: the point contact of the registered envs
            out["tyres"] = f"{soil.contact_width:g} m tread contact"
            if soil.cohesion_kpa is not None:  # absent: a rigid ground
                out["tyres"] += (
                    f" on a yielding ground (c {soil.cohesion_kpa:g} kPa, "
                    f"φ {soil.friction_angle_deg:g}°, {soil.bulk_density:g} t/m³)"
                )
        t = self.cfg.task
        nav = []
        if t.waypoint_goals:
            nav.append(f"waypoint follower (a goal per GPS waypoint, {t.goal_tolerance:g} m)")
        if t.recoveries:
            nav.append(f"Nav2 recoveries ({t.recovery_retries} per goal)")
        if not t.stop_on_failure:
            nav.append("a given-up waypoint skipped")
        if t.seconds_per_metre is not None:
            nav.append(f"time limit {t.seconds_per_metre:g} s per metre of route")
        if nav:
            out["navigator"] = ", ".join(nav)
        return out

    @property
    def arc(self) -> float:
        """How far along the route the robot is (m, ground truth: evaluation only)."""
        self._check_reset("arc")
        return float(self._s)

    def resume_on_route(self, ahead: float = 0.5) -> tuple[Obs, dict[str, Any]]:
        """An intervention: after a termination other than success, the operator puts the
        robot back on the route ``ahead`` metres past where it was, at rest and heading along
        it, and the episode goes on. The metrics keep counting (no path is weighed across the
        jump); the crop-contact and progress checks start afresh; the sensors and the estimator
        restart at the new pose as at a reset."""
        self._check_open("resume_on_route")
        if self.route is None:
            raise InputError("resume_on_route", "before reset()", "allowed: call reset() first")
        if not 0.0 <= ahead <= 10.0:
            raise InputError("ahead", ahead, "allowed: 0 to 10 m")
        end = self.route.length - self.cfg.task.success_tolerance - 0.05
        s = float(min(self._s + ahead, max(end, 0.0)))
        ((x, y),) = self.route.sample(np.array([s]))
        h = float(np.interp(s, self.route.arc, np.unwrap(self.route.heading)))
        self.world.follow(float(x), float(y), h)
        self.world.place_robot(float(x), float(y), h, self.scenario.terrain)
        self.world.settle()
        self.state = self.world.state()
        self._cmd, self._prev_action = (0.0, 0.0), (0.0, 0.0)
        # Sensors and estimator restart as at a reset: a fix still in the receiver's latency
        # queue is of the place the robot was carried from, and fused it would pull the
        # estimate back there (every intervention then led to the next).
        self.readings = self.sensors.reset(self.state, self.np_random)
        self.estimator.reset(float(x), float(y), h, self.np_random)
        self.recoveries.reset()
        self.estimator.update(self.readings, self.dt)
        self.tracker.reset_at(s, *self._xy())
        self._cte, self._s, self._k = self.tracker.update(*self._xy())
        self.start, self._start_arc = (float(x), float(y), h), self._s
        self.metrics.break_path()
        self.metrics.update(*self._xy(), self._s)
        self._hit_base = len(self._hit)
        self._anchor = (*self._xy(), self._steps * self.dt)
        self._ended = False
        snap = self._snapshot()
        for m in self.obs_models.values():
            m.reset(snap)
        return self._observe(snap), self._info(None, {})

    def episode_metrics(self) -> dict[str, Any]:
        self._check_reset("episode_metrics")
        kinds = self.scenario.obstacles.kind
        out = self.metrics.result(len(self._hit), [str(kinds[i]) for i in self._obstacles_hit])
        if self._goal_model is not None:
            out["missed_waypoints"] = self._missed
        return out

    # ------------------------------------------------------------------ parts of a step
    def _behaviour(self) -> tuple[str, tuple[float, float]] | None:
        """The recovery behaviour driving the robot this step, and its action; None when the
        policy drives. No progress check while one runs (nav2_behaviors, not the controller
        server, has the robot), and a fresh one once FollowPath takes over again."""
        running = self.recoveries.running
        if running is None:
            return None
        self._anchor = (*self._xy(), self._steps * self.dt)
        twist = self.recoveries.twist(self.estimator.pose)
        if twist is None:
            return None
        r = self.cfg.robot
        return running.kind, (twist[0] / r.v_max, twist[1] / r.w_max)

    def _command(self, a: tuple[float, float]) -> None:
        """Acceleration-limited body twist to the wheels."""
        r = self.cfg.robot
        lv, lw = r.a_max * self.dt, r.alpha_max * self.dt
        dv = a[0] * r.v_max - self._cmd[0]
        dw = a[1] * r.w_max - self._cmd[1]
        self._cmd = (self._cmd[0] + min(max(dv, -lv), lv), self._cmd[1] + min(max(dw, -lw), lw))
        self.world.drive(float(self._cmd[0]), float(self._cmd[1]))

    def _context(self, a: tuple[float, float]) -> rewards.StepContext:
        assert self.route is not None
        x, y = self._xy()
        cte, s, k = self.tracker.update(x, y)
        ds, self._s, self._cte, self._k = s - self._s, s, cte, k
        self.metrics.update(x, y, s, abs(cte))
        new = [
            i for i in self.contact.touching(x, y, float(self.state.rpy[2])) if i not in self._hit
        ]
        self._hit.update(new)
        # obstacles are counted, never an end: a robot they block stalls (the progress check)
        self._obstacles_hit.update(self.obstacle_contact.touching(x, y, float(self.state.rpy[2])))
        furrow = bool(self.route.furrow[k])
        return rewards.StepContext(
            dt=self.dt,
            v_max=self.cfg.robot.v_max,
            cte=cte,
            ds=ds,
            furrow=furrow,
            corridor=self.task.corridor(self.scenario, furrow),
            heading_error=_wrap(float(self.state.rpy[2]) - float(self.route.heading[k])),
            tilt=max(abs(float(self.state.rpy[0])), abs(float(self.state.rpy[1]))),
            new_crops=len(new),
            crops_hit=len(self._hit) - self._hit_base,
            action=a,
            prev_action=self._prev_action,
            off_terrain=not bool(self.scenario.terrain.contains(x, y)),
            route_left=self.route.length - s,
            stalled=self._stalled(x, y),
        )

    def _stalled(self, x: float, y: float) -> float:
        """Seconds since the robot last left the progress_radius disc around its anchor (Nav2's
        SimpleProgressChecker: the anchor moves to the robot each time it leaves the disc)."""
        ax, ay, t0 = self._anchor
        now = self._steps * self.dt
        if math.hypot(x - ax, y - ay) > self.cfg.task.progress_radius:
            self._anchor = (x, y, now)
            return 0.0
        return now - t0

    def _snapshot(self) -> Snapshot:
        assert self.route is not None
        return Snapshot(
            self.state,
            self.readings,
            self.estimator.pose,
            self.route,
            self.scenario,
            self.field,
            self.np_random,
            self._steps,
            self.start,
            self._start_arc,
        )

    def _observe(self, snap: Snapshot) -> Obs:
        # encoded in the models' order (their random draws keep their order), returned in the
        # space's (gymnasium's Dict sorts its keys: flatten(space, obs) lines up with obs)
        obs = {k: m.encode(snap) for k, m in self.obs_models.items()}
        return {k: obs[k] for k in self._obs_keys}

    def _info(self, ctx: rewards.StepContext | None, parts: dict[str, float]) -> dict[str, Any]:
        assert self.route is not None
        r: Readings = self.readings
        if r.gnss_new or not hasattr(self, "_latlon"):
            self._latlon = self.scenario.geo.point_to_geodetic(*r.gnss_enu)[:2]
        info: dict[str, Any] = {
            "cte": float(self._cte),
            "heading_error": ctx.heading_error
            if ctx
            else _wrap(float(self.state.rpy[2]) - float(self.route.heading[self._k])),
            "progress": float((self._s - self._s0) / max(self.route.length - self._s0, 1e-9)),
            "segment": "furrow" if self.route.furrow[self._k] else "headland",
            "crops_hit": len(self._hit),
            "obstacles_hit": len(self._obstacles_hit),
            "lat": self._latlon[0],
            "lon": self._latlon[1],
            "rewards": parts,
            "is_success": bool(ctx and ctx.success),
            "localisation": self._localisation_info(),
            "metrics": self.episode_metrics(),
        }
        if ctx is not None and ctx.termination is not None:
            info["termination"] = ctx.termination
        for model in self.obs_models.values():
            info.update(model.extras())
        return info

    def _localisation_label(self) -> str:
        g = self.sensors.gnss.cfg
        name = self.estimator.name
        if name == "ideal":
            return "ideal (ground truth pose)"
        fix = (
            "canopy/multipath fix modes"
            if g.fix.model == "canopy"
            else "open-sky fix mode (multipath slips)"
        )
        if g.fix.multipath_mtbf_s != GnssFixConfig.multipath_mtbf_s:
            fix += f", multipath MTBF {g.fix.multipath_mtbf_s:g} s"
        if g.fix.faults:  # opt-in: every row the faults touched says so
            f = g.fix
            fix += f" + faults (jumps {f.jump_rate_hz:g}/s, wrong fixes {f.false_fix_prob:g})"
        if name == "robot_localization":
            name += self._rl_settings()
        elif name in ("ekf", "ekf-oracle"):  # it knows the simulator's noise models
            name += " (oracle, an upper bound)"
        return f"{name}, GNSS {g.mode} best, {fix}, {g.latency_s:g} s latency"

    def _rl_settings(self) -> str:
        """What a robot_localization row sets beyond the node's defaults, in brackets."""
        rl = self.cfg.localisation.robot_localization
        out = [] if rl.two_d_mode else ["3D: imu roll and pitch"]
        if rl.gps_lever_arm:
            out.append("gps lever arm")
        if rl.smooth_lagged_data:
            out.append(f"smooth_lagged_data {rl.history_length_s:g} s")
        gates = (
            ("odom", rl.odom_rejection_threshold),
            ("imu", rl.imu_rejection_threshold),
            ("gps", rl.gps_rejection_threshold),
        )
        out += [f"{k} gate {v:g}σ" for k, v in gates if v is not None]
        if rl.fuse_imu_yaw_rate:
            out.append("imu yaw rate")
        if rl.fuse_imu_acceleration:
            out.append("imu acceleration")
        return f" ({', '.join(out)})" if out else " (defaults)"

    def _localisation_info(self) -> dict[str, Any]:
        """Which estimator, the receiver's fix mode and the estimate's true error (for
        evaluation: policies never see it)."""
        ex, ey, eyaw = self.estimator.pose
        return {
            "estimator": self.estimator.name,
            "gnss_mode": self.readings.gnss_mode,
            "position_error": math.hypot(ex - self.state.pos[0], ey - self.state.pos[1]),
            "yaw_error": _wrap(eyaw - float(self.state.rpy[2])),
        }

    # ------------------------------------------------------------------ helpers
    def _xy(self) -> tuple[float, float]:
        return float(self.state.pos[0]), float(self.state.pos[1])

    def _build_world(self) -> None:
        scn = self.scenario
        self.world.load(scn.terrain, scn.rows.angle if scn.rows.curve is None else None)
        self.world.set_obstacles(scn.obstacles)  # a no-op while they are the same
        if self._fields_of is not scn:
            fit = self.cfg.camera.proxy_fit
            planting = planting_of(scn.spec.furrows) if fit == "auto" else fit
            self.plants = PlantField.from_scenario(scn, planting=planting)
            self.field = FieldView(scn, self.plants, self._camera_scenes)
            self.contact = CropContact.from_scenario(scn, self.world.geometry)
            self.obstacle_contact = ObstacleContact.from_scenario(scn, self.world.geometry)
            self.sensors.set_canopy(Canopy(scn))
            self._fields_of = scn

    def _clearance(self) -> float:
        """Room each side of the lane centre before a wheel or the chassis meets a stalk."""
        return 0.5 * self.scenario.rows.spacing - self.contact.half_width - self.contact.max_radius

    def _apply_env_values(self, values: dict[str, Any]) -> None:
        """This reset's draws of the env-side ``randomize`` keys (``scenarios.ENV_KEYS``); the
        config's values where a key is not randomized."""
        fix = {k.rpartition(".")[2]: v for k, v in values.items() if k.startswith("gnss.fix.")}
        if "gnss.mode" in values or fix:
            mode = values.get("gnss.mode")
            self.sensors.set_gnss(None if mode is None else str(mode), fix)
        light = self.cfg.lighting
        self._lighting = (
            values.get("lighting.soil_rgb", light.soil_rgb),
            values.get("lighting.sun_azimuth_deg", light.sun_azimuth_deg),
            values.get("lighting.sun_elevation_deg", light.sun_elevation_deg),
        )
        for model in self.obs_models.values():
            model.set_lighting(*self._lighting)

    def _check_reset(self, what: str) -> None:
        """An episode's numbers exist once an episode has begun."""
        if self.route is None:
            raise InputError(what, "before reset()", "allowed: call reset() first")

    def _check_ground(self, scn: Scenario) -> None:
        """A plane steeper than the tyres hold the robot on (tan θ ≥ μ: from a standstill it
        slides down, tens of metres while it settles) gives no episode to drive: refused, as
        a DEM's steep spot is not (its slope under the start is not a setting)."""
        t = scn.spec.terrain
        mu = self.cfg.soil.friction
        limit = math.degrees(math.atan(mu))
        if t.source == "plane" and t.slope_deg >= limit:
            raise InputError(
                "terrain.slope_deg",
                t.slope_deg,
                f"allowed: below {limit:.1f}°, the steepest slope the tyres hold the robot on "
                f'at config.soil.friction {mu:g} (tan θ < μ, docs/physics.md "Traction on '
                'slopes"), or a higher soil.friction',
            )

    def _check_start_ground(self, scn: Scenario, start: tuple[float, float, float]) -> None:
        """The same limit where the ground is a DEM or a mesh, on the plane through the four
        wheels' ground points at the start (a 57° site picked by lat/lon slid the robot 73 m
        while it settled, and the first step's reward was -21,586)."""
        if scn.spec.terrain.source == "plane":  # refused whole, before the world was built
            return
        x, y, yaw = start
        g = self.world.geometry
        c, s_ = math.cos(yaw), math.sin(yaw)
        ax = np.array([1.0, 1.0, -1.0, -1.0]) * 0.5 * g.wheelbase
        ay = np.array([1.0, -1.0, 1.0, -1.0]) * 0.5 * g.track
        px, py = x + c * ax - s_ * ay, y + s_ * ax + c * ay
        z = scn.terrain.height_at(px, py)
        # least-squares plane z = a·x + b·y + d through the four points
        a, b, _ = np.linalg.lstsq(np.column_stack([px, py, np.ones(4)]), z, rcond=None)[0]
        slope = math.degrees(math.atan(math.hypot(a, b)))
        mu = self.cfg.soil.friction
        limit = math.degrees(math.atan(mu))
        if slope >= limit:
            raise InputError(
                "terrain",
                f"{slope:.1f}° under the start at ({x:.1f}, {y:.1f}) m of {scn.spec.name!r}",
                f"allowed: below {limit:.1f}°, the steepest ground the tyres hold the robot on "
                f'at config.soil.friction {mu:g} (docs/physics.md "Traction on slopes"); '
                "choose a flatter site (terrain.site) or a higher soil.friction",
            )

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise InputError(what, "called after close()", "allowed: make a new env")

    def _check_options(self, options: Any) -> dict[str, Any]:
        if options is None:
            return {}
        if not isinstance(options, dict):
            raise InputError("options", options, "allowed: a dict or None")
        allowed = ("scenario", *self.task.options)
        unknown = sorted(str(k) for k in set(options) - set(allowed))
        if unknown:
            raise InputError("options", unknown, f"allowed keys: {', '.join(allowed)}")
        return dict(options)

    def _check_action(self, action: Any) -> tuple[float, float]:
        self._check_open("step")
        if self.route is None:
            raise InputError(
                "step",
                "before reset()",
                "allowed: call reset() first (a copied or unpickled env is a new one, built from "
                "its constructor's arguments: it does not carry the episode)",
            )
        if self._ended:
            raise gym.error.ResetNeeded(
                "step() after the episode terminated or was truncated (or its reset failed): "
                "call reset() first (Gymnasium's contract)"
            )
        if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind == "f":
            a0, a1 = action.tolist()  # the usual action: checked without a copy
            if math.isfinite(a0) and math.isfinite(a1):
                return min(max(a0, -1.0), 1.0), min(max(a1, -1.0), 1.0)
        try:
            raw = np.asarray(action)
        except (TypeError, ValueError):
            raw = np.asarray(None)
        if raw.dtype.kind not in "fiu":  # strings, complex, objects: never coerced silently
            raise InputError("action", action, "allowed: 2 real numbers (v, w) in [-1, 1]")
        if raw.shape != (2,):  # a (1, 2) batch of one is refused, not flattened: one env
            raise InputError("action", f"shape {raw.shape}", "allowed: shape (2,)")
        a = raw.astype(np.float64)
        if not np.isfinite(a).all():
            raise InputError(
                "action",
                a.tolist(),
                "allowed: finite values in [-1, 1] (NaN or inf would corrupt the simulation)",
            )
        # documented: out-of-range actions are clipped
        return min(max(float(a[0]), -1.0), 1.0), min(max(float(a[1]), -1.0), 1.0)


def _check_observations(obs: Any, default: tuple[str, ...]) -> tuple[str, ...]:
    allowed = f"allowed: a name or a non-empty list of names from {', '.join(OBSERVATION_MODELS)}"
    if isinstance(obs, str):  # one name, not its letters
        obs = (obs,)
    if obs is not None and not isinstance(obs, (list, tuple, set, frozenset)):
        # a dict would give its keys whatever its values say: refused with the rest
        raise InputError("observations", obs, allowed)
    names = tuple(obs) if obs is not None else default
    if not all(isinstance(o, str) for o in names):
        raise InputError("observations", list(names), allowed)
    bad = [o for o in names if o not in OBSERVATION_MODELS]
    if bad or not names or len(set(names)) != len(names):
        raise InputError(
            "observations",
            list(names),
            f"allowed: a non-empty subset of {', '.join(OBSERVATION_MODELS)}",
        )
    return names


# the estimator's readings are part of the public step data


def env_creator(cls: type[AgriNavEnv]) -> Any:
    """What ``gym.make`` calls for ``cls`` (the registered entry point).

    It declares ``human`` even without a display, so ``gym.make(..., render_mode="human")``
    passes the mode to the env, which refuses it headless in one line; otherwise Gymnasium
    wraps a headless env in its pygame ``HumanRendering`` and fails at the first reset with an
    unrelated message. The class itself declares only the modes that work here (the checkers
    build the env in each)."""

    allowed = [n for n in inspect.signature(cls.__init__).parameters if n != "self"]

    def make(**kwargs: Any) -> AgriNavEnv:
        # an unknown keyword (a typo in a kwargs file) is one line, not a TypeError traceback
        unknown = sorted(k for k in kwargs if k not in allowed)
        if unknown:
            raise InputError("env kwargs", unknown, f"unknown; allowed: {', '.join(allowed)}")
        return cls(**kwargs)

    make.metadata = {**cls.metadata, "render_modes": ["rgb_array", "human"]}  # type: ignore[attr-defined]
    # registration checks a user env's keywords against it
    make.allowed = tuple(allowed)  # type: ignore[attr-defined]
    make.__name__ = make.__qualname__ = f"make_{cls.__name__}"
    return make


__all__ = ["AgriNavEnv", "env_creator"]
