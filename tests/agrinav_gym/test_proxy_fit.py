"""The analytic proxy against the mesh camera, with the tolerances its fit states."""

import math

import numpy as np
import pytest

from agrinav_gym.sim.proxy_fit import (
    FITTED,
    Comparison,
    ProxyParams,
    fit_residuals,
    lane_width,
    proxy_params,
)
from scenario_gen import CATALOG

HELD_OUT = 11  # lanes generated with another seed than the fit's


def _check(name: str, growth: float) -> None:
    dz_fit, dz_sd, dl_fit, dl_sd = fit_residuals(name, growth)
    dz, dl = Comparison(name, growth, seed=HELD_OUT).errors(None)
    n = len(dz)  # as many poses as the fit's
    # the held-out mean may exceed the fit's by at most three standard errors of the difference
    # of two means over n poses (the lane width has heavy tails: a leaf seen or not)
    for held, fit, sd in ((dz, dz_fit, dz_sd), (dl, dl_fit, dl_sd)):
        se = math.sqrt((sd**2 + held.std() ** 2) / n)
        assert held.mean() <= fit + 3 * max(se, 0.005), (held.mean(), fit, se)


@pytest.mark.parametrize(
    ("name", "stage"),
    [(n, s) for n in FITTED for s in range(1, CATALOG[n].stages + 1)],
)
def test_proxy_agrees_with_the_meshes_within_the_fit_on_held_out_lanes(
    name: str, stage: int
) -> None:
    """Per-pixel depth and the lane's visible width, every species and stage, unseen lanes."""
    _check(name, float(CATALOG[name].growth_of_stage(stage)))


def test_the_fit_beats_the_former_hand_tuned_constants() -> None:
    """Maize at 1.8 m: the fitted proxy is closer to the meshes than (0.2, 0.2, 0.9) was."""
    growth = float(CATALOG["corn"].growth_of_stage(4))
    cmp = Comparison("corn", growth, seed=HELD_OUT)
    fit = sum(e.mean() for e in cmp.errors(None))
    hand = sum(e.mean() for e in cmp.errors(ProxyParams(0.2, 0.2, 0.9)))
    assert fit < 0.8 * hand, (fit, hand)


def test_fitted_parameters_interpolate_between_stages() -> None:
    table = np.asarray(FITTED["corn"])
    mid = 0.5 * (table[1, 0] + table[2, 0])
    fill, _, reach = proxy_params("corn", mid)
    assert fill == pytest.approx(0.5 * (table[1, 1] + table[2, 1]))
    assert reach == pytest.approx(0.5 * (table[1, 3] + table[2, 3]))
    assert all(len(row) == 8 for rows in FITTED.values() for row in rows)


def test_lane_width_of_an_open_lane_and_of_two_walls() -> None:
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.env import robot_interface
    from agrinav_gym.sim.world import RobotGeometry

    cfg = EnvConfig.from_dict({"camera": {"width": 128, "height": 96}})
    m = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    rays = m.pixel_rays() @ m.rotation.T
    # walls at y = ±0.4 m from base_link: depth where the ray meets them (z-depth: x_cam = 1)
    y = rays[:, 1]
    z = np.where(np.abs(y) > 1e-9, 0.4 / np.maximum(np.abs(y), 1e-9), 0.0)
    z = np.where((z * rays[:, 0] < 6.0), z, 0.0).reshape(m.height, m.width).astype(np.float32)
    assert lane_width(z, m) == pytest.approx(0.8, abs=0.02)
    assert lane_width(np.zeros_like(z), m) == 2.0  # nothing seen: both sides capped at 1 m
