"""Sensor tests run on both paths: the compiled kernels and the numpy/Embree reference."""

from __future__ import annotations

import pytest

from agrinav_gym.render import native


@pytest.fixture(params=["compiled", "reference"])
def kernels(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """The proxy camera through the compiled kernels, then through numpy and Embree."""
    if request.param == "compiled":
        if not native.available():
            pytest.skip("compiled kernels not built (test_native checks the build in CI)")
    else:
        monkeypatch.setenv("AGRINAV_NATIVE", "0")
    return str(request.param)


@pytest.fixture(params=["raster", "raycast"])
def renderer(request: pytest.FixtureRequest) -> str:
    """The mesh camera's renderer: the compiled rasteriser, then Embree's rays."""
    if request.param == "raster" and not native.available():
        pytest.skip("compiled kernels not built (test_native checks the build in CI)")
    return str(request.param)
