import math

import gymnasium as gym
import numpy as np
import pytest

from agrinav_gym.metrics import EpisodeMetrics, RouteProjector, planted_lane_rmse
from agrinav_gym.routes import RoutePath

from .helpers import TINY


def _brute(points: np.ndarray, path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Independent point-to-segment distances: every point against every segment."""
    a, b = path[:-1], path[1:]
    ab = b - a
    p = points[:, None, :]
    u = np.clip(((p - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-18), 0, 1)
    d = np.linalg.norm(p - (a + u[..., None] * ab), axis=-1)
    return d.min(axis=1), d.argmin(axis=1)


def _brute_each(points: np.ndarray, path: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, None]:
    """Distance of each point to its own segment k."""
    a, b = path[k], path[k + 1]
    ab = b - a
    u = np.clip(((points - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-18), 0, 1)
    return np.linalg.norm(points - (a + u[:, None] * ab), axis=-1), None


def _metrics(path: np.ndarray, furrow: np.ndarray, poses: np.ndarray) -> dict:
    m = EpisodeMetrics(path, furrow)
    for x, y in poses:
        _, _, s = m.route.project(x, y)
        m.update(x, y, s)
    return m.result(crops_hit=2)


def test_metrics_on_a_straight_path_by_hand() -> None:
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    poses = np.array([[1.0, 0.1], [2.0, -0.2], [3.0, 0.3], [4.0, 0.0]])
    m = _metrics(path, np.array([True, True]), poses)
    assert m["rmse"] == pytest.approx(math.sqrt((0.01 + 0.04 + 0.09) / 4))
    assert m["mae"] == pytest.approx(0.6 / 4)
    assert m["max"] == pytest.approx(0.3)
    assert m["completion"] == pytest.approx(40.0)
    assert m["headland_rmse"] is None and m["poses"] == 4


def test_path_weighted_rmse_by_hand_ignores_standing_still() -> None:
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    stall = [[2.0, 0.3]] * 10  # stopped 0.3 m off the line for ten more steps
    poses = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.3], *stall])
    m = _metrics(path, np.array([True, True]), poses)
    assert m["rmse"] == pytest.approx(math.sqrt(0.09 * 11 / 13))  # time-weighted: the stall counts
    ds2 = math.hypot(1.0, 0.3)
    # trapezoid over the two driven pieces: (0 + 0) / 2 · 1 m, then (0 + 0.09) / 2 · ds2
    assert m["path_rmse"] == pytest.approx(math.sqrt(0.045 * ds2 / (1.0 + ds2)))
    assert m["path_in_furrow_rmse"] == pytest.approx(m["path_rmse"])
    assert m["path_headland_rmse"] is None and m["driven_m"] == pytest.approx(1.0 + ds2)
    one = _metrics(path, np.array([True, True]), poses[:1])
    assert one["path_rmse"] is None and one["rmse"] == 0.0  # no path driven: nothing to weigh


def test_nearest_segment_and_furrow_headland_split() -> None:
    # an L: furrow along x, then a headland leg along y
    path = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
    furrow = np.array([True, True, False])
    poses = np.array([[1.0, 0.2], [3.0, -0.1], [4.3, 2.0], [3.8, 1.0], [5.0, -1.0]])
    m = _metrics(path, furrow, poses)
    # distances: 0.2, 0.1, 0.3 (headland leg), 0.2 (headland leg), √2 to the corner (4, 0)
    d = np.array([0.2, 0.1, 0.3, 0.2, math.sqrt(2)])
    assert m["rmse"] == pytest.approx(math.sqrt(np.mean(d**2)))
    # the corner is the end of the furrow segment (it is nearer than the headland leg's start)
    assert m["in_furrow_rmse"] == pytest.approx(
        math.sqrt(np.mean(np.array([0.2, 0.1, 2**0.5]) ** 2))
    )
    assert m["headland_rmse"] == pytest.approx(math.sqrt((0.09 + 0.04) / 2))
    assert m["crops_hit"] == 2 and m["max"] == pytest.approx(math.sqrt(2))
    assert m["completion"] == pytest.approx(100 * 6.0 / 7.0)


def test_projector_is_exact_on_a_random_polyline() -> None:
    rng = np.random.default_rng(0)
    path = np.cumsum(rng.normal(size=(300, 2)), axis=0)
    pts = rng.normal(size=(2000, 2)) * 8
    proj = RouteProjector(path, np.ones(len(path), bool))
    want, _ = _brute(pts, path)
    for slack in (None, 0.0, 3.0, 50.0):  # vertex bound, exact, loose (vectorised), KD-tree
        got = [
            proj.project(x, y, None if slack is None else w + slack)
            for (x, y), w in zip(pts, want, strict=True)
        ]
        np.testing.assert_allclose([g[0] for g in got], want, rtol=0, atol=1e-12)
        # the reported segment holds the nearest point (at a shared vertex either one does)
        k = np.array([g[1] for g in got])
        own, _ = _brute_each(pts, path, k)
        np.testing.assert_allclose(own, want, rtol=0, atol=1e-12)


def test_field_route_episode_matches_independent_computation() -> None:
    """A whole FieldRoute episode with a headland U-turn, driven by pure pursuit: the env's
    running metrics equal a brute-force nearest-segment computation over its pose log."""
    from policies import make_policy

    env = gym.make("AgriNav/FieldRoute-v3", scenario_overrides=TINY, observations=["odom", "route"])
    try:
        pi = make_policy("rpp", env)
        obs, _ = env.reset(seed=3)
        pi.reset()
        while True:
            obs, _, term, trunc, info = env.step(pi.act(obs))
            if term or trunc:
                break
        u = env.unwrapped
        poses, route = u.trajectory, u.route
    finally:
        env.close()
    assert (~route.furrow).any() and info["metrics"]["headland_rmse"] is not None
    d, seg = _brute(poses, route.xy)
    in_furrow = (route.furrow[:-1] & route.furrow[1:])[seg]
    m = info["metrics"]
    assert m["poses"] == len(poses)
    assert m["rmse"] == pytest.approx(math.sqrt(np.mean(d**2)), rel=1e-12)
    assert m["mae"] == pytest.approx(np.mean(d), rel=1e-12)
    assert m["max"] == pytest.approx(d.max(), rel=1e-12)
    assert m["in_furrow_rmse"] == pytest.approx(math.sqrt(np.mean(d[in_furrow] ** 2)), rel=1e-12)
    assert m["headland_rmse"] == pytest.approx(math.sqrt(np.mean(d[~in_furrow] ** 2)), rel=1e-12)


def test_route_lookup_interpolates_and_continues_past_the_end() -> None:
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.03]])  # 2.03 m: not a multiple of the table step
    route = RoutePath.from_points(xy, np.zeros(3), np.array([True, True, False]))
    pts, tags = route.lookup(np.array([0.5, 1.5, 2.03, 2.43, 2.83]))
    np.testing.assert_allclose(
        pts, [[0.5, 0.0], [1.0, 0.5], [1.0, 1.03], [1.0, 1.43], [1.0, 1.83]], atol=1e-9
    )
    assert tags[0] and not tags[-1]


def test_planted_lane_rmse_by_hand() -> None:
    """From the lanes as planted, path-weighted: poses along a drifted lane's planted centre
    score 0 (the logged line would not), a steady 5 cm aside 5 cm, standing still adds nothing,
    and the headland beyond the rows' ends is not in a lane."""
    import scenario_gen as sg
    from scenario_gen.drift import planted_offset
    from scenario_gen.generate import planting_drift

    scn = sg.generate(
        sg.preset(
            "default",
            field={"width": 12.0, "length": 40.0},
            layout={"drift_amplitude": 0.2, "drift_pass_rows": 1, "jitter_lateral": 0.0},
        ),
        3,
    )
    rows, phases = scn.rows, planting_drift(scn)
    k = np.full(200, 2)
    t = np.linspace(rows.starts[2] + 0.5, rows.ends[2] - 0.5, 200)
    centre = 0.5 * (
        planted_offset(rows, phases, scn.spec.layout, k, t)
        + planted_offset(rows, phases, scn.spec.layout, k + 1, t)
    )

    def poses(aside: np.ndarray) -> np.ndarray:
        return np.column_stack(rows.to_enu(t, centre + aside))

    assert planted_lane_rmse(poses(np.zeros(200)), scn) == pytest.approx(0.0, abs=1e-9)
    logged = 0.5 * (rows.offsets[2] + rows.offsets[3])
    on_log = np.column_stack(rows.to_enu(t, np.full(200, logged)))
    assert planted_lane_rmse(on_log, scn) == pytest.approx(
        float(np.sqrt(np.mean((logged - centre) ** 2))), rel=0.05
    )
    assert planted_lane_rmse(poses(np.full(200, 0.05)), scn) == pytest.approx(0.05, abs=1e-9)
    # the first half 0.1 m aside, the second half on the centre, plus a long stop 0.3 m aside
    # at the end of the first half: the stop weighs nothing, the halves equal path
    aside = np.where(np.arange(200) < 100, 0.1, 0.0)
    still = poses(aside)
    stop = np.repeat(np.column_stack(rows.to_enu(t[99:100], centre[99:100] + 0.1)), 50, axis=0)
    driven = np.concatenate([still[:100], stop, still[100:]])
    assert planted_lane_rmse(driven, scn) == pytest.approx(0.1 / math.sqrt(2), rel=0.02)
    beyond = np.column_stack(rows.to_enu(np.full(5, rows.ends[2] + 2.0), centre[:5]))
    assert planted_lane_rmse(beyond, scn) is None
