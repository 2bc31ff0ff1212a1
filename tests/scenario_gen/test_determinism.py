from pathlib import Path

import numpy as np

from scenario_gen import generate, save

from .helpers import small


def _arrays(scn) -> dict[str, np.ndarray]:
    out = {f"plants.{k}": v for k, v in scn.plants.arrays().items()}
    out["terrain"] = scn.terrain.heights
    out["route"] = scn.route.xyz
    return out


def test_same_seed_same_bits_other_seed_different() -> None:
    spec = small(layout={"weed_density": 1.0, "gap_run_prob": 0.01})
    a, b, c = generate(spec, 7), generate(spec, 7), generate(spec, 8)
    for key, value in _arrays(a).items():
        other = _arrays(b)[key]
        assert value.dtype == other.dtype and np.array_equal(value, other), key
    assert not np.array_equal(a.plants.x[: len(c.plants)], c.plants.x[: len(a.plants)])
    assert not np.array_equal(a.terrain.heights, c.terrain.heights)  # roughness differs


def test_same_seed_same_files(tmp_path: Path) -> None:
    spec = small()
    save(generate(spec, 3), tmp_path / "a")
    save(generate(spec, 3), tmp_path / "b")
    save(generate(spec, 4), tmp_path / "c")
    for name in (
        "scenario.json",
        "plants.csv",
        "route.csv",
        "field.geojson",
        "route.geojson",
        "plants.geojson",
        "terrain.npz",
        "preview.png",
    ):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    assert (tmp_path / "a" / "plants.csv").read_bytes() != (
        tmp_path / "c" / "plants.csv"
    ).read_bytes()


def test_changing_one_parameter_keeps_other_random_choices() -> None:
    # independent streams: adding weeds must not move a single crop plant
    a = generate(small(), 5)
    b = generate(small(layout={"weed_density": 2.0}), 5)
    crops = ~b.plants.is_weed
    np.testing.assert_array_equal(a.plants.x, b.plants.x[crops])
    np.testing.assert_array_equal(a.plants.y, b.plants.y[crops])
