"""Receiver faults under canopy (sensors/gnss_faults, sensors/fixmode): multipath jumps, false
fixes, re-fix time with the visible sky, the mode across the row — their statistics over long
seeded runs against their parameters."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import scenario_gen as sg
from agrinav_gym.config import GnssConfig, GnssFixConfig
from agrinav_gym.interface import GNSS_RTK_FIXED, GNSS_RTK_FLOAT, GNSS_STANDALONE
from agrinav_gym.sensors.fixmode import LEVELS, Canopy, FixModeChain, SkyModel
from agrinav_gym.sensors.gnss import Gnss, error_sigma
from agrinav_gym.sensors.gnss_faults import FALSE_FIX, JUMP, ReceiverFaults

from .test_fixmode import ANTENNA_AGL

EPOCH = 0.1
FLOAT, FIXED = LEVELS.index(GNSS_RTK_FLOAT), LEVELS.index(GNSS_RTK_FIXED)


def run_faults(
    cfg: GnssFixConfig, best: str, q: float, epochs: int, seed: int
) -> tuple[FixModeChain, ReceiverFaults, list[tuple[int, str | None, np.ndarray]]]:
    """The mode chain and the faults stepped together at a constant sky ``q`` (carrier)."""
    chain = FixModeChain(cfg, best, EPOCH)
    faults = ReceiverFaults(cfg, EPOCH)
    rng = np.random.default_rng(seed)
    chain.reset(q, 1.0)
    faults.reset(rng)
    trace = []
    for _ in range(epochs):
        before = chain.level
        chain.step(q, 1.0, rng)
        off = faults.step(before, chain, q)
        trace.append((chain.level, faults.kind, off.copy()))
    return chain, faults, trace


def episodes(trace: list[tuple[int, str | None, np.ndarray]], kind: str) -> list[np.ndarray]:
    """The offsets of each run of consecutive epochs in a fault of ``kind`` (one per fault)."""
    out: list[list[np.ndarray]] = []
    prev = None
    for _, k, off in trace:
        if k == kind:
            if prev is None or not np.array_equal(off, prev):
                out.append([])
            out[-1].append(off)
            prev = off
        else:
            prev = None
    return [np.asarray(e) for e in out]


def test_multipath_jumps_follow_their_rate_size_and_duration() -> None:
    cfg = GnssFixConfig(jump_rate_hz=0.1, jump_float_m=0.5, jump_duration_s=2.0)
    q = 0.3  # float's sky: 70 % of it through foliage
    _, faults, trace = run_faults(cfg, GNSS_RTK_FLOAT, q, 200_000, seed=0)
    jumps = episodes(trace, JUMP)
    assert faults.started[JUMP] == len(jumps) > 1000
    free = sum(1 for _, k, _ in trace if k is None)
    p_start = 1.0 - math.exp(-EPOCH * cfg.jump_rate_hz * (1.0 - q))
    assert len(jumps) / free == pytest.approx(p_start, rel=0.08)
    # horizontal size: east and north normal, RMS jump_float_m (±3 % at ~1,200 jumps)
    first = np.array([j[0] for j in jumps])
    assert np.sqrt(np.mean(np.sum(first[:, :2] ** 2, axis=1))) == pytest.approx(0.5, rel=0.06)
    assert np.all(first[:, 2] == 0.0)
    # duration: a constant hazard per epoch, mean ≈ jump_duration_s
    p_end = 1.0 - math.exp(-EPOCH / cfg.jump_duration_s)
    mean = np.mean([len(j) for j in jumps]) * EPOCH
    assert mean == pytest.approx(EPOCH / p_end, rel=0.08)


def test_jumps_scale_with_the_foliage_covered_sky_and_are_off_by_default() -> None:
    cfg = GnssFixConfig(jump_rate_hz=0.2)
    counts = [run_faults(cfg, GNSS_RTK_FLOAT, q, 50_000, 1)[1].started[JUMP] for q in (0.3, 0.65)]
    assert counts[1] / counts[0] == pytest.approx(0.35 / 0.7, rel=0.15)
    assert run_faults(cfg, GNSS_RTK_FLOAT, 1.0, 20_000, 1)[1].started[JUMP] == 0  # open sky
    assert not GnssFixConfig().faults and Gnss(GnssConfig(), 0.05).faults is None


def test_standalone_jumps_take_their_own_size() -> None:
    cfg = GnssFixConfig(jump_rate_hz=0.2, jump_standalone_m=3.0, jump_float_m=0.1)
    _, _, trace = run_faults(cfg, GNSS_STANDALONE, 0.2, 100_000, seed=2)
    first = np.array([j[0] for j in episodes(trace, JUMP)])
    assert np.sqrt(np.mean(np.sum(first**2, axis=1))) == pytest.approx(3.0, rel=0.08)


def test_false_fixes_follow_their_probability_size_and_detection_time() -> None:
    # fixes come and go quickly (1 s to fix, slips every ~3 s) so that a long run has many
    cfg = GnssFixConfig(
        acquire_fixed_s=1.0,
        multipath_mtbf_s=5.0,
        false_fix_prob=0.3,
        false_fix_m=0.4,
        false_fix_duration_s=5.0,
    )
    q = 0.6
    _, faults, trace = run_faults(cfg, GNSS_RTK_FIXED, q, 150_000, seed=3)
    wrong = episodes(trace, FALSE_FIX)
    assert faults.fixes > 1000 and faults.started[FALSE_FIX] == len(wrong)
    p = cfg.false_fix_prob * (1.0 - q) / (1.0 - cfg.fixed_sky)  # 0.24
    assert len(wrong) / faults.fixes == pytest.approx(p, abs=0.03)
    first = np.array([w[0] for w in wrong])
    assert np.sqrt(np.mean(np.sum(first**2, axis=1))) == pytest.approx(0.4, rel=0.08)
    # reported as fixed all along; the receiver catches it after ≈ false_fix_duration_s,
    # unless a slip (mean multipath_mtbf_s × q = 3 s here) drops it to float first
    assert all(level == FIXED for level, k, _ in trace if k == FALSE_FIX)
    hazard = (1.0 - math.exp(-EPOCH / 5.0)) + (1.0 - math.exp(-EPOCH / (5.0 * q)))
    assert np.mean([len(w) for w in wrong]) * EPOCH == pytest.approx(EPOCH / hazard, rel=0.1)


def test_no_false_fix_under_open_sky() -> None:
    cfg = GnssFixConfig(acquire_fixed_s=1.0, multipath_mtbf_s=5.0, false_fix_prob=1.0)
    _, faults, _ = run_faults(cfg, GNSS_RTK_FIXED, 1.0, 30_000, seed=4)
    assert faults.fixes > 100 and faults.started[FALSE_FIX] == 0


def _receiver(fix: GnssFixConfig, q: float, best: str = GNSS_RTK_FIXED) -> Gnss:
    g = Gnss(GnssConfig(mode=best, fix=fix, latency_s=0.0), 0.05)
    g.usable_sky = lambda antenna: (q, 1.0)  # type: ignore[method-assign]
    return g


def test_a_false_fix_is_reported_fixed_with_an_optimistic_accuracy() -> None:
    fix = GnssFixConfig(
        acquire_fixed_s=1.0, multipath_mtbf_s=5.0, false_fix_prob=1.0, false_fix_m=0.5
    )
    g = _receiver(fix, 0.5)  # the sky just supports fixed: every ambiguity fix is wrong
    rng = np.random.default_rng(5)
    truth = np.array([10.0, 20.0, 1.0])
    g.reset(truth, rng)
    err_wrong, err_right = [], []
    for _ in range(40_000):
        g.step(truth, rng, 0.05)
        if g.updated and g.mode == GNSS_RTK_FIXED:
            assert np.array_equal(g.sigma, error_sigma(g.cfg, GNSS_RTK_FIXED))
            e = float(np.hypot(*(g.reading[:2] - truth[:2])))
            assert g.faults is not None
            (err_wrong if g.faults.kind == FALSE_FIX else err_right).append(e)
    # the start is a right fix (converged before the episode); every later one is wrong
    assert len(err_wrong) > 10 * len(err_right) > 0
    sigma = float(error_sigma(g.cfg, GNSS_RTK_FIXED)[0])
    assert np.sqrt(np.mean(np.square(err_wrong))) > 20 * sigma  # ≈ 0.5 m, reported ≈ 1 cm


def test_faults_are_deterministic_per_seed_and_leave_the_main_draws_alone() -> None:
    fix = GnssFixConfig(jump_rate_hz=1.0, false_fix_prob=0.5, acquire_fixed_s=1.0)

    def drive(cfg: GnssFixConfig, seed: int) -> tuple[np.ndarray, float]:
        g = _receiver(cfg, 0.3, GNSS_RTK_FLOAT)
        rng = np.random.default_rng(seed)
        g.reset(np.zeros(3), rng)
        out = []
        for k in range(2000):
            g.step(np.array([0.01 * k, 0.0, 0.0]), rng, 0.05)
            out.append(g.reading.copy())
        return np.asarray(out), float(rng.random())

    a, b, c = drive(fix, 6), drive(fix, 6), drive(fix, 7)
    assert np.array_equal(a[0], b[0]) and not np.array_equal(a[0], c[0])
    # the faults draw from their own stream: the receiver's own draws are those it makes
    # without them (the jumps are the only difference)
    off = drive(GnssFixConfig(acquire_fixed_s=1.0), 6)
    assert a[1] == off[1]
    assert not np.array_equal(a[0], off[0])


@pytest.mark.parametrize("k", [1.0, 2.0])
def test_refix_time_grows_as_the_clean_sky_shrinks(k: float) -> None:
    cfg = GnssFixConfig(refix_sky_exponent=k)
    rng = np.random.default_rng(8)
    q = 0.6
    waits = []
    for _ in range(600):
        chain = FixModeChain(cfg, GNSS_RTK_FIXED, EPOCH)
        chain.level = FLOAT
        n = 1
        while chain.step(q, 1.0, rng) != GNSS_RTK_FIXED:
            n += 1
        waits.append(n * EPOCH)
    expect = cfg.acquire_fixed_s / q**k + EPOCH / 2
    assert np.mean(waits) == pytest.approx(expect, rel=0.1)


def test_refix_time_is_the_configured_dwell_by_default() -> None:
    chain = FixModeChain(GnssFixConfig(), GNSS_RTK_FIXED, EPOCH)
    assert chain._p_up(FLOAT, 0.5) == chain._p_up(FLOAT, 1.0) == chain.p_up[FLOAT]


def _v10_field() -> sg.Scenario:
    spec = sg.preset(
        "default", crop={"stage": 3}, field={"width": 12.0, "length": 20.0}
    )  # V10, 1.2 m tall, 0.8 m wide canopies in 1 m rows: a gap over each lane
    return sg.generate(spec, 0)


def _across(scn: sg.Scenario, frac: float) -> np.ndarray:
    """The antenna ``frac`` of the way from one row to the next near the field's middle."""
    r = scn.rows
    mid = len(r.offsets) // 2
    s = r.offsets[mid - 1] + frac * (r.offsets[mid] - r.offsets[mid - 1])
    t = 0.5 * (r.starts.min() + r.ends.max())
    x, y = r.to_enu(np.array([t]), np.array([s]))
    return np.array([x[0], y[0], float(scn.terrain.height_at(x[0], y[0])) + ANTENNA_AGL])


#: a heavy foliage loss, so that the mechanism shows at V10 (at 2 dB/m the lane's sky and the
#: row's differ by a few per cent)
FIX_ACROSS = GnssFixConfig(foliage_db_per_m=6.0, foliage_profile="stalk", across_row_update_m=0.05)


def test_the_fix_mode_follows_the_antenna_across_the_row() -> None:
    scn = _v10_field()
    canopy = Canopy(scn)
    sky = SkyModel(FIX_ACROSS, canopy)
    # the lane centre sees the sky through the gap between the canopies, a row does not
    q_lane = sky.usable(_across(scn, 0.5))[0]
    q_row = sky.usable(_across(scn, 0.0))[0]
    assert q_lane >= FIX_ACROSS.fixed_sky > FIX_ACROSS.float_sky > q_row
    share = {}
    for frac in (0.0, 0.5):
        g = Gnss(GnssConfig(fix=FIX_ACROSS), 0.05)
        g.set_canopy(canopy)
        rng = np.random.default_rng(9)
        ant = _across(scn, frac)
        g.reset(ant, rng)
        modes = []
        for _ in range(4000):
            g.step(ant, rng, 0.05)
            modes.append(g.mode)
        share[frac] = modes.count(GNSS_RTK_FIXED) / len(modes)
    assert share[0.5] > 0.8 and share[0.0] == 0.0


def test_across_row_updates_follow_small_moves_that_update_m_ignores() -> None:
    scn = _v10_field()
    canopy = Canopy(scn)
    start, end = _across(scn, 0.5), _across(scn, 0.1)
    stale = []
    for cfg in (replace(FIX_ACROSS, across_row_update_m=None), FIX_ACROSS):
        g = Gnss(GnssConfig(fix=cfg), 0.05)
        g.set_canopy(canopy)
        assert g.sky is not None
        worst = 0.0
        for f in np.linspace(0.0, 1.0, 21):  # 2 cm steps across the row towards the row
            ant = start + f * (end - start)
            q = g.usable_sky(ant)[0]
            worst = max(worst, abs(q - g.sky.usable(ant)[0]))
        stale.append(worst)
    assert stale[0] > 0.1  # update_m (0.5 m) keeps the lane centre's sky the whole way
    assert stale[1] < 0.5 * stale[0]


def test_randomize_draws_the_receiver_under_canopy_per_reset() -> None:
    from .helpers import make

    env = make(
        randomize={
            "gnss.fix.foliage_db_per_m": [0.4, 1.5],
            "gnss.fix.jump_rate_hz": [0.0, 0.2],
            "gnss.mode": {"choices": [GNSS_RTK_FIXED, GNSS_STANDALONE]},
        },
        config={"gnss": {"fix": {"false_fix_prob": 0.1}}},
    )
    try:
        seen = set()
        for i in range(6):
            env.reset(seed=i)
            cfg = env.unwrapped.sensors.gnss.cfg
            assert 0.4 <= cfg.fix.foliage_db_per_m <= 1.5 and 0.0 <= cfg.fix.jump_rate_hz <= 0.2
            assert cfg.fix.false_fix_prob == 0.1  # the config's value where not randomized
            seen.add(round(cfg.fix.foliage_db_per_m, 6))
            assert "+ faults" in env.unwrapped.conditions()["localisation"]
            env.step(np.array([0.5, 0.0], np.float32))
        assert len(seen) == 6
    finally:
        env.close()


def test_randomize_draws_the_open_sky_slip_interval_per_reset() -> None:
    """The one receiver value no study gives (open-sky multipath slips) is drawn per reset like
    the others, reaches the fix-mode chain, and the rollout's conditions name it."""
    from .helpers import make

    env = make(randomize={"gnss.fix.multipath_mtbf_s": {"choices": [40.0, 600.0]}})
    try:
        seen = set()
        for i in range(8):
            env.reset(seed=i)
            gnss = env.unwrapped.sensors.gnss
            mtbf = gnss.cfg.fix.multipath_mtbf_s
            assert mtbf in (40.0, 600.0) and gnss.chain.cfg.multipath_mtbf_s == mtbf
            label = env.unwrapped.conditions()["localisation"]
            assert ("multipath MTBF 40 s" in label) == (mtbf == 40.0)
            seen.add(mtbf)
        assert seen == {40.0, 600.0}
    finally:
        env.close()
