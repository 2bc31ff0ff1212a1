import math

import numpy as np
import pytest

from agrinav_gym.metrics import cross_track_metrics, project_to_polyline


def test_metrics_on_a_straight_path_by_hand() -> None:
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    poses = np.array([[1.0, 0.1], [2.0, -0.2], [3.0, 0.3], [4.0, 0.0]])
    m = cross_track_metrics(poses, path)
    assert m["rmse"] == pytest.approx(math.sqrt((0.01 + 0.04 + 0.09) / 4))
    assert m["mae"] == pytest.approx(0.6 / 4)
    assert m["max"] == pytest.approx(0.3)
    assert m["completion"] == pytest.approx(40.0)
    _, _, _, signed = project_to_polyline(poses, path)
    np.testing.assert_allclose(signed, [0.1, -0.2, 0.3, 0.0])  # left of the path is positive


def test_nearest_segment_and_furrow_headland_split() -> None:
    # an L: furrow along x, then a headland leg along y
    path = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
    labels = np.array(["furrow", "furrow", "headland"])
    poses = np.array([[1.0, 0.2], [3.0, -0.1], [4.3, 2.0], [3.8, 1.0], [5.0, -1.0]])
    m = cross_track_metrics(poses, path, labels, crops_hit=2)
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


def test_chunking_does_not_change_results() -> None:
    rng = np.random.default_rng(0)
    path = np.cumsum(rng.normal(size=(300, 2)), axis=0)
    pts = rng.normal(size=(5000, 2)) * 5
    a = project_to_polyline(pts, path, chunk=97)
    b = project_to_polyline(pts, path, chunk=10000)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_route_lookup_interpolates_and_continues_past_the_end() -> None:
    from agrinav_gym.tasks import RoutePath

    xy = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.03]])  # 2.03 m: not a multiple of the table step
    route = RoutePath.from_points(xy, np.zeros(3), np.array([True, True, False]))
    pts, tags = route.lookup(np.array([0.5, 1.5, 2.03, 2.43, 2.83]))
    np.testing.assert_allclose(
        pts, [[0.5, 0.0], [1.0, 0.5], [1.0, 1.03], [1.0, 1.43], [1.0, 1.83]], atol=1e-9
    )
    assert tags[0] and not tags[-1]
