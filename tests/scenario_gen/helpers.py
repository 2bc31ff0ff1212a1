"""Small, fast specs shared by the scenario_gen tests."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from scenario_gen import ScenarioSpec, preset


def small(**overrides: Any) -> ScenarioSpec:
    """The default preset on a 10 x 14 m field: the real pipeline at test speed."""
    base = {
        "field": {"width": 10.0, "length": 14.0},
        "layout": {"headland": 2.0},
        "terrain": {"margin": 4.0},
    }
    spec = preset("default", **base)
    return spec.replace(overrides) if overrides else spec


def plane(slope_deg: float = 0.0, aspect_deg: float = 0.0, **overrides: Any) -> ScenarioSpec:
    """A tilted plane with no micro-relief: analytic ground truth."""
    o: dict[str, Any] = {
        "terrain": {
            "source": "plane",
            "slope_deg": slope_deg,
            "aspect_deg": aspect_deg,
            "site": "flattest",
        },
        "furrows": {"enabled": False, "roughness": 0.0},
    }
    spec = small(**o)
    return spec.replace(overrides) if overrides else spec


def url_encoded_leaf(cutout: Path, dest: Path) -> Path:
    """A copy of the cut-out plant model whose leaf texture is named ``leaf tex.png`` and
    referenced, as COLLADA's URIs write it, ``leaf%20tex.png``; returns the copy's mesh."""
    shutil.copytree(cutout, dest)
    textures = dest / "materials" / "textures"
    (textures / "leaf.png").rename(textures / "leaf tex.png")
    dae = dest / "meshes" / "plant.dae"
    dae.write_text(dae.read_text().replace("textures/leaf.png", "textures/leaf%20tex.png"))
    return dae
