"""The analytic proxy against the mesh camera, with the tolerances its fit states."""

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from agrinav_gym.render.proxy_params import (
    COLUMNS,
    ProxyParams,
    fit_residuals,
    fitted,
    parse_table,
    proxy_params,
)
from agrinav_gym.tools.proxy_fit import Comparison, FitResult, lane_width, table_document
from scenario_gen import CATALOG
from scenario_gen.errors import InputError

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
    [(n, s) for n in fitted() for s in range(1, CATALOG[n].stages + 1)],
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
    table = fitted()["corn"]
    mid = 0.5 * (table[1, 0] + table[2, 0])
    fill, _, reach = proxy_params("corn", mid)
    assert fill == pytest.approx(0.5 * (table[1, 1] + table[2, 1]))
    assert reach == pytest.approx(0.5 * (table[1, 3] + table[2, 3]))
    assert all(t.shape[1] == 8 for t in fitted().values())


def test_every_catalog_species_has_fitted_parameters() -> None:
    assert set(fitted()) == set(CATALOG)


def test_the_written_table_is_what_the_runtime_reads() -> None:
    rows = [
        (0.0, FitResult(ProxyParams(0.1, 1.0, 0.0), (0.01, 0.001), (0.0, 0.0), 0.2)),
        (1.0, FitResult(ProxyParams(0.3, 0.5, 1.2), (0.02, 0.002), (0.05, 0.01), 0.3)),
    ]
    doc = table_document({"corn": rows})
    t = parse_table(doc)["corn"]
    assert t[1].tolist() == [1.0, 0.3, 0.5, 1.2, 0.02, 0.002, 0.05, 0.01]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(columns=["growth"]), "columns: got"),
        (lambda d: d["species"]["corn"].reverse(), "rising from 0 to 1"),
        (lambda d: d["species"]["corn"][0].pop(), "rows of 8 finite numbers"),
        (lambda d: d.update(species={}), "a mapping of species to rows"),
    ],
)
def test_a_malformed_table_is_refused_naming_what_is_wrong(
    edit: Callable[[dict[str, Any]], None], message: str
) -> None:
    rows = [[0, 0.1, 1, 0, 0, 0, 0, 0], [1, 0.2, 1, 0, 0, 0, 0, 0]]
    doc = {"columns": list(COLUMNS), "species": {"corn": rows}}
    edit(doc)
    with pytest.raises(InputError, match=message):
        parse_table(doc)


def test_a_species_without_a_fit_is_named() -> None:
    with pytest.raises(InputError, match="got 'lettuce'; fitted: cabbage, corn"):
        proxy_params("lettuce", 0.5)


def test_lane_width_of_an_open_lane_and_of_two_walls() -> None:
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.robot import RobotGeometry, robot_interface

    cfg = EnvConfig.from_dict({"camera": {"width": 128, "height": 96}})
    m = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    rays = m.pixel_rays() @ m.rotation.T
    # walls at y = ±0.4 m from base_link: depth where the ray meets them (z-depth: x_cam = 1)
    y = rays[:, 1]
    z = np.where(np.abs(y) > 1e-9, 0.4 / np.maximum(np.abs(y), 1e-9), 0.0)
    z = np.where((z * rays[:, 0] < 6.0), z, 0.0).reshape(m.height, m.width).astype(np.float32)
    assert lane_width(z, m) == pytest.approx(0.8, abs=0.02)
    assert lane_width(np.zeros_like(z), m) == 2.0  # nothing seen: both sides capped at 1 m
