"""GNSS fix mode under the canopy (sensors/fixmode) and the receiver's latency (sensors/gnss)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenario_gen as sg
from agrinav_gym.config import GnssConfig, GnssFixConfig
from agrinav_gym.sensors.fixmode import LEVELS, Canopy, FixModeChain, SkyModel
from agrinav_gym.sensors.gnss import Gnss, error_sigma

from .helpers import TINY, make

ANTENNA_AGL = 0.11 + 0.60  # base_link above ground + mast (design.md "Physical facts", GnssConfig)


def field(stage: int, rows: float = 1.0) -> sg.Scenario:
    spec = sg.preset(
        "default",
        layout={"row_spacing": rows},
        crop={"stage": stage},
        field={"width": 12.0, "length": 20.0},
    )
    return sg.generate(spec, 0)


def lane_antenna(scn: sg.Scenario) -> np.ndarray:
    """The antenna over the middle of a lane near the field centre."""
    p = scn.plants
    rows = np.unique(p.row[p.row >= 0])
    a, b = (np.array([p.x[p.row == r].mean(), p.y[p.row == r].mean()]) for r in rows[3:5])
    c = 0.5 * (a + b)
    return np.array([c[0], c[1], float(scn.terrain.height_at(c[0], c[1])) + ANTENNA_AGL])


def modes_over(chain: FixModeChain, q: tuple[float, float], seconds: float, seed: int) -> list[str]:
    rng = np.random.default_rng(seed)
    return [chain.step(*q, rng) for _ in range(round(seconds / chain.epoch_s))]


@pytest.mark.parametrize("rows", [1.0, 0.76])
def test_mature_maize_over_the_antenna_loses_rtk_fixed(rows: float) -> None:
    scn = field(5, rows)  # R1: 2.5 m, canopy 1 m wide
    q = SkyModel(GnssFixConfig(), Canopy(scn)).usable(lane_antenna(scn))
    chain = FixModeChain(GnssFixConfig(), "rtk_fixed", 0.1)
    assert chain.supported(*q) < LEVELS.index("rtk_fixed")
    chain.level = LEVELS.index("rtk_fixed")  # a fixed receiver driving in
    modes = modes_over(chain, q, 60.0, seed=0)
    assert "rtk_fixed" not in modes[50:]  # lost within 5 s (mean 0.5 s) and never regained


def test_seedlings_below_the_antenna_keep_rtk_fixed() -> None:
    scn = field(1)  # V3: 0.3 m
    q = SkyModel(GnssFixConfig(), Canopy(scn)).usable(lane_antenna(scn))
    assert q == (1.0, 1.0)
    chain = FixModeChain(GnssFixConfig(), "rtk_fixed", 0.1)
    assert chain.reset(*q) == "rtk_fixed"
    modes = modes_over(chain, q, 60.0, seed=0)
    # open sky: only multipath slips (mean 600 s apart, 10 s to re-fix)
    assert modes.count("rtk_fixed") / len(modes) > 0.8


def test_canopy_loss_grows_with_the_crop() -> None:
    qs = []
    for stage in (1, 3, 4, 5):
        scn = field(stage)
        qs.append(SkyModel(GnssFixConfig(), Canopy(scn)).usable(lane_antenna(scn))[0])
    assert qs == sorted(qs, reverse=True) and qs[0] == 1.0 and qs[-1] < 0.5


def test_attenuation_through_one_plant_is_its_foliage_path() -> None:
    # one 2.5 m plant, canopy 1 m wide, right over the antenna: a steep ray stays inside the
    # cylinder from the antenna to the top, a path of (top − antenna) / sin(elevation)
    scn = field(5)
    canopy = Canopy(scn)
    keep = np.array([0])
    for name in ("xy", "radius", "bottom", "top", "share"):
        setattr(canopy, name, getattr(canopy, name)[keep])
    canopy.radius[:] = 0.5
    canopy.share[:] = 1.0
    canopy.top[:] = canopy.bottom[0] + 2.0
    canopy.max_top, canopy.max_radius = float(canopy.top[0]), 0.5
    from scipy.spatial import cKDTree

    canopy.tree = cKDTree(canopy.xy)
    cfg = GnssFixConfig()
    sky = SkyModel(cfg, canopy)
    ant = np.array([*canopy.xy[0], canopy.bottom[0] + 0.5])
    a = sky.attenuation(ant)
    el = math.atan(sky.tan_el[-1])  # the steepest band
    expect = cfg.foliage_db_per_m * (canopy.top[0] - ant[2]) / math.sin(el)
    assert a[:, -1] == pytest.approx(expect, rel=1e-9)


def test_mean_time_to_fix_is_the_configured_dwell() -> None:
    cfg = GnssFixConfig()
    rng = np.random.default_rng(0)
    waits = []
    for _ in range(1000):
        chain = FixModeChain(cfg, "rtk_fixed", 0.1)
        chain.level = LEVELS.index("rtk_float")
        n = 1
        while chain.step(1.0, 1.0, rng) != "rtk_fixed":
            n += 1
        waits.append(n * 0.1)
    # geometric in epochs: mean epoch / (1 − e^(−epoch/τ)) ≈ τ + epoch/2
    assert np.mean(waits) == pytest.approx(cfg.acquire_fixed_s + 0.05, rel=0.08)


def _drive_in(seed: int) -> tuple[list[str], np.ndarray]:
    """A receiver carried from the headland into mature maize along a lane at 0.5 m/s."""
    scn = field(5)
    g = Gnss(GnssConfig(), 0.05)
    g.set_canopy(Canopy(scn))
    ant = lane_antenna(scn)
    # along the row direction, from outside the field towards its centre
    d = np.array([math.cos(scn.rows.angle), math.sin(scn.rows.angle), 0.0])
    start = ant - 12.0 * d
    rng = np.random.default_rng(seed)
    g.reset(start, rng)
    modes, readings = [], []
    for k in range(1, 401):
        g.step(start + 0.025 * k * d, rng, 0.05)
        modes.append(g.mode)
        readings.append(g.reading.copy())
    return modes, np.asarray(readings)


def test_fix_modes_are_deterministic_per_seed() -> None:
    a, b, c = _drive_in(1), _drive_in(1), _drive_in(2)
    assert a[0] == b[0] and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[1], c[1])
    assert a[0][0] == "rtk_fixed" and a[0][-1] != "rtk_fixed"  # open headland, then canopy


def test_a_fix_arrives_one_latency_after_its_epoch() -> None:
    cfg = GnssConfig(latency_s=0.1, fix=GnssFixConfig(model="constant"))
    g = Gnss(cfg, 0.05)
    rng = np.random.default_rng(0)
    v = np.array([1.0, 0.0, 0.0])
    g.reset(np.zeros(3), rng)
    arrivals = []
    for k in range(1, 201):
        g.step(v * 0.05 * k, rng, 0.05)
        if g.updated:
            arrivals.append((k, g.age, g.reading[0] - v[0] * 0.05 * k))
    ks, ages, lag = (np.array(x) for x in zip(*arrivals, strict=True))
    assert np.allclose(ages, 0.1) and np.all(np.diff(ks) == 2)  # 10 Hz, 0.1 s old
    sigma = error_sigma(cfg)[0]
    # the reading is the antenna where it was a latency ago: 0.1 m behind at 1 m/s
    assert np.mean(lag) == pytest.approx(-0.1, abs=4 * sigma)


def test_no_fix_holds_the_last_reading() -> None:
    g = Gnss(GnssConfig(), 0.05)
    rng = np.random.default_rng(0)
    g.reset(np.ones(3), rng)
    held = g.reading.copy()
    for _ in range(10):  # open sky, the antenna moved 5 m
        g.step(np.ones(3) + 5.0, rng, 0.05)
    assert g.mode == "rtk_fixed" and np.abs(g.reading - 6.0).max() < 0.05
    g.usable_sky = lambda antenna: (0.0, 0.0)  # type: ignore[method-assign]  # a closed sky
    modes = []
    for _ in range(100):
        g.step(np.ones(3) + 5.0, rng, 0.05)
        modes.append(g.mode)
    assert modes[-1] == "none"
    k = modes.index("none")
    assert modes[k:] == ["none"] * (100 - k)
    assert not g.updated and g.age > 1.0
    assert np.abs(g.reading - 6.0).max() < 0.05  # the last fix before the loss
    assert not np.array_equal(g.reading, held)


@pytest.mark.parametrize("stage,fixed", [(1, True), (5, False)])
def test_env_reports_the_canopy_fix_mode(stage: int, fixed: bool) -> None:
    env = make(
        scenario_overrides={
            **TINY,
            "layout": {"headland": 2.0, "row_spacing": 1.0},
            "crop": {"stage": stage},
        },
        config={"task": {"corridor": 5.0, "max_crops_hit": 10**6}},
    )
    try:
        env.reset(seed=0, options={"lane": 2})
        modes = []
        for _ in range(100):  # 3 m into the lane
            _, _, term, _, info = env.step(np.array([0.7, 0.0], np.float32))
            modes.append(info["localisation"]["gnss_mode"])
            assert not term
        assert (modes[-1] == "rtk_fixed") == fixed
    finally:
        env.close()
