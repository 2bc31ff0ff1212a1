"""The analytic proxy against the mesh camera, with the tolerances its fit states."""

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agrinav_gym.render.proxy_params import (
    COLUMNS,
    PLANTINGS,
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


def _check(name: str, growth: float, planting: str) -> None:
    dz_fit, dz_sd, dl_fit, dl_sd = fit_residuals(name, growth, planting)
    dz, dl = Comparison(name, growth, seed=HELD_OUT, planting=planting).errors(None)
    n = len(dz)  # as many poses as the fit's
    # the held-out mean may exceed the fit's by at most three standard errors of the difference
    # of two means over n poses (the lane width has heavy tails: a leaf seen or not)
    for held, fit, sd in ((dz, dz_fit, dz_sd), (dl, dl_fit, dl_sd)):
        se = math.sqrt((sd**2 + held.std() ** 2) / n)
        assert held.mean() <= fit + 3 * max(se, 0.005), (held.mean(), fit, se)


@pytest.mark.parametrize(
    ("planting", "name", "stage"),
    [(p, n, s) for p in PLANTINGS for n in fitted(p) for s in range(1, CATALOG[n].stages + 1)],
)
def test_proxy_agrees_with_the_meshes_within_the_fit_on_held_out_lanes(
    planting: str, name: str, stage: int
) -> None:
    """Per-pixel depth and the lane's visible width, every table, species and stage, unseen
    lanes of the table's planting."""
    _check(name, float(CATALOG[name].growth_of_stage(stage)), planting)


def test_on_flat_planting_the_flat_table_is_nearer_the_meshes() -> None:
    """1.8 m maize, whose leaf band starts near the camera's height: on unseen flat lanes the
    table fitted on flat lanes is nearer the meshes than the ridged lanes' table (it was fitted
    for a camera 0.12 m lower against the plants)."""
    growth = float(CATALOG["corn"].growth_of_stage(4))
    cmp = Comparison("corn", growth, seed=HELD_OUT, planting="flat")
    ridged = ProxyParams(*map(float, proxy_params("corn", growth, "ridged")))
    flat = sum(e.mean() for e in cmp.errors(None))
    assert flat < 0.8 * sum(e.mean() for e in cmp.errors(ridged))


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


@pytest.mark.parametrize("planting", PLANTINGS)
def test_every_catalog_species_has_fitted_parameters(planting: str) -> None:
    assert set(fitted(planting)) == set(CATALOG)


def test_a_planting_without_a_table_is_named() -> None:
    with pytest.raises(InputError, match="proxy fit planting: got 'bedded'; allowed: ridged, flat"):
        proxy_params("corn", 0.5, "bedded")


def test_the_written_table_is_what_the_runtime_reads() -> None:
    rows = [
        (0.0, FitResult(ProxyParams(0.1, 1.0, 0.0), (0.01, 0.001), (0.0, 0.0), 0.2)),
        (1.0, FitResult(ProxyParams(0.3, 0.5, 1.2), (0.02, 0.002), (0.05, 0.01), 0.3)),
    ]
    doc = table_document({"corn": rows}, "flat")
    t = parse_table(doc)["corn"]
    assert t[1].tolist() == [1.0, 0.3, 0.5, 1.2, 0.02, 0.002, 0.05, 0.01]
    assert doc["fitted_on"]["planting"] == "flat" and doc["fitted_on"]["preset"] == "default"


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


CROP_MODELS = Path(__file__).resolve().parents[1] / "data" / "crop_models"


def _user_lanes(model: Path) -> list[Any]:
    """Lanes of 1.2 m plants of a user model, 0.75 and 1 m rows, with the fit's poses."""
    import scenario_gen as sg
    from agrinav_gym.tools.proxy_fit import FitScene, _lane_poses

    out = []
    for k, spacing in enumerate((0.75, 1.0)):
        spec = sg.preset(
            "default",
            terrain={"margin": 4.0},
            field={"width": 4.5 * spacing, "length": 14.0},
            layout={"row_spacing": spacing, "headland": 2.0, "weed_density": 0.0},
            crop={"species": "corn", "stage": 2, "model": str(model)},
        )
        scn = sg.generate(spec, HELD_OUT + k)
        out.append(FitScene(scn, _lane_poses(scn)))
    return out


@pytest.mark.parametrize("model", ["textured_obj/plant.obj", "cutout_plant/meshes/plant.dae"])
def test_the_proxy_of_a_user_model_is_fitted_to_that_model(model: str) -> None:
    """With crop.model the proxy camera draws the shape measured from the model when the
    scenario was generated: its depth differs from the catalog maize's proxy on the same field
    and is nearer to the mesh camera's (per-pixel depth plus lane width, as the fit weighs
    them)."""
    from agrinav_gym.config import EnvConfig
    from agrinav_gym.render.mesh_scene import MeshScene
    from agrinav_gym.render.proxy_plants import PlantField
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from agrinav_gym.sensors.depth import DepthCamera
    from agrinav_gym.sensors.mesh_camera import MeshCamera
    from agrinav_gym.tools.proxy_fit import _depth_error

    cfg = EnvConfig.from_dict({"camera": {"min_range": 0.0}})
    cam = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    proxy, mesh = DepthCamera(cfg.camera, cam), MeshCamera(cfg.camera, cam)
    far = cfg.camera.max_range
    err = {"model": 0.0, "catalog": 0.0}
    differ = 0.0
    for fs in _user_lanes(CROP_MODELS / model):
        scn = fs.scenario
        assert scn.crop_model is not None and scn.crop_model.shape is not None
        fields = {
            "model": PlantField.from_scenario(scn),
            "catalog": PlantField.from_scenario(scn, proxy_params),
        }
        ms = MeshScene.from_scenario(scn)
        for r, p in fs.poses:
            ref = mesh.draw(r, p, ms, None, stereo=False).depth
            depth = {k: proxy.draw(r, p, scn.terrain, f, None).depth for k, f in fields.items()}
            for k, d in depth.items():
                err[k] += _depth_error(d, ref, far) + abs(lane_width(d, cam) - lane_width(ref, cam))
            differ += _depth_error(depth["model"], depth["catalog"], far)
    assert differ > 0.05 * len(fs.poses)
    assert err["model"] < 0.7 * err["catalog"], err


def test_the_model_shape_follows_the_models_silhouette() -> None:
    """The test plant: a 2 cm stalk, a 0.3 m opaque strip across its y axis from 0.2 m up (its
    outer quarters cut out); the box: 0.1 m square, 0.5 m tall."""
    from scenario_gen.models import inspect_model

    leaf = inspect_model(CROP_MODELS / "cutout_plant" / "meshes" / "plant.dae").shape
    assert leaf is not None
    assert leaf.base == pytest.approx(0.2, abs=0.051)
    assert leaf.reach_y == pytest.approx(0.15, rel=0.1)  # the cut-out quarters do not count
    # it stands on its stalk (x 0.05 in its file), the strip 5 cm from it
    assert leaf.reach_x == pytest.approx(0.05, abs=0.01) and leaf.core < 0.04
    box = inspect_model(CROP_MODELS / "textured_obj" / "plant.obj").shape
    assert box is not None and box.base == 0.0
    assert box.core == pytest.approx(0.1, rel=0.06) and box.reach_x == pytest.approx(box.core)


def test_the_fit_lanes_follow_the_preset_asked() -> None:
    """The ridged table's lanes are ridged (the v1 envs'); the flat table's are flat."""
    from agrinav_gym.tools.proxy_fit import FIT_PRESETS, fit_scenes

    growth = float(CATALOG["corn"].growth_of_stage(2))
    ridged = fit_scenes("corn", growth, preset=FIT_PRESETS["ridged"])
    flat = fit_scenes("corn", growth, preset=FIT_PRESETS["flat"])
    assert len(ridged) == len(flat) == 2
    for r, f in zip(ridged, flat, strict=True):
        assert r.scenario.spec.furrows.enabled and not f.scenario.spec.furrows.enabled
        assert np.ptp(r.scenario.terrain.heights) > np.ptp(f.scenario.terrain.heights)


def test_the_env_draws_the_proxies_from_the_table_its_config_names() -> None:
    """``camera.proxy_fit`` picks the table: the same reset of a 1.2 m maize field observes
    other depth with the flat table than with the ridged one (the default, unchanged), and its
    plants are that table's."""
    from agrinav_gym.render.proxy_plants import PlantField

    from .helpers import TINY, make

    over = {**TINY, "crop": {"stage": 3}}
    depth = {}
    for planting in (None, *PLANTINGS):
        config = {} if planting is None else {"camera": {"proxy_fit": planting}}
        env = make("AgriNav/FurrowFollowDepth-v3", config=config, scenario_overrides=over)
        try:
            obs, _ = env.reset(seed=3)
            depth[planting] = obs["depth"]
            u = env.unwrapped
            assert u.plants is not None
            direct = PlantField.from_scenario(u.scenario, planting=planting or "ridged")
            np.testing.assert_array_equal(u.plants.radius, direct.radius)
        finally:
            env.close()
    np.testing.assert_array_equal(depth[None], depth["ridged"])
    assert np.abs(depth["flat"] - depth["ridged"]).mean() > 0.01


@pytest.mark.parametrize(
    ("enabled", "depth", "table"),
    [
        (False, 0.12, "flat"),
        (True, 0.0, "flat"),
        (True, 0.05, "flat"),
        (True, 0.06, "ridged"),
        (True, 0.25, "ridged"),
    ],
)
def test_auto_takes_the_table_nearer_the_fields_ridge_height(
    enabled: bool, depth: float, table: str
) -> None:
    from agrinav_gym.render.proxy_params import planting_of
    from scenario_gen.spec import FurrowSpec

    assert planting_of(FurrowSpec(enabled=enabled, depth=depth)) == table


def test_auto_gives_each_fit_presets_fields_their_own_table() -> None:
    """The ridge height ``auto`` measures against is the ridged fit's, so the fit's own lanes
    (``FIT_PRESETS``) map back to the table fitted on them."""
    from agrinav_gym.render.proxy_params import RIDGED_FIT_HEIGHT, planting_of
    from agrinav_gym.tools.proxy_fit import FIT_PRESETS
    from scenario_gen.presets import preset

    assert preset(FIT_PRESETS["ridged"]).furrows.depth == RIDGED_FIT_HEIGHT
    for planting in PLANTINGS:
        assert planting_of(preset(FIT_PRESETS[planting]).furrows) == planting


@pytest.mark.parametrize("ridged", [False, True])
def test_auto_draws_each_fields_proxies_from_its_plantings_table(ridged: bool) -> None:
    from agrinav_gym.render.proxy_plants import PlantField

    from .helpers import TINY, make

    furrows = {"enabled": ridged, "depth": 0.12}
    over = {**TINY, "crop": {"stage": 3}, "furrows": furrows}
    env = make(
        "AgriNav/FurrowFollowDepth-v3",
        config={"camera": {"proxy_fit": "auto"}},
        scenario_overrides=over,
    )
    try:
        env.reset(seed=3)
        u = env.unwrapped
        assert u.plants is not None
        want = PlantField.from_scenario(u.scenario, planting="ridged" if ridged else "flat")
        other = PlantField.from_scenario(u.scenario, planting="flat" if ridged else "ridged")
        np.testing.assert_array_equal(u.plants.radius, want.radius)
        assert not np.array_equal(u.plants.radius, other.radius)
    finally:
        env.close()
