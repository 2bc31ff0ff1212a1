"""The shared environment: a Summit-XL on a scenario's terrain, following a reference route.

Subclasses choose the route (``_make_route``), the start (``_start_pose``) and the default
observations; everything else — physics, sensors, estimation, reward parts, termination,
metrics — lives here once.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import pybullet as p
from gymnasium import spaces
from gymnasium.utils import EzPickle
from numpy.typing import NDArray

from scenario_gen import Scenario, ScenarioError

from ..config import OBSERVATIONS, EnvConfig
from ..metrics import cross_track_metrics
from ..scenarios import Bank, resolve, sample_randomization, split_randomization
from ..sensors.depth import DepthCamera, DepthFrame
from ..sensors.gnss import Gnss
from ..sensors.imu import Imu, WheelOdometry
from ..sim.plants import PlantField
from ..sim.world import World
from ..tasks import RoutePath, Tracker

FloatArray = NDArray[np.float64]


def obs_bounds(route_points: int) -> dict[str, tuple[NDArray[np.float32], NDArray[np.float32]]]:
    """Measurement ranges; readings saturate at them like the real sensors' do.

    gps: ENU metres (±10 km), fix code 0-2, fix age up to 60 s; imu: ±20 g specific force and
    ±450 °/s rate (MTi-300 ranges), roll/pitch ±π, sin/cos of heading; odom: ±10 m/s,
    ±20 rad/s; route: robot-frame points within ±100 m and a 0/1 furrow flag.
    """
    g20, rate = 20 * 9.81, math.radians(450.0)

    def box(lo: list[float], hi: list[float]) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        return np.asarray(lo, np.float32), np.asarray(hi, np.float32)

    return {
        "gps": box([-1e4, -1e4, -1e4, 0, 0], [1e4, 1e4, 1e4, 2, 60]),
        "imu": box(
            [-g20] * 3 + [-rate] * 3 + [-math.pi, -math.pi, -1, -1],
            [g20] * 3 + [rate] * 3 + [math.pi, math.pi, 1, 1],
        ),
        "odom": box([-10, -20], [10, 20]),
        "route": box([-100, -100, 0] * route_points, [100, 100, 1] * route_points),
    }


def _wrap(a: float) -> float:
    return float((a + math.pi) % (2 * math.pi) - math.pi)


class AgriNavEnv(gym.Env[dict[str, NDArray[np.float32]], NDArray[np.float32]], EzPickle):
    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"], "render_fps": 20}  # noqa: RUF012
    default_observations: ClassVar[tuple[str, ...]] = ("gps", "imu", "odom", "route")

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
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ScenarioError(
                "render_mode",
                render_mode,
                f"allowed: None, {', '.join(self.metadata['render_modes'])}",
            )
        obs = tuple(observations) if observations is not None else self.default_observations
        bad = [o for o in obs if o not in OBSERVATIONS]
        if bad or not obs:
            raise ScenarioError(
                "observations",
                list(obs),
                f"allowed: a non-empty subset of {', '.join(OBSERVATIONS)}",
            )
        self.observation_names = obs
        self.cfg = EnvConfig.from_dict(config)
        self.render_mode = render_mode
        self.randomize = dict(randomize or {})
        lo, hi = scenario_seeds if scenario_seeds is not None else (0, 2**31 - 1)
        if not (isinstance(lo, int) and isinstance(hi, int) and 0 <= lo < hi):
            raise ScenarioError(
                "scenario_seeds", scenario_seeds, "allowed: [low, high) integers, 0 <= low < high"
            )
        self.scenario_seeds = (lo, hi)
        self._scenario_source = (scenario, scenario_overrides)
        self.bank = Bank(bank) if bank is not None else None
        if self.randomize:  # validate the keys now, not at the first reset
            probe = sample_randomization(self.randomize, np.random.default_rng(0))
            scn_keys, _ = split_randomization(probe)
            if scn_keys and (
                self.bank is not None
                or isinstance(scenario, Scenario)
                or (
                    isinstance(scenario, (str, Path))
                    and (Path(scenario) / "scenario.json").is_file()
                )
            ):
                raise ScenarioError(
                    "randomize",
                    sorted(scn_keys),
                    "scenario keys need a preset scenario to regenerate",
                )
            if scn_keys:
                import scenario_gen as sg

                name = str(scenario or "default")
                sg.preset(name, **(scenario_overrides or {})).replace(scn_keys)
        self.scenario = (
            self.bank.sample(np.random.default_rng(scenario_seed))
            if self.bank
            else resolve(scenario, scenario_overrides, scenario_seed)
        )

        r = self.cfg.robot
        self.dt = 1.0 / r.control_hz
        self.substeps = r.physics_hz // r.control_hz
        self.world = World(r, gui=render_mode == "human")
        geo = self.world.geometry
        self.odometry = WheelOdometry(self.cfg.odom, geo.wheel_radius, geo.track)
        self.imu = Imu(self.cfg.imu, self.dt)
        self.gnss = Gnss(self.cfg.gnss, self.dt)
        self.camera = DepthCamera(self.cfg.depth, r)
        self._depth_every = max(1, round(r.control_hz / self.cfg.depth.rate_hz))
        self._route_offsets = self.cfg.task.route_spacing * np.arange(
            1, self.cfg.task.route_points + 1
        )

        k = self.cfg.task.route_points
        d = self.cfg.depth
        self._bounds = obs_bounds(k)
        all_spaces = {
            n: spaces.Box(lo, hi, dtype=np.float32) for n, (lo, hi) in self._bounds.items()
        }
        all_spaces["depth"] = spaces.Box(0.0, d.max_range, (1, d.height, d.width), np.float32)
        self.observation_space = spaces.Dict({n: all_spaces[n] for n in obs})  # type: ignore[assignment]
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._plants: PlantField | None = None
        self._plants_of: Scenario | None = None
        self._frame: DepthFrame | None = None
        self.route: RoutePath | None = None

    # ------------------------------------------------------------------ hooks
    def _make_route(self, scn: Scenario) -> RoutePath:
        raise NotImplementedError

    def _start_pose(self, route: RoutePath) -> tuple[float, float, float]:
        """Perturbed start: a little along the route, offset sideways, heading off."""
        t = self.cfg.task
        s0 = min(0.3, 0.1 * route.length)
        ((x, y),) = route.sample(np.array([s0]))
        h = float(np.interp(s0, route.arc, np.unwrap(route.heading)))
        corridor = self._corridor(True)
        lat = float(
            np.clip(
                self.np_random.normal(0.0, t.start_lateral_std), -0.5 * corridor, 0.5 * corridor
            )
        )
        dh = math.radians(
            float(np.clip(self.np_random.normal(0.0, t.start_heading_std_deg), -30.0, 30.0))
        )
        return x - lat * math.sin(h), y + lat * math.cos(h), _wrap(h + dh)

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"scenario", "lane"}
        if unknown:
            raise ScenarioError("options", sorted(unknown), "allowed keys: scenario, lane")
        env_rand: dict[str, Any] = {}
        if "scenario" in options:
            self.scenario = resolve(options["scenario"], None, 0)
        elif self.bank is not None:
            self.scenario = self.bank.sample(self.np_random)
        if self.randomize:
            scn_rand, env_rand = split_randomization(
                sample_randomization(self.randomize, self.np_random)
            )
            if scn_rand and "scenario" not in options:
                src, over = self._scenario_source
                import scenario_gen as sg

                spec = sg.preset(str(src or "default"), **(over or {})).replace(scn_rand)
                self.scenario = sg.generate(
                    spec, int(self.np_random.integers(*self.scenario_seeds))
                )
        self._apply_env_randomization(env_rand)
        scn = self.scenario
        self.world.load(scn.terrain, scn.rows.angle)
        if self._plants_of is not scn:
            self._plants = PlantField.from_scenario(scn)
            self._plants_of = scn
        self._lane_option = options.get("lane")
        self.route = self._make_route(scn)
        x, y, yaw = self._start_pose(self.route)
        self.world.place_robot(x, y, yaw, scn.terrain)
        self.world.step(1)
        self.tracker = Tracker(self.route)
        self.tracker.reset(x, y)
        self.est_tracker = Tracker(self.route)
        self.est_tracker.reset(x, y)
        self._cmd = (0.0, 0.0)
        self._prev_action = (0.0, 0.0)
        self._hit: set[int] = set()
        self._steps = 0
        self._poses: list[tuple[float, float]] = []
        # running sums for the paper's metrics: (n, Σd², Σ|d|, max) overall, in furrow, headland
        self._acc = {
            "all": [0, 0.0, 0.0, 0.0],
            "furrow": [0, 0.0, 0.0, 0.0],
            "headland": [0, 0.0, 0.0, 0.0],
        }
        self._s_max = 0.0
        self.imu.reset(self.np_random)
        self._read_state()
        self.gnss.reset(self._antenna(), self.np_random)
        self._imu_reading = self.imu.measure(
            self._rot, self._vel, self._ang, self._rpy, self.np_random
        )
        self._odom = np.zeros(2)
        self._est_xy = np.zeros(2)
        self._estimate(gnss_update=True)
        self._frame = None
        cte, s, k = self.tracker.update(self._pos[0], self._pos[1])
        self._s = self._s0 = s
        self._cte, self._k = cte, k
        self._poses.append((float(self._pos[0]), float(self._pos[1])))
        self._accumulate(cte, bool(self.route.furrow[k]), s)
        if self.render_mode == "human":
            self._load_visuals()
        return self._observe(), self._info({}, False)

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[dict[str, NDArray[np.float32]], float, bool, bool, dict[str, Any]]:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (2,):
            raise ValueError(f"action: got shape {np.shape(action)}; allowed: shape (2,)")
        if not np.isfinite(a).all():
            raise ValueError(
                f"action: got {a.tolist()}; allowed: finite values in [-1, 1] "
                "(NaN or inf would corrupt the simulation)"
            )
        # documented: out-of-range actions are clipped
        a0, a1 = min(max(float(a[0]), -1.0), 1.0), min(max(float(a[1]), -1.0), 1.0)
        r = self.cfg.robot
        dv = a0 * r.v_max - self._cmd[0]
        dw = a1 * r.w_max - self._cmd[1]
        lv, lw = r.a_max * self.dt, r.alpha_max * self.dt  # acceleration limits
        self._cmd = (self._cmd[0] + min(max(dv, -lv), lv), self._cmd[1] + min(max(dw, -lw), lw))
        self.world.drive(float(self._cmd[0]), float(self._cmd[1]))
        self.world.follow(float(self._pos[0]), float(self._pos[1]), float(self._rpy[2]))
        self.world.step(self.substeps)
        self._steps += 1
        self._read_state()
        rng = self.np_random
        self.gnss.step(self._antenna(), rng, self.dt)
        self._imu_reading = self.imu.measure(self._rot, self._vel, self._ang, self._rpy, rng)
        self._odom = self.odometry.measure(self._wheels, rng)
        self._estimate(gnss_update=self.gnss.updated)
        if "depth" in self.observation_names and self._steps % self._depth_every == 0:
            self._frame = None  # re-rendered lazily in _observe

        x, y = float(self._pos[0]), float(self._pos[1])
        self._poses.append((x, y))
        cte, s, k = self.tracker.update(x, y)
        ds = s - self._s
        self._s, self._cte, self._k = s, cte, k
        furrow = bool(self.route.furrow[k]) if self.route is not None else True
        self._accumulate(cte, furrow, s)
        geo = self.world.geometry
        assert self._plants is not None
        new = [
            i
            for i in self._plants.crops_touching(x, y, self._rpy[2], *geo.footprint).tolist()
            if i not in self._hit
        ]
        self._hit.update(new)

        corridor = self._corridor(furrow)
        heading_err = _wrap(self._rpy[2] - float(self.route.heading[k]))  # type: ignore[union-attr]
        tilt = max(abs(self._rpy[0]), abs(self._rpy[1]))
        t = self.cfg.task
        success = self.route is not None and s >= self.route.length - t.success_tolerance
        off = not bool(self.scenario.terrain.contains(x, y))
        failure = (
            abs(cte) > corridor
            or tilt > math.radians(t.max_tilt_deg)
            or len(self._hit) > t.max_crops_hit
            or off
        )
        terminated = bool(success or failure)
        w = self.cfg.reward
        progress = w.progress * ds / (r.v_max * self.dt)
        if w.progress_cte_scale is not None and furrow:
            progress *= math.exp(-abs(cte) / (w.progress_cte_scale * corridor))
        parts = {
            "progress": progress,
            "cte": -w.cte * (cte / corridor) ** 2,
            "heading": -w.heading * abs(heading_err) / math.pi,
            "crop_contact": -w.crop_contact * len(new),
            "action_rate": -w.action_rate
            * ((a0 - self._prev_action[0]) ** 2 + (a1 - self._prev_action[1]) ** 2),
            "terminal": (w.terminal if success else -w.terminal) if terminated else 0.0,
        }
        self._prev_action = (a0, a1)
        reward = float(sum(parts.values()))
        # Truncation is the TimeLimit wrapper's (max_episode_steps), which the env cannot see:
        # the running metrics therefore ride on every step's info, and the last one is final.
        truncated = False
        info = self._info(parts, bool(success), heading_err)
        info["metrics"] = self.running_metrics()
        if terminated:
            info["termination"] = (
                "success"
                if success
                else "corridor"
                if abs(cte) > corridor
                else "off_terrain"
                if off
                else "tip_over"
                if tilt > math.radians(t.max_tilt_deg)
                else "crops_hit"
                if failure
                else "time_limit"
            )
        return self._observe(), reward, terminated, truncated, info

    def _accumulate(self, cte: float, furrow: bool, s: float) -> None:
        d = abs(cte)
        for key in ("all", "furrow" if furrow else "headland"):
            a = self._acc[key]
            a[0] += 1
            a[1] += d * d
            a[2] += d
            a[3] = max(a[3], d)
        self._s_max = max(self._s_max, s)

    def running_metrics(self) -> dict[str, Any]:
        """The paper's metrics (DESIGN §6) over the episode so far, O(1) per step.

        Each pose's error is its distance to the nearest route segment as tracked along the
        route — the global nearest segment while the robot stays inside its corridor.
        ``episode_metrics`` recomputes them from the pose log against the whole route.
        """
        assert self.route is not None

        def rmse(a: list[Any]) -> float | None:
            return math.sqrt(a[1] / a[0]) if a[0] else None

        a = self._acc["all"]
        return {
            "rmse": rmse(a),
            "mae": a[2] / a[0] if a[0] else None,
            "max": a[3],
            "in_furrow_rmse": rmse(self._acc["furrow"]),
            "headland_rmse": rmse(self._acc["headland"]),
            "completion": 100.0 * self._s_max / max(self.route.length, 1e-9),
            "crops_hit": len(self._hit),
            "poses": a[0],
        }

    @property
    def trajectory(self) -> FloatArray:
        """Ground-truth base positions (N, 2) of this episode: for evaluation, never policies."""
        return np.asarray(self._poses, dtype=np.float64)

    def episode_metrics(self) -> dict[str, Any]:
        assert self.route is not None
        labels = np.where(self.route.furrow, "furrow", "headland")
        return cross_track_metrics(
            np.asarray(self._poses), self.route.xy, labels, crops_hit=len(self._hit)
        )

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode != "rgb_array":
            return None
        self._load_visuals()
        cid = self.world.client
        x, y, z = self._pos
        yaw = self._rpy[2]
        eye = [x - 3.5 * math.cos(yaw), y - 3.5 * math.sin(yaw), z + 3.5]
        view = p.computeViewMatrix(
            eye, [x + math.cos(yaw), y + math.sin(yaw), z], [0, 0, 1], physicsClientId=cid
        )
        proj = p.computeProjectionMatrixFOV(60, 4 / 3, 0.1, 60, physicsClientId=cid)
        _, _, rgba, _, _ = p.getCameraImage(
            320, 240, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=cid
        )
        return np.asarray(rgba, np.uint8).reshape(240, 320, 4)[:, :, :3].copy()

    def close(self) -> None:
        if hasattr(self, "world"):
            self.world.close()

    # ------------------------------------------------------------------ internals
    def _corridor(self, furrow: bool) -> float:
        t = self.cfg.task
        if not furrow:
            return t.headland_corridor
        return t.corridor if t.corridor is not None else 0.5 * self.scenario.rows.spacing

    def _apply_env_randomization(self, values: dict[str, Any]) -> None:
        if "gnss_mode" in values:
            from dataclasses import replace

            self.gnss = Gnss(replace(self.cfg.gnss, mode=str(values["gnss_mode"])), self.dt)
        if "soil_colour" in values:
            self.camera.soil_rgb = np.clip(np.asarray(values["soil_colour"], float), 0, 1)
        az = math.radians(float(values.get("light_azimuth_deg", 33.7)))
        el = math.radians(float(values.get("light_elevation_deg", 68.4)))
        self.camera.light = np.array(
            [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
        )

    def _read_state(self) -> None:
        pos, quat, lin, ang, wheels = self.world.state()
        self._pos = np.asarray(pos)
        self._rot = np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        self._rpy = np.asarray(p.getEulerFromQuaternion(quat))
        self._vel = np.asarray(lin)
        self._ang = np.asarray(ang)
        self._wheels = wheels

    def _antenna(self) -> FloatArray:
        g = self.cfg.gnss
        return self._pos + self._rot @ np.array([g.antenna_x, 0.0, g.antenna_height])

    def _estimate(self, gnss_update: bool) -> None:
        """GNSS + IMU attitude (+ odometry between fixes): the pose a real robot would know.

        The antenna sits on a 0.6 m mast, so a few degrees of roll on a furrow ridge move it
        centimetres sideways; like a GNSS/INS, the fix is brought back to base_link through the
        lever arm rotated by the IMU's attitude estimate.
        """
        roll, pitch, yaw = (float(v) for v in self._imu_reading[2])
        c, s = math.cos(yaw), math.sin(yaw)
        if gnss_update:
            g = self.cfg.gnss
            cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
            # R = Rz(yaw)·Ry(pitch)·Rx(roll) applied to the lever arm (ax, 0, ah)
            lx = cp * g.antenna_x + sp * cr * g.antenna_height
            ly = -sr * g.antenna_height
            ant = self.gnss.reading
            self._est_xy = np.array([ant[0] - (c * lx - s * ly), ant[1] - (s * lx + c * ly)])
        else:
            v = float(self._odom[0])
            self._est_xy = self._est_xy + v * self.dt * np.array([c, s])
        self._est_yaw = yaw

    def _observe(self) -> dict[str, NDArray[np.float32]]:
        out: dict[str, NDArray[np.float32]] = {}
        names = self.observation_names
        if "gps" in names:
            g = self.gnss
            gps = np.empty(5, np.float32)
            gps[:3] = g.reading
            gps[3], gps[4] = g.mode.code, min(g.age, 60.0)
            out["gps"] = gps
        if "imu" in names:
            f, w, est = self._imu_reading
            imu = np.empty(10, np.float32)
            imu[:3], imu[3:6], imu[6:8] = f, w, est[:2]
            imu[8], imu[9] = math.sin(est[2]), math.cos(est[2])
            out["imu"] = imu
        if "odom" in names:
            out["odom"] = self._odom.astype(np.float32)
        if "route" in names:
            out["route"] = self._route_obs()
        for name, value in out.items():  # saturate like the real sensors
            lo, hi = self._bounds[name]
            np.minimum(np.maximum(value, lo, out=value), hi, out=value)
        if "depth" in names:
            if self._frame is None:
                d = self.cfg.depth
                assert self._plants is not None
                self._frame = self.camera.render(
                    self._rot,
                    self._pos,
                    self.scenario.terrain,
                    self._plants,
                    self.np_random,
                    rgb=d.rgb,
                    labels=d.segmentation,
                )
            out["depth"] = self._frame.depth[None]
        return out

    def _route_obs(self) -> NDArray[np.float32]:
        route = self.route
        assert route is not None
        t = self.cfg.task
        ex, ey = float(self._est_xy[0]), float(self._est_xy[1])
        _, s, _ = self.est_tracker.update(ex, ey)
        pts, furrow = route.lookup(s + self._route_offsets)
        c, sn = math.cos(self._est_yaw), math.sin(self._est_yaw)
        out = np.empty((t.route_points, 3), np.float32)
        out[:, :2] = (pts - (ex, ey)) @ np.array([[c, -sn], [sn, c]])  # world -> robot frame
        out[:, 2] = furrow
        return out.ravel()

    def _info(
        self, parts: dict[str, float], success: bool, heading_err: float | None = None
    ) -> dict[str, Any]:
        assert self.route is not None
        if self.gnss.updated:
            self._lat, self._lon, _ = self.scenario.geo.point_to_geodetic(*self.gnss.reading)
        info: dict[str, Any] = {
            "cte": float(self._cte),
            "heading_error": float(
                heading_err
                if heading_err is not None
                else _wrap(self._rpy[2] - float(self.route.heading[self._k]))
            ),
            "progress": float((self._s - self._s0) / max(self.route.length - self._s0, 1e-9)),
            "segment": "furrow" if self.route.furrow[self._k] else "headland",
            "crops_hit": len(self._hit),
            "lat": self._lat,
            "lon": self._lon,
            "rewards": parts,
            "is_success": success,
        }
        if self._frame is not None and self._frame.rgb is not None:
            info["rgb"] = self._frame.rgb
        if self._frame is not None and self._frame.label is not None:
            info["segmentation"] = self._frame.label
        return info

    def _load_visuals(self) -> None:
        if self.world.visuals_loaded:
            return
        from ..sim.visuals import load_plant_visuals, load_terrain_visual

        load_terrain_visual(self.world.client, self.scenario)
        load_plant_visuals(self.world.client, self.scenario)
        self.world.visuals_loaded = True
