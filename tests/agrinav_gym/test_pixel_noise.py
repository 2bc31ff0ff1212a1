"""The stereo noise's per-pixel draws (render/pixel_noise.py): a standard normal, the kernels'
and the numpy twin's bits alike, one rng draw a frame whatever the scene."""

import math

import numpy as np
import pytest
from scipy import stats

from agrinav_gym.render import native, pixel_noise
from scenario_gen import generate, preset

from .helpers import TINY, lane_pose, make_camera, mesh_camera

N = 1_000_000


@pytest.fixture(scope="module")
def draws() -> np.ndarray:
    return pixel_noise.normals(0x5EED, N)


def test_the_tables_close_the_ziggurat() -> None:
    """256 layers of equal area: the top layer's rectangle holds the same area as the base
    layer (rectangle plus the tail beyond r), to the rounding of the recursion."""
    x, f = pixel_noise._X, pixel_noise._F
    area = x[0] * f[1]
    assert x[255] * (1.0 - f[255]) == pytest.approx(area, rel=1e-9)
    assert (np.diff(x[1:]) < 0).all() and x[256] == 0.0


def test_draws_are_standard_normal(draws: np.ndarray) -> None:
    """Moments within 5 standard errors, Kolmogorov–Smirnov at the 0.1 % level, and the tail
    beyond the base layer's edge r (the exponential method's region) at its Gaussian mass."""
    n = len(draws)
    assert abs(draws.mean()) < 5 / math.sqrt(n)
    assert abs(draws.var() - 1.0) < 5 * math.sqrt(2 / n)
    assert abs(stats.skew(draws)) < 5 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(draws)) < 5 * math.sqrt(24 / n)
    assert stats.kstest(draws, "norm").pvalue > 1e-3
    p = math.erfc(pixel_noise.R / math.sqrt(2))
    beyond = (np.abs(draws) > pixel_noise.R).sum()
    assert abs(beyond - n * p) < 5 * math.sqrt(n * p)


def test_neighbouring_pixels_and_frames_are_uncorrelated(draws: np.ndarray) -> None:
    """A row's neighbours, a column's (848 pixels apart) and the same pixel in the next frame
    (the next key from the rng): |ρ| within 5 standard errors of 0."""
    lim = 5 / math.sqrt(N)
    for lag in (1, 848):
        assert abs(np.corrcoef(draws[:-lag], draws[lag:])[0, 1]) < lim
    rng = np.random.default_rng(1)
    a, b = (pixel_noise.normals(pixel_noise.frame_key(rng), N) for _ in range(2))
    assert abs(np.corrcoef(a, b)[0, 1]) < lim


@pytest.mark.skipif(not native.available(), reason="compiled kernels not built")
@pytest.mark.parametrize("key", [0, 1, 0x5EED, 2**64 - 1])
def test_the_kernels_and_the_numpy_twin_give_the_same_bits(key: int) -> None:
    """Exact: the fast path is one integer-to-double conversion and one product, the slow path
    the same C library's exp and log."""
    a = pixel_noise.normals(key, 200_000)
    b = pixel_noise.normals_numpy(key, 200_000)
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64))


def test_a_pixels_draw_depends_on_the_key_and_its_index_only() -> None:
    """Pixels 5..9 of a long frame are those of a short one: no order, no buffer."""
    assert np.array_equal(pixel_noise.normals(9, 10)[5:], pixel_noise.normals(9, 1000)[5:10])
    assert not np.array_equal(pixel_noise.normals(9, 10), pixel_noise.normals(10, 10))


@pytest.mark.parametrize("renderer", ["raster", "raycast", "proxy"])
def test_a_frame_takes_one_draw_from_the_rng_whatever_the_scene(renderer: str) -> None:
    """The rng's state after a noisy frame is that after one key, among seedlings as among
    tall maize, at 64 × 48 as at 32 × 24: what the episode's other sensors draw next depends
    neither on what the camera saw nor on its resolution."""
    from agrinav_gym.render.mesh_scene import MeshScene
    from agrinav_gym.render.proxy_plants import PlantField

    if renderer == "raster" and not native.available():
        pytest.skip("the rasteriser needs the compiled kernels")
    after, valid = [], []
    for stage, (w, h) in ((1, (64, 48)), (5, (32, 24))):
        scn = generate(preset("default", **{**TINY, "crop": {"stage": stage}}), 0)
        rng = np.random.default_rng(4)
        rot, pos = lane_pose(scn)
        if renderer == "proxy":
            cam = make_camera(None, {"width": w, "height": h})
            frame = cam.draw(rot, pos, scn.terrain, PlantField.from_scenario(scn), rng)
        else:
            cam = mesh_camera(w, h, renderer)
            frame = cam.draw(rot, pos, MeshScene.from_scenario(scn), rng)
        valid.append(int((frame.depth > 0).sum()))
        after.append(rng.bit_generator.state)
    assert min(valid) > 0 and valid[0] != valid[1]  # the noise touched different pixels
    ref = np.random.default_rng(4)
    pixel_noise.frame_key(ref)
    assert after[0] == after[1] == ref.bit_generator.state
