"""The compiled per-step kernels against their Python twins: the tyre model (``tyre_forces``)
and the route's (``route_track``, ``route_nearest``, ``route_points``) bit for bit, the EKF
(``ekf_update``) to rounding, the GNSS sky's foliage loss (``sky_attenuation``) bit for bit or
to a unit in the last place, and their refusals (statuses)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from agrinav_gym.config import GnssFixConfig, LocalisationConfig, RobotConfig, SoilConfig
from agrinav_gym.estimation import ekf as ekf_module
from agrinav_gym.metrics import RouteProjector
from agrinav_gym.render import native
from agrinav_gym.routes import RoutePath, Tracker, scenario_route
from agrinav_gym.sensors.fixmode import GRID_CELL_M, Canopy, SkyModel
from agrinav_gym.sim.tyres import TyreModel
from agrinav_gym.sim.world import World
from scenario_gen import Terrain, generate, preset

from . import localisation_helpers
from .helpers import TINY

needs_kernels = pytest.mark.skipif(not native.available(), reason="compiled kernels not built")
#: how far the EKF kernel's pose may part from the numpy filter's over a 40 s drive: the two
#: round differently (BLAS sums, LAPACK's Cholesky); measured ≤ 2e-8 m, most of it from the
#: diffuse start (a 10⁶ m² prior against a 1 cm fix)
EKF_POSE_TOL = 1e-6
EKF_COV_TOL = 1e-9  # m², rad²


def _bumpy(seed: int) -> Terrain:
    rng = np.random.default_rng(seed)
    h = np.cumsum(np.cumsum(rng.normal(0.0, 0.004, (60, 80)), axis=0), axis=1)
    return Terrain(h - h.mean(), -4.0, -3.0, 0.1)


def _wheel_states(
    rng: np.random.Generator, terrain: Terrain, n: int
) -> tuple[list[tuple], list[tuple]]:
    """pybullet-shaped link and joint states of ``n`` wheels: on, above and in the ground, at
    rest and slipping, at random headings."""
    links, joints = [], []
    for _ in range(n):
        x, y = rng.uniform(-4.5, 4.5), rng.uniform(-3.5, 3.5)  # also off the grid's edge
        z = float(terrain.height_at(x, y)) + rng.choice([0.2, 0.108, 0.1, 0.09])
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        v = rng.normal(0.0, rng.choice([0.0, 1e-4, 0.5]), 3)
        w = rng.normal(0.0, rng.choice([0.0, 3.0]), 3)
        zero = (0.0, 0.0, 0.0)
        unit = (0.0, 0.0, 0.0, 1.0)
        links.append(((x, y, z), unit, zero, unit, zero, tuple(q), tuple(v), tuple(w)))
        joints.append((0.0, float(rng.choice([0.0, 1e-7, rng.normal(0.0, 8.0)])), zero, 0.0))
    return links, joints


@needs_kernels
# a point contact, the Summit-XL's tread, the tread on a ground that yields (and is cut)
@pytest.mark.parametrize("width,cohesion", [(0.0, None), (0.15, None), (0.15, 2.07)])
@pytest.mark.parametrize("seed", range(4))
def test_tyre_kernel_gives_the_python_twins_bits(
    seed: int, width: float, cohesion: float | None
) -> None:
    terrain = _bumpy(seed)
    soil = SoilConfig(contact_width=width, cohesion_kpa=cohesion, friction_angle_deg=10.0)
    kernel = TyreModel(soil, 0.11, 12.0, 1 / 240, native=True)
    twin = TyreModel(soil, 0.11, 12.0, 1 / 240, native=False)
    for t in (kernel, twin):
        t.reset(terrain)
    rng = np.random.default_rng(seed)
    contacts = 0
    for _ in range(300):  # successive steps: the shear state carries over
        links, joints = _wheel_states(rng, terrain, 4)
        a, b = kernel.forces(links, joints), twin.forces(links, joints)
        assert a == b
        assert np.array_equal(kernel.shear, twin.shear) and np.array_equal(
            kernel.normal, twin.normal
        )
        contacts += sum(a[7 * i] for i in range(4))
    assert 100 < contacts < 1100  # both branches (airborne and in contact) were taken
    assert np.array_equal(kernel.ground, twin.ground)
    # the yielding ground was cut (the same cells, to the same bits); a rigid one never is
    assert (kernel.ground < terrain.heights).any() == (cohesion is not None)


@needs_kernels
def test_a_drive_over_ridges_is_the_same_with_the_kernel_and_the_twin() -> None:
    """The whole physics, bit for bit: the same trajectory either way."""
    scn = generate(preset("ridged", field={"width": 8.0, "length": 12.0}), 0)
    terrain = scn.terrain
    paths = []
    for use_kernel in (True, False):
        w = World(RobotConfig())
        g = w.geometry
        w.tyres = TyreModel(
            w.soil, g.wheel_radius, 0.25 * g.mass, 1 / w.cfg.physics_hz, native=use_kernel
        )
        try:
            w.load(terrain)
            ny, nx = terrain.shape
            cx, cy = (
                terrain.x0 + 0.5 * (nx - 1) * terrain.spacing,
                terrain.y0 + 0.5 * (ny - 1) * terrain.spacing,
            )
            w.place_robot(cx, cy, 0.3, terrain)
            rows = []
            for k in range(60):
                w.drive(0.8, 0.6 * math.sin(k / 10))
                w.step(12)
                s = w.state()
                rows.append(np.concatenate([s.pos, s.rpy, s.vel, s.ang, s.wheels]))
            paths.append(np.asarray(rows))
        finally:
            w.close()
    assert np.array_equal(paths[0], paths[1])


def test_the_tyre_twin_is_used_without_the_kernels(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AGRINAV_NATIVE", "0")
    assert not TyreModel(SoilConfig(), 0.11, 12.0, 1 / 240).native
    assert not ekf_module.Ekf(LocalisationConfig(), 2.1, 0.05).native


@needs_kernels
def test_the_tyre_kernel_refuses_what_it_cannot_read() -> None:
    ground = native.TyreGround(
        heights=np.zeros((1, 5)), heights0=None, nx=5, ny=1, x0=0.0, y0=0.0, spacing=0.1,
        radius=0.11, dt=1 / 240, kz=6e4, cz=500.0, friction=0.6, shear_modulus=0.025,
        contact_length=0.1, rolling_resistance=0.06, shear_damping=0.05, contact_width=0.0,
        slices=0, bearing=0, bear_cohesive=0.0, bear_weight=0.0, bear_k3=0.0,
    )  # fmt: skip
    args = native.TyreForcesArgs(
        ground=ground, n=4, wheels=np.zeros((4, 14)), shear=np.zeros((4, 3)),
        normal=np.zeros(4), out=np.zeros((4, 7)),
    )  # fmt: skip
    with pytest.raises(native.KernelError, match="tyre_forces failed with status 2"):
        native.call(args)  # one row of heights: no cell to interpolate
    ground.set(heights=np.zeros((2, 5)), ny=2, spacing=0.0)
    with pytest.raises(native.KernelError, match="status 4"):
        native.call(args)
    ground.set(spacing=0.1, slices=65)  # more discs than the kernel allows
    with pytest.raises(native.KernelError, match="status 4"):
        native.call(args)
    ground.set(slices=6, contact_width=0.15, bearing=1, bear_k3=-1.0)  # a negative capacity
    with pytest.raises(native.KernelError, match="status 4"):
        native.call(args)
    ground.set(bear_k3=0.5)  # a yielding ground without the field's heights before any cut
    with pytest.raises(native.KernelError, match="status 3"):
        native.call(args)
    ground.set(slices=0, bearing=0)
    args.set(shear=None)
    with pytest.raises(native.KernelError, match="status 3"):
        native.call(args)
    out = np.full((4, 7), np.nan)
    args.set(shear=np.zeros((4, 3)), out=out)
    native.call(args)  # all well: four wheels at the origin, centres on the ground
    assert (out[:, 0] == 1.0).all()  # in contact, pressed in by a whole radius


def _drive(native_ekf: bool, mode: str, seed: int, **kw: object) -> localisation_helpers.Drive:
    def make(kind: str, cfg: object = None, skid_factor: float = 1.0, dt: float = 0.05) -> object:
        return ekf_module.Ekf(cfg, skid_factor, dt, native=native_ekf)  # type: ignore[arg-type]

    saved = localisation_helpers.make_estimator
    localisation_helpers.make_estimator = make  # type: ignore[assignment]
    try:
        return localisation_helpers.drive("ekf", mode, seed, **kw)  # type: ignore[arg-type]
    finally:
        localisation_helpers.make_estimator = saved


@needs_kernels
@pytest.mark.parametrize(
    "mode,latency,accel",
    [
        ("rtk_fixed", 0.1, True),
        ("rtk_float", 0.1, True),
        ("standalone", 0.25, True),
        ("rtk_fixed", 0.0, False),
    ],
)
def test_ekf_kernel_follows_the_numpy_filter(mode: str, latency: float, accel: bool) -> None:
    loc = LocalisationConfig(use_accel=accel)
    a = _drive(True, mode, 3, latency=latency, loc=loc)
    b = _drive(False, mode, 3, latency=latency, loc=loc)
    assert np.abs(a.errors - b.errors).max() < EKF_POSE_TOL
    # the first fix cancels the 10⁶ m² prior down to ~10⁻⁴ m²: both filters keep ~10⁻¹⁰ m²
    # of that rounding (DIFFUSE times a few machine epsilons)
    assert np.abs(a.covariances - b.covariances).max() < EKF_COV_TOL


@needs_kernels
def test_ekf_kernel_replays_a_short_history_as_the_filter_does() -> None:
    """A history shorter than the latency: fixes older than it are dropped by both."""
    loc = LocalisationConfig(history_s=0.1)
    a = _drive(True, "rtk_fixed", 1, latency=0.15, seconds=10.0, loc=loc)
    b = _drive(False, "rtk_fixed", 1, latency=0.15, seconds=10.0, loc=loc)
    assert np.abs(a.errors - b.errors).max() < EKF_POSE_TOL


@needs_kernels
def test_ekf_kernel_raises_as_numpy_on_a_covariance_that_is_not_positive() -> None:
    from agrinav_gym.estimation import Readings

    z3 = np.zeros(3)
    r = Readings(z3, False, "none", z3, 0.0, z3, z3, z3, np.zeros(2), z3)
    for use_kernel in (True, False):
        f = ekf_module.Ekf(LocalisationConfig(), 2.1, 0.05, native=use_kernel)
        f.reset(0.0, 0.0, 0.0, np.random.default_rng(0))
        f.P[:] = -np.eye(12)  # no filter gets here; a kernel bug could
        with pytest.raises(np.linalg.LinAlgError, match="not positive"):
            f.update(r, 0.05)


@pytest.fixture(scope="module")
def field_route() -> RoutePath:
    """A FieldRoute route: lanes 0.75 m apart joined by headland turns (points near several
    lanes at once, ties between a segment's two ends)."""
    return scenario_route(generate(preset("default", **TINY), 0))


def _points_around(route: RoutePath, n: int, seed: int) -> np.ndarray:
    """Points walking along the route with growing lateral offsets (to 3 m), and some far off."""
    rng = np.random.default_rng(seed)
    s = np.sort(rng.uniform(-1.0, route.length + 1.0, n))
    xy = route.sample(s) + rng.normal(0.0, 1.0, (n, 2)) * np.linspace(0.0, 3.0, n)[:, None]
    xy[::17] += rng.uniform(-30.0, 30.0, (len(xy[::17]), 2))
    xy[5] = route.xy[7]  # on a vertex: two segments at the same distance
    return xy


@needs_kernels
def test_route_tracker_kernel_gives_the_python_twins_bits(field_route: RoutePath) -> None:
    kernel, twin = Tracker(field_route, native=True), Tracker(field_route, native=False)
    pts = _points_around(field_route, 600, 0)
    for t in (kernel, twin):
        t.reset(*pts[0])
    for x, y in pts.tolist():
        assert kernel.update(x, y) == twin.update(x, y)


@needs_kernels
def test_nearest_segment_kernel_gives_the_python_twins_bits(field_route: RoutePath) -> None:
    kernel = RouteProjector(field_route.xy, field_route.furrow, native=True)
    twin = RouteProjector(field_route.xy, field_route.furrow, native=False)
    tracker = Tracker(field_route, native=False)
    pts = _points_around(field_route, 800, 1)
    tracker.reset(*pts[0])
    for x, y in pts.tolist():
        cte, _, _ = tracker.update(x, y)
        for bound in (abs(cte), None, abs(cte) + 5.0):  # the env's bound, none, a loose one
            assert kernel.project(x, y, bound) == twin.project(x, y, bound)


@needs_kernels
def test_route_observation_kernel_gives_the_python_twins_floats(
    field_route: RoutePath, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same float32 observation: the rotation into the robot frame differs from numpy's
    matmul only where that fuses a multiply-add, in a double's last bit."""
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.observations import RouteObservation
    from agrinav_gym.robot import RobotGeometry, robot_interface

    cfg = EnvConfig.from_dict({})
    robot = robot_interface(cfg, RobotGeometry.from_urdf())
    models = {}
    for name, available in (("kernel", True), ("twin", False)):
        monkeypatch.setattr(native, "available", lambda a=available: a)
        m = RouteObservation(cfg, robot)
        snap = SimpleNamespace(route=field_route, start=(*field_route.xy[0], 0.0), start_arc=0.0)
        m.reset(snap)  # type: ignore[arg-type]
        models[name] = m
    monkeypatch.undo()
    assert models["kernel"]._points is not None and models["twin"]._points is None
    rng = np.random.default_rng(2)
    for x, y in _points_around(field_route, 500, 2).tolist():
        snap = SimpleNamespace(estimate=(x, y, float(rng.uniform(-4.0, 4.0))), route=field_route)
        a, b = (models[k].encode(snap) for k in ("kernel", "twin"))  # type: ignore[arg-type]
        assert a.dtype == b.dtype == np.float32 and np.array_equal(a, b)


def _sky_field(stage: int, rows: float) -> Canopy:
    spec = preset(
        "default",
        layout={"row_spacing": rows},
        crop={"stage": stage},
        field={"width": 12.0, "length": 20.0},
    )
    return Canopy(generate(spec, 0))


def _antennas(canopy: Canopy, n: int, seed: int) -> np.ndarray:
    """Antennas over the field and past its edges, from the ground to above the canopy."""
    rng = np.random.default_rng(seed)
    lo, hi = canopy.xy.min(axis=0) - 6.0, canopy.xy.max(axis=0) + 6.0
    xy = rng.uniform(lo, hi, (n, 2))
    xy[::5] = canopy.xy[rng.integers(0, len(canopy), len(xy[::5]))]  # on a stalk
    z = rng.uniform(float(canopy.bottom.min()) - 0.3, canopy.max_top + 0.3, n)
    return np.column_stack([xy, z])


@needs_kernels
@pytest.mark.parametrize("stage,rows", [(5, 1.0), (5, 0.76), (3, 1.0)])
@pytest.mark.parametrize("profile", ["uniform", "stalk"])
def test_sky_kernel_gives_the_numpy_twins_loss(stage: int, rows: float, profile: str) -> None:
    """The same plants in reach as cKDTree finds, summed in the same order: with uniform
    foliage the same bits; with the stalk profile libm's pow against numpy's (a unit in the
    last place), so the same sky fractions."""
    canopy = _sky_field(stage, rows)
    cfg = GnssFixConfig(foliage_profile=profile)
    kernel, twin = SkyModel(cfg, canopy, native=True), SkyModel(cfg, canopy, native=False)
    assert kernel._args is not None and twin._args is None
    shaded = 0
    for ant in _antennas(canopy, 150, stage):
        a, b = kernel.attenuation(ant), twin.attenuation(ant)
        reach = twin._reach(float(ant[2]))
        if reach is not None:
            assert kernel._args.n_found == len(canopy.tree.query_ball_point(ant[:2], reach))
        if profile == "uniform":
            assert np.array_equal(a, b)
        else:
            np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-12)
        assert kernel.usable(ant) == twin.usable(ant)
        shaded += bool(b.any())
    assert shaded > 50  # most antennas see some canopy: the comparison is not of zeros


@needs_kernels
def test_sky_kernel_on_a_grid_coarsened_past_its_cell_limit() -> None:
    """Plants kilometres apart make the grid's cells double (native.MAX_GRID_CELLS): the
    search still finds what cKDTree finds."""
    from scipy.spatial import cKDTree

    canopy = _sky_field(5, 1.0)
    far = canopy.xy[:40] + np.array([30_000.0, -20_000.0])
    canopy.xy = np.ascontiguousarray(np.concatenate([canopy.xy, far]))
    for name in ("radius", "bottom", "top", "share"):
        v = getattr(canopy, name)
        setattr(canopy, name, np.ascontiguousarray(np.concatenate([v, v[:40]])))
    canopy.tree = cKDTree(canopy.xy)
    assert canopy.grid.cell > GRID_CELL_M
    cfg = GnssFixConfig()
    kernel, twin = SkyModel(cfg, canopy, native=True), SkyModel(cfg, canopy, native=False)
    for ant in [*_antennas(canopy, 30, 7)[:15], *(np.array([*p, 0.7]) for p in far[:15])]:
        assert np.array_equal(kernel.attenuation(ant), twin.attenuation(ant))


@needs_kernels
def test_the_sky_kernel_refuses_an_antenna_it_cannot_place(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sky = SkyModel(GnssFixConfig(), _sky_field(5, 1.0), native=True)
    with pytest.raises(native.KernelError, match="sky_attenuation failed with status 4"):
        sky.attenuation(np.array([math.nan, 0.0, 0.5]))
    monkeypatch.setenv("AGRINAV_NATIVE", "0")
    assert SkyModel(GnssFixConfig(), _sky_field(5, 1.0))._args is None
