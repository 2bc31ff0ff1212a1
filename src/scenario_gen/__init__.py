"""Scenario generator: real terrain -> randomized, georeferenced crop fields.

>>> import scenario_gen as sg
>>> scn = sg.generate(sg.preset("default"), seed=0)
>>> sg.save(scn, "runs/default")  # doctest: +SKIP
"""

from __future__ import annotations

from .crops import CATALOG, crop_mesh, crop_model
from .errors import InputError, ScenarioError
from .generate import generate
from .geodesy import GeoFrame, ground_sample_distance
from .io import save
from .model import Plants, Scenario
from .presets import preset, preset_names
from .reading import load
from .routes import Route
from .spec import ScenarioSpec
from .terrain import Terrain

__all__ = [
    "CATALOG",
    "GeoFrame",
    "InputError",
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
    "save",
]
