"""What an export may be asked to do: one frozen, validated config for every target."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import InputError
from ..schema import from_mapping
from ..schema import param as _f

TARGETS = ("gazebo", "nav2", "gis", "mesh")
MESH_FORMATS = ("glb", "obj", "ply", "dae")

#: Above this many plants the world uses merged tiles. Parsing alone costs libsdformat 12
#: (Gazebo Fortress's parser) ≈60 ms and ≈5 MB per <include> (benchmarks/bench_export.py), and
#: the source paper measured ≈1.45 MB of Gazebo memory per plant model at run time: 1,000
#: plants are ≈1 min and ≈6 GB before the first simulation step.
INCLUDE_LIMIT = 1000


@dataclass(frozen=True)
class ExportOptions:
    plants: str = _f(
        "auto",
        "Gazebo plants: one <include> per plant, merged static tiles, or auto (tiles above "
        "include_limit); the obstacles likewise: one static model each, or merged tiles",
        choices=("auto", "include", "tiles"),
    )
    include_limit: int = _f(
        INCLUDE_LIMIT,
        "auto: the most plants written as includes (and obstacles as models, counted apart)",
        0,
        10**7,
    )
    tile_plants: int = _f(
        1000, "merged tiles hold about this many plants (obstacle tiles: obstacles) each", 1, 10**6
    )
    heightmap: bool = _f(
        False, "Gazebo: also write the terrain as a 16-bit heightmap and a world using it"
    )
    formats: tuple[str, ...] = _f(("glb",), "mesh export: file formats", choices=MESH_FORMATS)
    mesh_plants: bool = _f(
        False,
        "mesh export: also write every plant merged into one mesh and every obstacle as a "
        "named node",
    )
    robot_urdf: str | None = _f(
        None, "nav2: the robot URDF copied into the export and spawned at the route start"
    )
    nav2_robot: dict[str, Any] | None = _f(
        None,
        "nav2: the simulated robot's drive, sensors and EKF model and the benchmarked DWB "
        "configuration (ros_robot.Nav2Robot; the CLI passes baselines.nav2_robot's)",
    )

    def __post_init__(self) -> None:
        if not self.formats or any(f not in MESH_FORMATS for f in self.formats):
            raise InputError(
                "formats", list(self.formats), f"allowed: one or more of {', '.join(MESH_FORMATS)}"
            )

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ExportOptions:
        opts: ExportOptions = from_mapping(cls, data, "")
        return opts

    def use_tiles(self, n_plants: int) -> bool:
        if self.plants == "auto":
            return n_plants > self.include_limit
        return self.plants == "tiles"
