import numpy as np
import pytest

from scenario_gen import CATALOG, crop_mesh, crop_model
from scenario_gen.errors import ScenarioError


@pytest.mark.parametrize("name", sorted(CATALOG))
@pytest.mark.parametrize("growth", [0.0, 0.5, 1.0])
def test_mesh_height_follows_growth(name: str, growth: float) -> None:
    mesh = crop_mesh(name, growth)
    model = crop_model(name, growth)
    assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-9)  # base at the origin
    assert mesh.bounds[1, 2] == pytest.approx(model.height, rel=1e-9)
    assert len(mesh.visual.face_colors) == len(mesh.faces)


def test_corn_grows_more_and_longer_leaves() -> None:
    small, big = crop_mesh("corn", 0.0), crop_mesh("corn", 1.0)
    assert len(big.faces) > 2 * len(small.faces)
    w = lambda m: float(np.ptp(m.vertices[:, :2], axis=0).max())  # noqa: E731
    assert w(big) > 1.8 * w(small)


def test_corn_stage_heights_match_design() -> None:
    corn = CATALOG["corn"]
    assert corn.heights == (0.3, 0.6, 1.2, 1.8, 2.5)
    assert corn.height(0.5) == pytest.approx(1.2)
    assert corn.height(0.625) == pytest.approx(1.5)  # continuous between stages


def test_bad_growth_and_species() -> None:
    with pytest.raises(ScenarioError, match="crop.growth"):
        crop_mesh("corn", 1.5)
    with pytest.raises(ScenarioError, match="crop.species"):
        crop_mesh("rice", 0.5)


def test_crop_mesh_returns_a_mesh_of_its_own() -> None:
    a = crop_mesh("corn", 0.5)
    before = crop_mesh("corn", 0.5).vertices.copy()
    a.apply_translation([1.0, 0.0, 0.0])
    assert (crop_mesh("corn", 0.5).vertices == before).all()
