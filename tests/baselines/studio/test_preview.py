"""The live preview puts every plant and waypoint where ``generate`` does, and its errors are
the generator's, named by field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Polygon

from baselines.studio.preview import SiteCache, layout_preview, plan_layout, plan_scene
from baselines.studio.session import Session
from scenario_gen import generate
from scenario_gen.errors import InputError
from scenario_gen.preview import OBSTACLE_RGB


def _pentagon_with_hole(lat: float, lon: float) -> Polygon:
    d = 0.00025  # ≈ 25 m
    shell = [
        (lon - d, lat - d),
        (lon + d, lat - d),
        (lon + d, lat + d),
        (lon, lat + 1.4 * d),
        (lon - d, lat + d),
    ]
    hole = [(lon - 0.2 * d, lat - 0.2 * d), (lon + 0.2 * d, lat - 0.2 * d), (lon, lat + 0.2 * d)]
    return Polygon(shell, [hole])


@pytest.mark.parametrize("drawn", [False, True])
def test_preview_is_the_generated_layout_to_the_bit(tmp_path: Path, drawn: bool) -> None:
    s = Session(seed=5)
    s.set("layout.weed_density", 0.2)
    s.set("layout.gap_run_prob", 0.05)
    sites = SiteCache()
    if drawn:
        s.set_field(_pentagon_with_hole(36.55, -84.14))
        path = tmp_path / "f.geojson"
        assert s.field_text is not None
        path.write_text(s.field_text)
        spec = s.spec(str(path))
    else:
        spec = s.spec()
    _, lay, route = plan_layout(s.spec(), s.seed, s.field_geom, sites)
    scn = generate(spec, s.seed)
    assert np.array_equal(lay.x, scn.plants.x) and np.array_equal(lay.y, scn.plants.y)
    assert np.array_equal(lay.is_weed, scn.plants.is_weed)
    assert np.array_equal(route.xyz[:, :2], scn.route.xyz[:, :2])
    pv = layout_preview(s.spec(), s.seed, s.field_geom, sites)
    assert pv.n_plants == int((~scn.plants.is_weed).sum()) and pv.stride == 1
    lat, lon, _ = scn.geo.enu_to_geodetic(
        scn.plants.x[~scn.plants.is_weed], scn.plants.y[~scn.plants.is_weed]
    )
    assert np.allclose(pv.plants, np.column_stack([lat, lon]), atol=1e-12, rtol=0)


@pytest.mark.parametrize(("geometry", "turn"), [("curved", "omega"), ("contour", "three_point")])
def test_preview_draws_curved_rows_and_sized_turns_where_generate_puts_them(
    geometry: str, turn: str
) -> None:
    s = Session(seed=3)
    s.set("terrain.site", "steepest")
    s.set("terrain.max_slope_deg", 15.0)
    s.set("layout.row_geometry", geometry)
    s.set("route.turn", turn)
    _, lay, route = plan_layout(s.spec(), s.seed, None, SiteCache())
    scn = generate(s.spec(), s.seed)
    assert np.array_equal(lay.x, scn.plants.x) and np.array_equal(lay.y, scn.plants.y)
    assert np.array_equal(route.xyz[:, :2], scn.route.xyz[:, :2])
    assert np.array_equal(route.turn, scn.route.turn)


def test_large_fields_are_drawn_decimated_with_the_true_count() -> None:
    s = Session()
    full = layout_preview(s.spec(), 0, None, SiteCache())
    small = layout_preview(s.spec(), 0, None, SiteCache(), max_drawn=500)
    assert small.n_plants == full.n_plants > 2000
    assert small.stride == -(-full.n_plants // 500) and len(small.plants) <= 500
    assert np.array_equal(small.plants, full.plants[:: small.stride])


def test_errors_name_the_field_they_concern() -> None:
    sites = SiteCache()
    s = Session()
    s.set_field(_pentagon_with_hole(50.0, 10.0))  # far off the embedded DEM
    with pytest.raises(InputError) as e:
        layout_preview(s.spec(), 0, s.field_geom, sites)
    assert e.value.field == "field" and "off the DEM" in str(e.value)
    s = Session()
    s.set("route.lanes", 500)
    with pytest.raises(InputError) as e:
        layout_preview(s.spec(), 0, None, sites)
    assert e.value.field == "route.lanes"
    s = Session()
    s.set("terrain.margin", 0.0)
    s.set("route.lead_in", 30.0)
    with pytest.raises(InputError) as e:
        layout_preview(s.spec(), 0, None, sites)
    assert e.value.field == "route"  # the generator's own check, on the grid's exact extent


OBSTACLES = {"stone_density": 0.3, "litter_density": 0.05, "stalk_lodging": 0.05}


def _with_obstacles(s: Session) -> Session:
    for key, value in OBSTACLES.items():
        s.set(f"obstacles.{key}", value)
    return s


@pytest.mark.parametrize("turn", ["semicircle", "omega"])
def test_preview_obstacles_are_where_generate_puts_them(turn: str) -> None:
    """With obstacles, the same plants fall (and leave the drawn layout), the route avoids the
    same standing crop, and every obstacle has generate's kind, position, heading and size."""
    s = _with_obstacles(Session(seed=4))
    s.set("route.turn", turn)
    _, lay, route, obs = plan_scene(s.spec(), s.seed, None, SiteCache())
    scn = generate(s.spec(), s.seed)
    counts = scn.obstacles.counts()
    assert all(n > 0 for n in counts.values()), counts
    assert np.array_equal(lay.x, scn.plants.x) and np.array_equal(lay.y, scn.plants.y)
    assert np.array_equal(route.xyz[:, :2], scn.route.xyz[:, :2])
    for name in ("kind", "x", "y", "yaw", "length", "width", "height", "shape"):
        assert np.array_equal(getattr(obs, name), getattr(scn.obstacles, name)), name
    pv = layout_preview(s.spec(), s.seed, None, SiteCache())
    assert pv.n_plants == int((~scn.plants.is_weed).sum())
    o = scn.obstacles
    feet = o.footprints()
    assert sorted(pv.obstacles) == sorted(k for k, n in counts.items() if n)
    for kind, drawn in pv.obstacles.items():
        sel = o.kind == kind
        lat, lon, _ = scn.geo.enu_to_geodetic(feet[sel, :, 0], feet[sel, :, 1])
        np.testing.assert_allclose(drawn, np.stack([lat, lon], axis=-1), atol=1e-12, rtol=0)
        # the page gets every corner of every obstacle, 1e-7° (≈ 1 cm)
        flat = pv.payload()["obstacles"][kind]
        assert len(flat) == 8 * int(sel.sum())
        np.testing.assert_allclose(np.reshape(flat, (-1, 4, 2)), drawn, atol=5.1e-8, rtol=0)
        # and how to draw it: the previews' colour, named once (scenario_gen.preview)
        fill = pv.payload()["obstacle_style"][kind][0]
        assert tuple(int(fill[i : i + 2], 16) for i in (1, 3, 5)) == OBSTACLE_RGB[kind]


def test_preview_without_obstacles_draws_none_and_samples_nothing_more() -> None:
    s = Session(seed=4)
    _, lay, _, obs = plan_scene(s.spec(), s.seed, None, SiteCache())
    assert (
        len(obs) == 0
        and layout_preview(s.spec(), 4, None, SiteCache()).payload()["obstacles"] == {}
    )
    # only stones: nothing lodged, so the drawn layout is the obstacle-free one
    s.set("obstacles.stone_density", 0.2)
    _, lay_st, _, obs_st = plan_scene(s.spec(), s.seed, None, SiteCache())
    assert np.array_equal(lay_st.x, lay.x) and set(obs_st.kind.tolist()) == {"stone"}


def test_preview_lodges_a_native_scale_user_model_as_generate_does(tmp_path: Path) -> None:
    """crop.model_scale native: the plants' heights (and so the fallen stalks' lengths) come
    from the model's own size, read as generate reads it."""
    model = Path(__file__).parents[2] / "data" / "crop_models" / "cutout_plant" / "meshes"
    s = Session(seed=2)
    s.set("obstacles.stalk_lodging", 0.1)
    s.set("crop.model", str(model / "plant.dae"))
    s.set("crop.model_scale", "native")
    _, _, _, obs = plan_scene(s.spec(), s.seed, None, SiteCache())
    scn = generate(s.spec(), s.seed)
    assert len(obs) and np.array_equal(obs.length, scn.obstacles.length)
    assert np.array_equal(obs.x, scn.obstacles.x)
