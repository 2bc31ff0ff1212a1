import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from agrinav_gym.config import GnssConfig, ImuConfig
from agrinav_gym.render.proxy_plants import PlantField
from agrinav_gym.sensors.gnss import MODES, Gnss
from agrinav_gym.sensors.imu import G, Imu
from scenario_gen import Terrain

from .helpers import make_camera


@pytest.mark.parametrize("mode", ["rtk_fixed", "rtk_float", "standalone"])
def test_gnss_error_statistics_match_the_mode(mode: str) -> None:
    cfg = GnssConfig(mode=mode, baseline_km=1.0)
    gnss = Gnss(cfg, control_dt=0.05)
    rng = np.random.default_rng(0)
    truth = np.array([10.0, -5.0, 1.0])
    # stationary distribution: each reset draws an independent steady-state error
    err = []
    for _ in range(4000):
        gnss.reset(truth, rng)
        err.append(gnss.reading - truth)
    e = np.asarray(err)
    cep = MODES[mode].cep + (1e-3 if mode != "standalone" else 0.0)  # + 1 ppm of 1 km
    # the median horizontal error *is* the CEP; 4,000 samples pin it to about ±3 %
    assert np.median(np.hypot(e[:, 0], e[:, 1])) == pytest.approx(cep, rel=0.06)
    assert np.std(e[:, 2]) == pytest.approx(
        (MODES[mode].vertical + (1e-3 if mode != "standalone" else 0.0)) / 1.1774, rel=0.06
    )
    # time-correlated, not white: the lag-τ autocorrelation is e⁻¹
    tau = MODES[mode].tau
    gnss.reset(truth, rng)
    fixes = []
    for _ in range(int(300 * tau / 0.05)):
        gnss.step(truth, rng, 0.05)
        if gnss.updated:
            fixes.append(gnss.reading[0] - truth[0])
    x = np.asarray(fixes)
    lag = round(tau / 0.1)
    assert float(np.corrcoef(x[:-lag], x[lag:])[0, 1]) == pytest.approx(math.exp(-1), abs=0.1)
    assert gnss.every == 2  # 10 Hz fixes at 20 Hz control


def test_imu_noise_matches_the_datasheet() -> None:
    cfg = ImuConfig()
    dt = 0.05
    imu = Imu(cfg, dt)
    rng = np.random.default_rng(1)
    imu.reset(rng)
    rot, zero, rpy = np.eye(3), np.zeros(3), np.zeros(3)
    f, w, est = [], [], []
    for _ in range(60000):  # 3,000 s: 10 orientation correlation times per 100 s
        a, b, c = imu.measure(rot, zero, zero, rpy, rng)
        f.append(a)
        w.append(b)
        est.append(c)
    f, w, est = np.asarray(f), np.asarray(w), np.asarray(est)
    rate = 1 / dt
    gyro_sigma = math.radians(0.01) * math.sqrt(rate)  # 0.01 °/s/√Hz
    accel_sigma = 60e-6 * G * math.sqrt(rate)  # 60 µg/√Hz
    # white noise std from first differences (bias drift is negligible per step)
    assert np.std(np.diff(w, axis=0)) / math.sqrt(2) == pytest.approx(gyro_sigma, rel=0.03)
    assert np.std(np.diff(f, axis=0)) / math.sqrt(2) == pytest.approx(accel_sigma, rel=0.03)
    # at rest the accelerometer measures +g up (specific force), within bias + noise
    assert f[:, 2].mean() == pytest.approx(G, abs=5 * 15e-6 * G + 1e-4)
    assert abs(f[:, 0].mean()) < 5 * 15e-6 * G + 1e-4
    # gyro bias within a few in-run stabilities (10 °/h)
    assert np.abs(w.mean(axis=0)).max() < 5 * math.radians(10 / 3600)
    # orientation estimate RMS: roll/pitch 0.2°, heading 1°
    rms = np.sqrt((est**2).mean(axis=0))
    assert rms[0] == pytest.approx(math.radians(0.2), rel=0.2)
    assert rms[2] == pytest.approx(math.radians(1.0), rel=0.2)


@pytest.mark.parametrize("ridged", [False, True])
def test_the_imu_reads_gravity_from_the_first_step(ridged: bool) -> None:
    """``reset`` lets the robot settle on the ground before the episode: standing still, the
    specific force reads g within its noise at the reset and every step after (it used to
    read 0.02, 27.3, 3.3 ... m/s² while the robot dropped onto its tyres). Ridged seed 2 starts
    on ridge flanks where the tyres chatter for ≈ 9 s before the robot rests."""
    from agrinav_gym.interface import decode_imu

    from .helpers import STILL, TINY, make

    over = {**TINY, "furrows": {"enabled": True}} if ridged else TINY
    env = make(scenario_overrides=over, config=STILL)
    sigma = 60e-6 * G * math.sqrt(20.0)  # white noise at the 20 Hz control rate
    tol = 6 * sigma + 5 * 15e-6 * G  # noise and the in-run bias
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        f = [np.linalg.norm(decode_imu(obs["imu"]).specific_force)]
        for _ in range(10):
            obs, *_ = env.step(np.zeros(2, np.float32))
            f.append(np.linalg.norm(decode_imu(obs["imu"]).specific_force))
        assert np.abs(np.array(f) - G).max() < tol, (seed, np.round(f, 4))
    env.close()


def _empty_plants() -> PlantField:
    e = np.empty(0)
    tree = cKDTree(np.zeros((1, 2)))
    return PlantField(np.empty((0, 2)), e, e, e, np.empty(0, bool), tree, 0.0, 0)


def _flat(z: float = 0.0) -> Terrain:
    return Terrain(np.full((200, 200), z), -12.0, -12.0, 0.12)


def test_depth_pixel_reads_the_true_distance_to_the_ground(kernels: str) -> None:
    cam = make_camera(
        {"camera_pitch_deg": 30.0, "camera_height": 0.55, "camera_x": 0.25},
        {"width": 64, "height": 48},
    )
    pos = np.array([0.0, 0.0, 0.11])
    frame = cam.draw(np.eye(3), pos, _flat(), _empty_plants(), rng=None)
    # analytic: the ray of pixel (row 30, col 20) from the camera origin to z = 0
    o, rays = cam.pose(np.eye(3), pos)
    i = 30 * 64 + 20
    t = -o[2] / rays[i, 2]
    expect = t * cam.forward[i]
    assert frame.depth[30, 20] == pytest.approx(expect, abs=1e-4)
    # every pixel below the horizon that sees ground within range is valid
    assert (frame.depth[30:] > 0).all()


# The reference path draws the same noise bits as the kernels
# (test_native.test_the_proxy_camera_draws_the_same_frame_without_the_kernels), and its 3,000
# frames cost ≈ 40 s: the law is checked on it in the full suite only.
@pytest.mark.parametrize(
    "kernels", ["compiled", pytest.param("reference", marks=pytest.mark.slow)], indirect=True
)
def test_depth_noise_follows_the_stereo_error_law(kernels: str) -> None:
    cam = make_camera({"camera_pitch_deg": 5.0}, {"width": 32, "height": 24})
    plants = _wall_plant(distance=4.0, radius=0.5, height=3.0)
    pos = np.array([0.0, 0.0, 0.11])
    rng = np.random.default_rng(0)
    samples = np.array(
        [cam.draw(np.eye(3), pos, _flat(), plants, rng).depth[12, 16] for _ in range(3000)]
    )
    true = float(cam.draw(np.eye(3), pos, _flat(), plants, None).depth[12, 16])
    sigma = true**2 * 0.08 / (cam.f_native * 0.095)
    assert samples.mean() == pytest.approx(true, abs=4 * sigma / math.sqrt(len(samples)))
    assert samples.std() == pytest.approx(sigma, rel=0.06)
    assert sigma / true < 0.02  # D455: < 2 % at 4 m


def _wall_plant(distance: float, radius: float, height: float) -> PlantField:
    xy = np.array([[0.25 + distance, 0.0]])
    tree = cKDTree(xy)
    return PlantField(
        xy,
        np.zeros(1),
        np.full(1, height),
        np.full(1, radius),
        np.zeros(1, bool),
        tree,
        radius,
        1,
    )


def test_depth_sees_a_plant_at_its_distance_and_labels_it(kernels: str) -> None:
    cam = make_camera({"camera_pitch_deg": 0.0}, {"width": 33, "height": 25, "segmentation": True})
    plants = _wall_plant(distance=3.0, radius=0.2, height=2.0)
    frame = cam.draw(np.eye(3), np.array([0.0, 0.0, 0.11]), _flat(), plants, None, labels=True)
    # the centre pixel looks straight along the optical axis at the cylinder's near side
    assert frame.depth[12, 16] == pytest.approx(3.0 - 0.2, abs=1e-6)
    assert frame.label[12, 16] == 2  # crop
    assert frame.label[-1, 0] == 1  # soil at the bottom corner
    assert frame.label[0, 0] == 0  # nothing within range above the horizon


def test_depth_out_of_range_is_zero(kernels: str) -> None:
    cam = make_camera(None, {"width": 16, "height": 12, "max_range": 2.0})
    frame = cam.draw(np.eye(3), np.array([0.0, 0.0, 0.11]), _flat(), _empty_plants(), None)
    assert (frame.depth == 0).any() and frame.depth.max() <= 2.0


def test_a_plant_seen_from_below_its_leaf_band(kernels: str) -> None:
    # a leaf band from 1.0 to 2.0 m, 2 m ahead: a ray 10° up from 0.66 m meets its underside
    cam = make_camera(
        {"camera_pitch_deg": -10.0, "camera_height": 0.55, "camera_x": 0.0},
        {"width": 33, "height": 25},
    )
    xy = np.array([[2.0, 0.0]])
    tree = cKDTree(xy)
    plants = PlantField(
        xy,
        np.full(1, 1.0),
        np.full(1, 2.0),
        np.full(1, 0.5),
        np.zeros(1, bool),
        tree,
        0.5,
        1,
    )
    pos = np.array([0.0, 0.0, 0.11])
    o, rays = cam.pose(np.eye(3), pos)
    frame = cam.draw(np.eye(3), pos, _flat(), plants, None)
    i = 12 * 33 + 16  # the optical axis
    t = (1.0 - o[2]) / rays[i, 2]
    x = o[0] + t * rays[i, 0]
    assert 1.5 <= x <= 2.5  # under the band
    assert frame.depth[12, 16] == pytest.approx(t * cam.forward[i], abs=1e-6)


@pytest.mark.parametrize(
    ("band", "pitch_deg", "expect"),
    [
        # the camera (0.66 m up, 0.25 m ahead of base_link) inside a band of radius 0.5 m whose
        # axis is 0.2 m ahead: the optical axis leaves through the wall 0.7 m away
        ((0.2, 2.0), 0.0, 0.7),
        # under a band from 1.0 m: looking 30° up it meets the underside after 0.34 / sin 30°,
        # 0.59 m ahead (within the disc); above one topping out at 0.4 m, looking 30° down, the
        # top after 0.26 / sin 30°
        ((1.0, 2.0), -30.0, (1.0 - 0.66) / math.sin(math.radians(30.0))),
        ((0.0, 0.4), 30.0, (0.66 - 0.4) / math.sin(math.radians(30.0))),
    ],
)
def test_a_band_over_the_camera_is_seen_from_where_the_camera_is(
    kernels: str, band: tuple[float, float], pitch_deg: float, expect: float
) -> None:
    """Leaf bands reach over the lane: a camera among leaves sees them close by."""
    cam = make_camera(
        {"camera_pitch_deg": pitch_deg, "camera_height": 0.55, "camera_x": 0.25},
        {"width": 33, "height": 25},
    )
    pos = np.array([0.0, 0.0, 0.11])
    o, rays = cam.pose(np.eye(3), pos)
    xy = np.array([[o[0] + 0.2, 0.0]])
    plants = PlantField(
        xy,
        np.array([band[0]]),
        np.array([band[1]]),
        np.array([0.5]),
        np.zeros(1, bool),
        cKDTree(xy),
        0.5,
        1,
    )
    t, lab = cam.cast(o, rays, _flat(), plants, cam.t_lim)
    i = 12 * 33 + 16  # the optical axis
    assert t[i] == pytest.approx(expect, abs=1e-5) and lab[i] == 2


@pytest.mark.parametrize("stage", [1, 3, 5])
def test_maize_proxies_follow_the_fitted_model(stage: int) -> None:
    """Core radius = fill × canopy width, leaf band from base × height to the top reaching
    reach × half the canopy width × |sin(yaw − row)|, all scaled with the plant's height."""
    from agrinav_gym.render.proxy_params import proxy_params
    from scenario_gen import CATALOG, generate, preset

    scn = generate(preset("default", crop={"stage": stage}, layout={"row_spacing": 1.0}), 0)
    field = PlantField.from_scenario(scn)
    p = scn.plants
    sp = CATALOG["corn"]
    growth = sp.growth_of_stage(stage)
    fill, base, reach = (float(v) for v in proxy_params("corn", growth))
    scale = p.height / float(sp.height(growth))
    width = float(sp.canopy_width(growth)) * scale
    n = len(field)
    assert np.allclose(field.radius[:n], fill * width)
    assert np.allclose(field.top[:n] - field.z[:n], p.height)
    band = slice(n, None)
    across = np.abs(np.sin(p.yaw - scn.rows.angle))
    leaf = 0.5 * reach * width * across
    has = np.flatnonzero(leaf > fill * width)  # bands only where they reach past the core
    assert len(field.radius[band]) == len(has)
    assert np.allclose(field.radius[band], leaf[has])
    assert np.allclose(field.z[band], p.z[has] + base * p.height[has])
    assert np.allclose(field.xy[band], np.column_stack([p.x, p.y])[has])


def test_only_planar_leaved_crops_grow_leaf_bands() -> None:
    from scenario_gen import generate, preset

    tomato = generate(preset("default", crop={"species": "tomato", "stage": 4}), 0)
    field = PlantField.from_scenario(tomato)
    assert len(field.radius) == len(field)  # cores only
    corn = PlantField.from_scenario(generate(preset("default", crop={"stage": 4}), 0))
    assert len(corn.radius) > len(corn)


@pytest.mark.parametrize("model", ["proxy", "mesh"])
def test_both_cameras_render_a_field_through_one_interface(model: str) -> None:
    """``make_camera`` by config, ``render`` on a ``FieldView``: the same frame the camera's own
    ``draw`` makes from the scene it would build, and nothing built that it does not use."""
    import scenario_gen as sg
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.render.mesh_scene import MeshScene
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from agrinav_gym.sensors import make_camera as camera_for
    from agrinav_gym.sensors.camera import FieldView

    from .helpers import FLAT, lane_pose

    cfg = EnvConfig.from_dict({"camera": {"model": model, "width": 64, "height": 48}})
    cam = camera_for(cfg.camera, robot_interface(cfg, RobotGeometry.from_urdf()).camera)
    scn = sg.generate(sg.preset("default", **FLAT), 3)
    rot, pos = lane_pose(scn)
    view = FieldView(scn)
    frame = cam.render(rot, pos, view, np.random.default_rng(5), rgb=True, labels=True)
    assert frame.depth.shape == (48, 64) and frame.label is not None and frame.rgb is not None
    assert (frame.depth > 0).mean() > 0.25  # ground below the horizon, less stereo shadows
    if model == "proxy":
        ref = cam.draw(
            rot, pos, scn.terrain, PlantField.from_scenario(scn), np.random.default_rng(5)
        )
        assert view._scenes._scene is None  # no meshes built
    else:
        ref = cam.draw(rot, pos, MeshScene.from_scenario(scn), np.random.default_rng(5))
        assert view._plants is None  # no proxies built
    np.testing.assert_array_equal(frame.depth, ref.depth)
