"""Every bad input gets a ScenarioError naming the field, the value and what is allowed."""

import json
import stat
import zipfile
from pathlib import Path

import pytest

from scenario_gen import ScenarioError, ScenarioSpec, generate, preset
from scenario_gen.models import load_model, safe_extract

from .helpers import small


@pytest.mark.parametrize(
    "overrides,field",
    [
        ({"layout.row_spacin": 1.0}, "layout.row_spacin"),
        ({"layout": {"row_spacing": -1.0}}, "layout.row_spacing"),
        ({"layout": {"row_spacing": "wide"}}, "layout.row_spacing"),
        ({"layout": {"gap_prob": 1.5}}, "layout.gap_prob"),
        ({"terrain": {"lod": 25}}, "terrain.lod"),
        ({"terrain": {"lod": 19.5}}, "terrain.lod"),
        ({"terrain": {"source": "lidar"}}, "terrain.source"),
        ({"terrain": {"datum": [1.0, 2.0]}}, "terrain.datum"),
        ({"crop": {"species": "banana"}}, "crop.species"),
        ({"furrows": {"enabled": "yes"}}, "furrows.enabled"),
        ({"route": {"spacing": 0.5}}, "route.spacing"),
        ({"wheels": 4}, "wheels"),
        ({"field": 3}, "field"),
        ({"field": {"width": 0.0}}, "field.width"),  # (0, 5000]: the range says it now
    ],
)
def test_spec_errors_name_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ScenarioError) as info:
        preset("default").replace(overrides)
    assert info.value.field == field
    assert "allowed" in str(info.value) or "unknown key" in str(info.value)
    if field == "field.width":
        assert "(0, 5000]" in str(info.value)


def test_unknown_preset_lists_the_allowed_ones() -> None:
    with pytest.raises(ScenarioError, match="allowed: one of default"):
        preset("nope")


@pytest.mark.parametrize(
    "overrides,field",
    [
        ({"crop": {"stage": 5, "species": "tomato"}}, "crop.stage"),
        ({"route": {"lanes": 500}}, "route.lanes"),
        ({"route": {"first_lane": 400}}, "route.first_lane"),
        ({"layout": {"headland": 20.0}}, "layout.headland/edge_margin"),
        ({"field": {"width": 0.5, "length": 0.5}}, "field"),
        ({"field": {"width": 1.2, "length": 30.0}}, "field"),  # one row: no lane at all
        ({"layout": {"rows": 1}}, "layout.rows"),  # one row asked for: that is named
        ({"layout": {"plant_spacing": 50.0}}, "layout"),  # rows, but no crop along a lane
        # every plant a gap: rows and lanes were reported over a field with no crop
        ({"layout": {"gap_prob": 1.0}}, "layout.gap_prob"),
        ({"layout": {"gap_run_prob": 1.0, "gap_run_mean": 10000.0}}, "layout.gap_run_prob"),
        ({"field": {"width": 2000.0, "length": 2500.0}}, "layout.plant_spacing/row_spacing"),
        ({"terrain": {"site": "latlon"}}, "terrain.lat/lon"),
        ({"terrain": {"source": "dem"}}, "terrain.path"),
        ({"terrain": {"source": "dem", "path": "/nonexistent.tif"}}, "terrain.path"),
        ({"terrain": {"path": "/x.tif"}}, "terrain.path"),
        ({"route": {"lead_in": 30.0}}, "route"),
    ],
)
def test_generation_errors_name_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ScenarioError) as info:
        generate(small(**overrides), seed=0)
    assert info.value.field == field, str(info.value)


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True])
def test_bad_seed(seed: object) -> None:
    with pytest.raises(ScenarioError, match="seed"):
        generate(small(), seed)  # type: ignore[arg-type]


def _geojson(tmp_path: Path, coords: list, name: str = "f.geojson") -> str:
    p = tmp_path / name
    p.write_text(json.dumps({"type": "Polygon", "coordinates": coords}))
    return str(p)


@pytest.mark.parametrize(
    "coords,match",
    [
        (
            [
                [
                    [-84.142, 36.549],
                    [-84.141, 36.550],
                    [-84.141, 36.549],
                    [-84.142, 36.550],
                    [-84.142, 36.549],
                ]
            ],
            "invalid .*Self-intersection",
        ),
        (
            [
                [
                    [-84.14250, 36.54920],
                    [-84.14249, 36.54920],
                    [-84.14249, 36.54921],
                    [-84.14250, 36.54920],
                ]
            ],
            "too small",
        ),
        (
            [[[500000, 4000000], [500100, 4000000], [500100, 4000100], [500000, 4000000]]],
            "look projected",
        ),
        ([[[-80.0, 36.5], [-79.99, 36.5], [-79.99, 36.51], [-80.0, 36.5]]], "off the DEM"),
        (  # latitude first: on the DEM the other way round
            [[[36.5491, -84.1426], [36.5491, -84.1422], [36.5494, -84.1422], [36.5491, -84.1426]]],
            "^field: .*off the DEM.*are the coordinates swapped",
        ),
    ],
)
def test_bad_field_polygons(tmp_path: Path, coords: list, match: str) -> None:
    with pytest.raises(ScenarioError, match=match):
        generate(small(field={"geojson": _geojson(tmp_path, coords)}), seed=0)


def test_geojson_without_polygon_or_not_json(tmp_path: Path) -> None:
    p = tmp_path / "points.geojson"
    p.write_text(json.dumps({"type": "Point", "coordinates": [0, 0]}))
    with pytest.raises(ScenarioError, match="no Polygon"):
        generate(small(field={"geojson": str(p)}), seed=0)
    p.write_text("{not json")
    with pytest.raises(ScenarioError, match="not valid JSON"):
        generate(small(field={"geojson": str(p)}), seed=0)
    with pytest.raises(ScenarioError, match="an existing file, GeoJSON"):
        generate(small(field={"geojson": str(tmp_path / "missing.geojson")}), seed=0)


def test_spec_round_trips_through_dict() -> None:
    spec = preset("hillside")
    assert ScenarioSpec.from_dict(spec.to_dict()) == spec


# ----------------------------------------------------------------------------- archives
def _zip(path: Path, members: dict[str, bytes], link: str | None = None) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        if link:
            info = zipfile.ZipInfo(link)
            info.external_attr = (stat.S_IFLNK | 0o777) << 16
            zf.writestr(info, "/etc/passwd")
    return path


@pytest.mark.parametrize(
    "name", ["../evil.obj", "a/../../evil.obj", "/abs/evil.obj", "C:/evil.obj"]
)
def test_zip_slip_is_refused_before_writing(tmp_path: Path, name: str) -> None:
    arc = _zip(tmp_path / "m.zip", {"ok.txt": b"x", name: b"v 0 0 0\n"})
    dest = tmp_path / "out"
    dest.mkdir()
    with pytest.raises(ScenarioError, match="crop.model"):
        safe_extract(arc, dest)
    assert list(dest.iterdir()) == []  # nothing written, not even the harmless member
    assert not (tmp_path / "evil.obj").exists()


def test_symlinks_and_bombs_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="symbolic links"):
        safe_extract(_zip(tmp_path / "l.zip", {}, link="plant.obj"), tmp_path / "o1")
    with pytest.raises(ScenarioError, match="compression ratio"):
        safe_extract(_zip(tmp_path / "b.zip", {"big.obj": b"\0" * 5_000_000}), tmp_path / "o2")


def test_model_zip_loads_and_scales(tmp_path: Path) -> None:
    import trimesh

    mesh = trimesh.creation.cylinder(radius=0.1, height=3.0)
    obj = trimesh.exchange.obj.export_obj(mesh)
    arc = _zip(tmp_path / "plant.zip", {"models/plant.obj": obj.encode(), "tex/a.png": b"png"})
    m = load_model(arc, height=1.2)
    assert m.bounds[1, 2] - m.bounds[0, 2] == pytest.approx(1.2)
    assert m.bounds[0, 2] == pytest.approx(0.0)
    with pytest.raises(ScenarioError, match="no mesh"):
        load_model(_zip(tmp_path / "empty.zip", {"readme.txt": b"hi"}), 1.0)


# ----------------------------------------------------------------------------- hostile input
@pytest.mark.parametrize(
    "layout,field,bound",
    [
        ({"jitter_lateral": 0.2}, "layout.jitter_lateral", "row_spacing/6 = 0.1667"),
        (
            {"jitter_longitudinal": 0.04, "plant_spacing": 0.18},
            "layout.jitter_longitudinal",
            "plant_spacing/6 = 0.03",
        ),
    ],
)
def test_jitter_beyond_half_the_spacing_is_refused(layout: dict, field: str, bound: str) -> None:
    with pytest.raises(ScenarioError) as info:
        generate(small(layout=layout), seed=0)
    assert info.value.field == field and bound in str(info.value), str(info.value)


def test_rows_survive_save_and_load_at_the_jitter_bound(tmp_path: Path) -> None:
    import numpy as np

    from scenario_gen import load, save

    spec = small(layout={"jitter_lateral": 1.0 / 6, "jitter_longitudinal": 0.03, "gap_prob": 0})
    scn = generate(spec, seed=4)
    _, s = scn.rows.to_rows(scn.plants.x, scn.plants.y)
    lateral = s - scn.rows.offsets[scn.plants.row]
    assert np.abs(lateral).max() <= 0.5 + 1e-9 and np.abs(lateral).max() > 0.3
    back = load(save(scn, tmp_path / "s", preview=False))
    np.testing.assert_array_equal(back.plants.row, scn.plants.row)


def test_numpy_scalars_are_accepted_in_a_spec() -> None:
    import numpy as np

    spec = preset("default").replace(
        {
            "layout.row_spacing": np.float32(0.8),
            "layout.rows": np.int64(10),
            "terrain.lod": np.int32(20),
            "furrows.enabled": np.bool_(False),
            "crop.species": np.str_("tomato"),
            "crop.stage": np.uint8(2),
            "terrain.source": "plane",
            "terrain.datum": [np.float64(42.0), np.float32(-5.5), np.int16(800)],
        }
    )
    assert spec.layout.row_spacing == pytest.approx(0.8) and type(spec.layout.rows) is int
    assert spec.furrows.enabled is False and spec.crop.species == "tomato"
    assert spec.terrain.datum == (42.0, -5.5, 800.0)
    assert type(spec.terrain.datum[0]) is float
    generate(spec.replace({"field.width": 8.0, "field.length": 10.0}), seed=np.int64(3))


def test_a_preset_with_files_is_named_after_them() -> None:
    """preset() names a scenario after the preset and the files its overrides bring in, in a
    form generate accepts (printable, no '--', at most 100 characters)."""
    from scenario_gen import preset
    from scenario_gen.presets import source_name

    assert preset("hillside").name == "hillside"
    dem = {"terrain": {"source": "dem", "path": "/data/farm.v2.tif"}}
    assert preset("default", **dem).name == "default+farm"
    both = preset("default", **dem, field={"geojson": "/x/north.geojson"})
    assert both.name == "default+farm+north"
    assert preset("default", **dem).replace({"name": "mine"}).name == "mine"
    # a name given is the name (it was a TypeError: preset's own first parameter)
    assert preset("default", **dem, name="mine").name == "mine"
    assert preset("default", terrain={"source": "plane"}).name == "default"  # no file
    odd = source_name("default", preset("default"), ["/x/a\nb---c.yaml"])
    assert odd == "default+a_b-c"
    long = source_name("default", preset("default"), ["/x/" + "a" * 300 + ".yaml"])
    assert len(long) == 100 and long.isprintable()


def test_generate_takes_a_spec_not_a_preset_name() -> None:
    with pytest.raises(ScenarioError) as info:
        generate("default", 1)  # type: ignore[arg-type]
    assert info.value.field == "spec" and "scenario_gen.preset(NAME)" in str(info.value)


def test_a_nan_coordinate_has_no_height() -> None:
    import numpy as np

    terrain = generate(small(), 0).terrain
    cx, cy = (np.asarray(terrain.bounds[:2]) + terrain.bounds[2:]) / 2
    z = terrain.height_at([np.nan, cx, cx], [0.0, np.nan, cy])
    assert np.isnan(z[:2]).all() and z[2] == terrain.height_at(cx, cy)
