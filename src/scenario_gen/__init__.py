"""Scenario generator: real terrain -> randomized, georeferenced crop fields.

>>> import scenario_gen as sg
>>> scn = sg.generate(sg.preset("default"), seed=0)
>>> scn.save("runs/default")
"""

from __future__ import annotations

from .config import ScenarioSpec, preset, preset_names
from .crops import CATALOG, crop_mesh, crop_model
from .errors import ScenarioError
from .geodesy import GeoFrame, ground_sample_distance
from .io import load
from .routes import Route
from .scenario import Plants, Scenario, generate
from .terrain import Terrain

__all__ = [
    "CATALOG",
    "GeoFrame",
    "Plants",
    "Route",
    "Scenario",
    "ScenarioError",
    "ScenarioSpec",
    "Terrain",
    "crop_mesh",
    "crop_model",
    "generate",
    "ground_sample_distance",
    "load",
    "preset",
    "preset_names",
]
