"""Crop catalog and procedural plant models.

Each species has growth stages with a nominal height and canopy width; ``growth`` in [0, 1] moves
continuously through them. ``crop_mesh`` builds a trimesh model whose shape follows growth (leaf
count, leaf length and droop, canopy width, tassels, heads, fruit), coloured per face, with
its base at the origin and +z up. ``Species.stem_diameter`` is what a wheel or the chassis of a
robot meets at ground level (the stalk of an upright crop, the head of a cabbage): the crop-contact
model and the models' stalks use it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .arrays import FloatArray
from .errors import InputError

Colour = tuple[int, int, int]
#: the species every field's weeds are (``layout.weed_density``)
WEED_SPECIES = "weed"
Parts = list[tuple[Any, Colour]]
LeafFn = Callable[
    [FloatArray, float, float, float, float, float], tuple[FloatArray, NDArray[np.int64]]
]
ModelFn = Callable[["Species", float, float, float, LeafFn], Parts]


@dataclass(frozen=True)
class Species:
    name: str
    stage_names: tuple[str, ...]
    heights: tuple[float, ...]  # nominal height per stage, m
    canopy: tuple[float, ...]  # canopy diameter per stage, m
    # Stalk (or head) diameter per stage at ground level, m: maize V3 ≈ 0.8 cm to ≈ 2.5 cm at
    # silking (agronomy references give 2-3 cm for mature stalks); sunflower to 3 cm; tomato to
    # 1.5 cm; a cabbage's wheel-height obstacle is its head, to ≈ 20 cm across.
    stem_diameter: tuple[float, ...]
    colour: tuple[int, int, int]
    # The procedural model: the parts (mesh, colour) of a plant of height h, canopy width w at
    # ``growth``; ``leaf`` draws one leaf ribbon (``crop_mesh`` scales its length and droop).
    model: ModelFn
    # Growth steps the mesh camera keeps models for (nodes 0, 1/n, ..., 1: every stage a node),
    # measured by benchmarks/growth_bins.py (the smallest count within the D455's depth noise).
    mesh_intervals: int
    # Grass crops (maize) carry their leaves in one vertical plane, which can cross the lane.
    planar_leaves: bool = False

    @property
    def stages(self) -> int:
        return len(self.heights)

    def growth_of_stage(self, stage: Any) -> Any:
        return (stage - 1.0) / (self.stages - 1.0)

    def stage_of_growth(self, growth: float | FloatArray) -> Any:
        return 1.0 + np.asarray(growth) * (self.stages - 1.0)

    def height(self, growth: float | FloatArray) -> Any:
        return np.interp(self.stage_of_growth(growth), np.arange(1, self.stages + 1), self.heights)

    def canopy_width(self, growth: float | FloatArray) -> Any:
        return np.interp(self.stage_of_growth(growth), np.arange(1, self.stages + 1), self.canopy)

    def stem_radius(self, growth: float | FloatArray) -> Any:
        d = np.interp(
            self.stage_of_growth(growth), np.arange(1, self.stages + 1), self.stem_diameter
        )
        return 0.5 * d

    @property
    def proxy_radius(self) -> float:
        """Largest stem radius over the stages: a growth-independent collision proxy."""
        return 0.5 * max(self.stem_diameter)


def scaled_by_height(
    species_of: NDArray[Any],
    stage: NDArray[Any],
    height: NDArray[Any],
    quantity: Callable[[Species, NDArray[np.float64]], NDArray[np.float64]],
) -> NDArray[np.float64]:
    """``quantity(species, growth)`` for every plant, scaled as the plant's height is to its
    species' height at that growth (a tall plant of a stage is proportionally wider)."""
    out = np.zeros(len(height))
    for name in np.unique(species_of):
        sp = CATALOG[str(name)]
        m = species_of == name
        growth = np.asarray(sp.growth_of_stage(stage[m]), np.float64)
        scale = height[m] / np.maximum(sp.height(growth), 1e-6)
        out[m] = quantity(sp, growth) * scale
    return out


def species(name: str) -> Species:
    if name not in CATALOG:
        raise InputError("crop.species", name, f"allowed: one of {', '.join(CATALOG)}")
    return CATALOG[name]


@dataclass(frozen=True)
class CropModel:
    species: str
    growth: float
    height: float
    canopy: float
    stem_radius: float  # at this growth, m


def crop_model(name: str, growth: float) -> CropModel:
    sp = species(name)
    return CropModel(
        name,
        growth,
        float(sp.height(growth)),
        float(sp.canopy_width(growth)),
        float(sp.stem_radius(growth)),
    )


# ----------------------------------------------------------------------------- geometry helpers
def _ribbon(
    centre: FloatArray, widths: FloatArray, side: FloatArray
) -> tuple[FloatArray, NDArray[np.int64]]:
    """A double-sided strip along ``centre`` (M, 3), half-width ``widths`` along ``side``."""
    m = len(centre)
    v = np.concatenate([centre - widths[:, None] * side, centre + widths[:, None] * side])
    a = np.arange(m - 1)
    f = np.concatenate(
        [np.column_stack([a, a + 1, a + m]), np.column_stack([a + 1, a + m + 1, a + m])]
    )
    return v, np.concatenate([f, f[:, ::-1]])


def _leaf_ribbon(
    base: FloatArray,
    azimuth: float,
    length: float,
    width: float,
    rise: float,
    droop: float,
    segments: int = 6,
) -> tuple[FloatArray, NDArray[np.int64]]:
    s = np.linspace(0.0, 1.0, segments + 1)
    d = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    side = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
    centre = (
        base + np.outer(s * length, d) + np.outer(length * (rise * s - droop * s * s), [0, 0, 1])
    )
    widths = width / 2 * np.sin(np.pi * np.clip(s, 0.05, 1.0)) ** 0.7
    return _ribbon(centre, widths, np.broadcast_to(side, centre.shape).copy())


def _mesh(parts: list[tuple[Any, tuple[int, int, int]]]) -> Any:
    import trimesh

    meshes = []
    for part, colour in parts:
        if isinstance(part, tuple):
            part = trimesh.Trimesh(vertices=part[0], faces=part[1], process=False)
        part.visual.face_colors = np.array([*colour, 255], dtype=np.uint8)
        meshes.append(part)
    return trimesh.util.concatenate(meshes)


def _stalk(height: float, r0: float, r1: float) -> Any:
    import trimesh

    m = trimesh.creation.cylinder(radius=r0, height=height, sections=8)
    m.apply_translation([0, 0, height / 2])
    v = m.vertices.copy()
    v[:, :2] *= 1 - (1 - r1 / r0) * v[:, 2:3] / height
    m.vertices = v
    return m


GREEN = (70, 140, 50)
DARK = (45, 100, 35)


def crop_mesh(name: str, growth: float, leaf_length: float = 1.0, leaf_droop: float = 1.0) -> Any:
    """Procedural model of ``name`` at ``growth`` in [0, 1], base at the origin, +z up.

    ``leaf_length`` and ``leaf_droop`` scale every leaf's length and droop (sensitivity studies;
    1 is the catalog model). Each call returns a mesh of its own (built once per arguments and
    copied), so a caller that transforms it cannot change what the next caller gets."""
    return _crop_mesh(name, float(growth), float(leaf_length), float(leaf_droop)).copy()


@lru_cache(maxsize=256)
def _crop_mesh(name: str, growth: float, leaf_length: float = 1.0, leaf_droop: float = 1.0) -> Any:
    if not 0.0 <= growth <= 1.0:
        raise InputError("crop.growth", growth, "allowed: a number in [0, 1]")
    for field, value in (("leaf_length", leaf_length), ("leaf_droop", leaf_droop)):
        if not 0.0 < value <= 10.0:
            raise InputError(f"crop.{field}", value, "allowed: a factor in (0, 10]")

    def _leaf(
        base: FloatArray, azimuth: float, length: float, width: float, rise: float, droop: float
    ) -> tuple[FloatArray, NDArray[np.int64]]:
        return _leaf_ribbon(base, azimuth, length * leaf_length, width, rise, droop * leaf_droop)

    sp = species(name)
    h, w = float(sp.height(growth)), float(sp.canopy_width(growth))
    parts = sp.model(sp, growth, h, w, _leaf)
    mesh = _mesh(parts)
    mesh.apply_translation([0, 0, -mesh.bounds[0, 2]])
    # Parts are laid out by eye; stretch vertically so the model is exactly its nominal height.
    mesh.apply_scale([1.0, 1.0, h / float(mesh.bounds[1, 2])])
    return mesh


# ----------------------------------------------------------------------------- the models
def _corn(sp: Species, growth: float, h: float, w: float, _leaf: LeafFn) -> Parts:
    """Maize: a stalk, distichous leaves along it, a tassel and an ear late in the season."""
    import trimesh

    parts: Parts = []
    parts.append(
        (
            _stalk(h * (0.85 if growth > 0.75 else 0.7), float(sp.stem_radius(growth)), 0.006),
            DARK,
        )
    )
    n = round(3 + 11 * growth)
    for i in range(n):
        f = (i + 1) / (n + 1)
        az = math.pi * i + 0.25 * math.sin(1.7 * i)  # distichous: leaves alternate sides
        length = w * (0.55 + 0.45 * math.sin(math.pi * min(f + 0.15, 1.0)))
        parts.append(
            (
                _leaf(
                    np.array([0, 0, h * 0.75 * f]),
                    az,
                    length,
                    0.04 + 0.05 * growth,
                    0.9 - 0.4 * growth,
                    0.6 + 0.3 * growth,
                ),
                GREEN,
            )
        )
    if growth > 0.75:  # tassel
        tassel = trimesh.creation.cone(radius=0.04, height=h * 0.15, sections=6)
        tassel.apply_translation([0, 0, h * 0.85])
        parts.append((tassel, (190, 170, 90)))
    if growth > 0.6:  # ear
        ear = trimesh.creation.capsule(radius=0.025, height=0.15, count=[6, 6])
        ear.apply_translation([0.03, 0, h * 0.45])
        parts.append((ear, (200, 190, 110)))
    return parts


def _sunflower(sp: Species, growth: float, h: float, w: float, _leaf: LeafFn) -> Parts:
    """A stalk with spiralled leaves and, from mid-season, the tilted head."""
    import trimesh

    parts: Parts = []
    head_h = h * 0.92
    r0 = float(sp.stem_radius(growth))
    parts.append((_stalk(head_h, r0, min(0.01, r0)), DARK))
    n = round(4 + 10 * growth)
    for i in range(n):
        f = (i + 1) / (n + 1)
        parts.append(
            (
                _leaf(np.array([0, 0, head_h * 0.85 * f]), 2.4 * i, w * 0.45, w * 0.3, 0.4, 0.5),
                GREEN,
            )
        )
    if growth > 0.5:
        head = trimesh.creation.cylinder(radius=0.06 + 0.1 * growth, height=0.04, sections=16)
        head.apply_transform(trimesh.transformations.rotation_matrix(0.8, [0, 1, 0]))
        head.apply_translation([0.05, 0, head_h])
        parts.append((head, (230, 190, 30)))
    return parts


def _tomato(sp: Species, growth: float, h: float, w: float, _leaf: LeafFn) -> Parts:
    """A stalk with foliage blobs around it and, from flowering, fruit."""
    import trimesh

    parts: Parts = []
    r0 = float(sp.stem_radius(growth))
    parts.append((_stalk(h * 0.8, r0, min(0.005, r0)), DARK))
    n = round(3 + 7 * growth)
    for i in range(n):
        f = (i + 1) / (n + 1)
        blob = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        blob.apply_scale([w * 0.3, w * 0.3, h * 0.18])
        az = 2.4 * i
        blob.apply_translation(
            [w * 0.2 * math.cos(az), w * 0.2 * math.sin(az), h * (0.2 + 0.7 * f)]
        )
        parts.append((blob, GREEN))
    if growth > 0.6:
        for i in range(int(2 + 6 * growth)):
            fruit = trimesh.creation.icosphere(subdivisions=1, radius=0.03)
            az = 1.3 * i + 0.5
            fruit.apply_translation(
                [w * 0.3 * math.cos(az), w * 0.3 * math.sin(az), h * (0.25 + 0.06 * i)]
            )
            parts.append((fruit, (210, 40, 30)))
    return parts


def _cabbage(sp: Species, growth: float, h: float, w: float, _leaf: LeafFn) -> Parts:
    """A head on a rosette of broad leaves."""
    import trimesh

    parts: Parts = []
    head = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    head.apply_scale([w * 0.25, w * 0.25, h * 0.45])
    head.apply_translation([0, 0, h * 0.5])
    parts.append((head, (150, 195, 130)))
    n = round(5 + 5 * growth)
    for i in range(n):
        parts.append(
            (
                _leaf(np.array([0, 0, h * 0.15]), 2.4 * i, w * 0.5, w * 0.35, 0.5, 0.6),
                (110, 165, 100),
            )
        )
    return parts


def _weed(sp: Species, growth: float, h: float, w: float, _leaf: LeafFn) -> Parts:
    """A low rosette."""
    parts: Parts = []
    n = 5 + round(4 * growth)
    for i in range(n):
        parts.append(
            (
                _leaf(
                    np.array([0, 0, 0.005]),
                    2 * math.pi * i / n,
                    w * 0.5,
                    w * 0.2,
                    h / max(w * 0.5, 1e-3) * 0.8,
                    0.4,
                ),
                sp.colour,
            )
        )
    return parts


# ----------------------------------------------------------------------------- the catalog
CATALOG: dict[str, Species] = {
    s.name: s
    for s in (
        # Maize stages ≈ 0.3 (early), 1.2 (intermediate), 2.5 m (mature): design.md, "Physical
        # facts".
        Species(
            "corn",
            ("V3", "V6", "V10", "V14", "R1"),
            (0.3, 0.6, 1.2, 1.8, 2.5),
            (0.35, 0.55, 0.8, 0.95, 1.0),
            (0.008, 0.015, 0.020, 0.023, 0.025),
            (70, 140, 50),
            model=_corn,
            mesh_intervals=48,
            planar_leaves=True,
        ),
        Species(
            "tomato",
            ("seedling", "vegetative", "flowering", "fruiting"),
            (0.15, 0.4, 0.8, 1.2),
            (0.2, 0.4, 0.6, 0.7),
            (0.004, 0.008, 0.012, 0.015),
            (60, 120, 45),
            model=_tomato,
            mesh_intervals=12,
        ),
        Species(
            "cabbage",
            ("seedling", "rosette", "heading", "mature"),
            (0.1, 0.2, 0.3, 0.35),
            (0.2, 0.4, 0.6, 0.7),
            (0.03, 0.08, 0.15, 0.20),
            (120, 170, 110),
            model=_cabbage,
            mesh_intervals=6,
        ),
        Species(
            "sunflower",
            ("V4", "V10", "R1", "R5"),
            (0.3, 0.8, 1.5, 2.0),
            (0.3, 0.5, 0.7, 0.8),
            (0.008, 0.015, 0.025, 0.030),
            (80, 130, 40),
            model=_sunflower,
            mesh_intervals=24,
        ),
        Species(
            WEED_SPECIES,
            ("small", "large"),
            (0.05, 0.3),
            (0.08, 0.35),
            (0.0, 0.0),
            (150, 160, 60),
            model=_weed,
            mesh_intervals=6,
        ),
    )
}

#: The species a field can be planted with (``crop.species``): every catalog entry but weeds.
CROP_SPECIES: tuple[str, ...] = tuple(n for n in CATALOG if n != WEED_SPECIES)
