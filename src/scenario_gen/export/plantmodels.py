"""Plant models for Gazebo: one model per species and growth, plus size variants.

A scenario gives every plant its own height (``crop.height_std``) while an SDF ``<include>``
cannot scale what it includes. So each species/growth (or the user's ``crop.model``) becomes one
*base* model holding the mesh and texture, and plants are binned into size variants
``SCALE_STEP`` apart whose model.sdf reuses the base mesh at that scale: a plant's height is then
off by at most half a step (1 %). Weeds grow continuously, so their growth is binned too
(``GROWTH_STEPS``); a crop field has one growth and keeps it exactly.

Collision proxy: a stem cylinder of the catalog's stem radius at the model's growth times the
plant's scale — the circle agrinav_gym counts crop contact with — as tall as the plant. Weeds
have none.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from ..arrays import FloatArray, IntArray
from ..crops import CATALOG, WEED_SPECIES, crop_mesh
from ..errors import InputError
from ..model import Scenario
from .meshes import face_colours, flat_colour_mesh, save_png, textured_mesh, write_dae

SCALE_STEP = 1.02
GROWTH_STEPS = 16
MAX_EXACT_GROWTHS = 8  # more distinct growth values than this are binned


@dataclass(frozen=True, eq=False)
class PlantModel:
    name: str  # the base model's folder and model name
    species: str
    growth: float
    label: str
    mesh: Any  # trimesh: base at the origin, +z up, ``height`` tall
    height: float
    proxy_radius: float  # stem radius at this growth and nominal size, m; 0 = no collision
    source: str  # "catalog" or the user model's path

    def variant(self, step: int) -> str:
        """Folder/model name of the size variant ``SCALE_STEP ** step``."""
        if step == 0:
            return self.name
        return f"{self.name}_s{'p' if step > 0 else 'm'}{abs(step):02d}"


@dataclass(frozen=True, eq=False)
class Assignment:
    models: list[PlantModel]
    model: IntArray  # per plant: index into ``models``
    step: IntArray  # per plant: size variant, scale = SCALE_STEP ** step

    @property
    def scale(self) -> FloatArray:
        return np.asarray(SCALE_STEP ** self.step.astype(np.float64))

    def variants(self) -> list[tuple[int, int]]:
        """Distinct (model, step) pairs in use, sorted."""
        pairs = np.unique(np.column_stack([self.model, self.step]), axis=0)
        return [(int(m), int(s)) for m, s in pairs]


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "model"


def _stage_label(species: str, growth: float) -> str:
    sp = CATALOG[species]
    stage = float(sp.stage_of_growth(growth))
    nearest = min(max(round(stage), 1), sp.stages)
    name = sp.stage_names[nearest - 1]
    return name if abs(stage - nearest) < 1e-6 else f"{name}~{stage:.2f}"


def user_model_path(scn: Scenario) -> Path | None:
    """The scenario's user plant model, refused up front if it is gone."""
    model = scn.spec.crop.model
    if model is None:
        return None
    p = Path(model)
    if not p.is_file():
        raise InputError(
            "crop.model",
            model,
            "the scenario's user plant model no longer exists; allowed: an existing mesh or .zip",
        )
    return p


def assign(scn: Scenario) -> Assignment:
    """Base models and size variants for every plant of ``scn``."""
    p = scn.plants
    user = user_model_path(scn)
    models: list[PlantModel] = []
    model = np.zeros(len(p), np.int64)
    step = np.zeros(len(p), np.int64)
    for name in sorted(np.unique(p.species).tolist()):
        sp = CATALOG[name]
        idx = np.flatnonzero(p.species == name)
        growth = np.clip(sp.growth_of_stage(p.stage[idx]), 0.0, 1.0)
        if len(np.unique(np.round(growth, 6))) > MAX_EXACT_GROWTHS:
            growth = np.round(growth * GROWTH_STEPS) / GROWTH_STEPS
        keys, which = np.unique(np.round(growth, 6), return_inverse=True)
        for g, members in ((float(g), idx[which.ravel() == i]) for i, g in enumerate(keys)):
            nominal = float(sp.height(g))
            base = f"agrinav_{name}_g{round(g * 1000):04d}"
            if user is not None and name != WEED_SPECIES:
                from ..models import load_model

                mesh = load_model(user, nominal)
                base = f"agrinav_{_slug(user.stem)}_{name}_g{round(g * 1000):04d}"
                source = str(user)
            else:
                mesh = crop_mesh(name, g)
                source = "catalog"
            model[members] = len(models)
            ratio = np.maximum(p.height[members], 1e-6) / nominal
            step[members] = np.round(np.log(ratio) / math.log(SCALE_STEP)).astype(np.int64)
            models.append(
                PlantModel(
                    base,
                    name,
                    g,
                    f"{name} {_stage_label(name, g)}",
                    mesh,
                    nominal,
                    float(sp.stem_radius(g)),
                    source,
                )
            )
    return Assignment(models, model, step)


# ----------------------------------------------------------------------------- SDF text
def fmt(*values: float, digits: int = 6) -> str:
    return " ".join(f"{v + 0.0:.{digits}f}" for v in values)


def model_config(name: str, description: str) -> str:
    return f"""<?xml version="1.0"?>
<model>
  <name>{escape(name)}</name>
  <version>1.0</version>
  <sdf version="1.7">model.sdf</sdf>
  <author><name>agrinav export</name><email>agrinav@localhost</email></author>
  <description>{escape(description)}</description>
</model>
"""


def stem_collision(name: str, pose: str, radius: float, length: float) -> str:
    return (
        f'<collision name="{name}"><pose>{pose}</pose><geometry><cylinder>'
        f"<radius>{radius:.5f}</radius><length>{length:.5f}</length>"
        f"</cylinder></geometry></collision>"
    )


def plant_sdf(pm: PlantModel, step: int) -> str:
    scale = SCALE_STEP**step
    h = pm.height * scale
    col = (
        stem_collision("stem", fmt(0, 0, h / 2, 0, 0, 0), pm.proxy_radius * scale, h)
        if pm.proxy_radius > 0
        else ""
    )
    return f"""<?xml version="1.0"?>
<sdf version="1.7">
  <model name="{pm.variant(step)}">
    <static>true</static>
    <link name="link">
      <visual name="visual">
        <geometry><mesh><uri>model://{pm.name}/meshes/plant.dae</uri>
          <scale>{fmt(scale, scale, scale)}</scale></mesh></geometry>
      </visual>
      {col}
    </link>
  </model>
</sdf>
"""


def write_models(models_dir: Path, a: Assignment, only_base: bool = False) -> list[str]:
    """Write every base model (mesh, texture) and, unless ``only_base``, every size variant."""
    written = []
    for m, pm in enumerate(a.models):
        folder = models_dir / pm.name
        (folder / "meshes").mkdir(parents=True)
        (folder / "materials" / "textures").mkdir(parents=True)
        data = textured_mesh(pm.mesh)
        if data is None:
            data = flat_colour_mesh(
                np.asarray(pm.mesh.vertices, np.float64),
                np.asarray(pm.mesh.faces, np.int64),
                face_colours(pm.mesh),
            )
        md, image = data
        save_png(image, folder / "materials" / "textures" / "plant.png")
        write_dae(folder / "meshes" / "plant.dae", md, "../materials/textures/plant.png", pm.name)
        desc = f"{pm.label}, {pm.height:.3f} m, from {pm.source}; agrinav export"
        (folder / "model.config").write_text(model_config(pm.name, desc))
        (folder / "model.sdf").write_text(plant_sdf(pm, 0))
        written.append(pm.name)
        if only_base:
            continue
        for mm, s in a.variants():
            if mm != m or s == 0:
                continue
            vfolder = models_dir / pm.variant(s)
            vfolder.mkdir()
            vdesc = f"{pm.label} at {SCALE_STEP**s:.4f}x ({pm.height * SCALE_STEP**s:.3f} m)"
            (vfolder / "model.config").write_text(model_config(pm.variant(s), vdesc))
            (vfolder / "model.sdf").write_text(plant_sdf(pm, s))
            written.append(pm.variant(s))
    return written
