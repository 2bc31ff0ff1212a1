"""The scenario data model: plain arrays and geometry, no simulator and no I/O.

A ``Scenario`` is what ``generate`` makes and ``io.load`` reads back; ``io.save`` writes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray
from .field import enu_to_lonlat
from .geodesy import GeoFrame
from .layout import RowFrame
from .models import UserModel
from .obstacles import Obstacles
from .routes import Route, lane_lines, lane_segments
from .spec import ScenarioSpec
from .terrain import Terrain


@dataclass(frozen=True, eq=False)
class Plants:
    """One entry per plant or weed; orientation R = Rz(yaw)·Ry(pitch)·Rx(roll) (URDF rpy)."""

    x: FloatArray
    y: FloatArray
    z: FloatArray
    roll: FloatArray
    pitch: FloatArray
    yaw: FloatArray
    height: FloatArray
    species: NDArray[np.str_]
    stage: FloatArray  # 1 .. the species' stage count, fractional for continuous growth
    row: NDArray[np.int64]  # row index, -1 for weeds

    def __len__(self) -> int:
        return len(self.x)

    @property
    def xyz(self) -> FloatArray:
        return np.column_stack([self.x, self.y, self.z])

    @property
    def is_weed(self) -> NDArray[np.bool_]:
        return self.row < 0

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True, eq=False)
class Scenario:
    spec: ScenarioSpec
    seed: int
    geo: GeoFrame
    terrain: Terrain
    field: BaseGeometry  # ENU polygon
    rows: RowFrame
    plants: Plants
    route: Route
    info: dict[str, Any] = field(default_factory=dict)
    crop_model: UserModel | None = None  # the user's plant model (crop.model), if any
    obstacles: Obstacles = field(default_factory=Obstacles.empty)  # stones, litter, stalks

    @property
    def lanes(self) -> FloatArray:
        """Planted lane stretches (n, 2, 2) in ENU, start -> end, ordered by centreline.

        A simple field has one stretch per lane centreline (between rows k and k+1), from where
        both rows start to where they end. A hole or a gap in the field splits a centreline into
        several stretches: ``lane_centreline`` says which centreline each belongs to."""
        return lane_lines(self.rows, self.field)

    @property
    def lane_centreline(self) -> NDArray[np.int64]:
        """For each entry of ``lanes``: its centreline k (between rows k and k+1)."""
        return lane_segments(self.rows, self.field)[0]

    @property
    def crop_model_path(self) -> Path | None:
        """The user plant model file to load (``models.load_model``), or None: after ``load``
        it is the copy inside the scenario folder."""
        return None if self.crop_model is None else self.crop_model.path

    @property
    def field_lonlat(self) -> BaseGeometry:
        return enu_to_lonlat(self.field, self.geo)

    def summary(self) -> dict[str, Any]:
        crops_mask = ~self.plants.is_weed
        return {
            "name": self.spec.name,
            "seed": self.seed,
            "datum": f"{self.geo.lat:.6f}, {self.geo.lon:.6f}, {self.geo.alt:.1f} m",
            "plants": int(crops_mask.sum()),
            "weeds": int((~crops_mask).sum()),
            **({"obstacles": self.obstacles.counts()} if len(self.obstacles) else {}),
            "rows": len(self.rows.offsets),
            "field_area_m2": round(float(self.field.area), 1),
            "relief_m": round(self.terrain.relief, 2),
            **({"slope_deg": self.info["slope_deg"]} if self.info.get("slope_deg") else {}),
            "row_spacing_m": self.spec.layout.row_spacing,
            "plant_spacing_m": self.spec.layout.plant_spacing,
            "grid": f"{self.terrain.shape[1]}x{self.terrain.shape[0]} @ "
            f"{self.terrain.spacing:.3f} m (LoD {self.terrain.lod})",
            "route_m": round(self.route.length, 1),
            **({"crop_model": self.crop_model.name} if self.crop_model else {}),
        }
