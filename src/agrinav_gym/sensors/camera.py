"""What every camera shares: the frame it returns, the field it looks at, and the one interface
(``Camera``) both the proxy camera (``depth.DepthCamera``) and the mesh camera
(``mesh_camera.MeshCamera``) implement, so the env and the tools never ask which one they hold.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from scenario_gen import Scenario, Terrain
from scenario_gen.arrays import FloatArray

from ..config import CameraConfig
from ..interface import CameraModel
from ..render.mesh_scene import MeshScene, SceneCache
from ..render.proxy_plants import PlantField

if TYPE_CHECKING:
    from typing import Any


@dataclass
class DepthFrame:
    depth: NDArray[np.float32]  # (H, W) metres, 0 = invalid
    label: NDArray[np.uint8] | None = None  # (H, W) OTHER/SOIL/CROP/WEED(/ROBOT)
    rgb: NDArray[np.uint8] | None = None  # (H, W, 3)
    # mesh camera only: plant index (row of plants.csv) per depth pixel, -1 elsewhere, and
    # the labels of the colour camera's own pixels (RGB is seen from the colour camera)
    instance: NDArray[np.int32] | None = None
    rgb_label: NDArray[np.uint8] | None = None
    rgb_instance: NDArray[np.int32] | None = None


class FieldView:
    """One scenario as the cameras see it: its terrain, the proxy plants and the crop meshes,
    each built on first use (a proxy camera never builds the meshes, nor a mesh camera the
    proxies). ``plants`` and ``scenes`` reuse what the caller already holds."""

    def __init__(
        self,
        scenario: Scenario,
        plants: PlantField | None = None,
        scenes: SceneCache | None = None,
    ) -> None:
        self.scenario = scenario
        self._plants = plants
        self._scenes = scenes if scenes is not None else SceneCache()

    @property
    def terrain(self) -> Terrain:
        return self.scenario.terrain

    @property
    def proxies(self) -> PlantField:
        if self._plants is None:
            self._plants = PlantField.from_scenario(self.scenario)
        return self._plants

    @property
    def meshes(self) -> MeshScene:
        return self._scenes.get(self.scenario)


class Camera(Protocol):
    """A depth camera on the robot (D455-like): z-depth, and on request RGB and labels."""

    cfg: CameraConfig
    model: CameraModel

    def render(
        self,
        rot: FloatArray,
        pos: FloatArray,
        field: FieldView,
        rng: np.random.Generator | None,
        *,
        rgb: bool = False,
        labels: bool = False,
    ) -> DepthFrame:
        """One frame with base_link at ``pos``, orientation ``rot`` (body -> world); ``rng``
        draws the frame's noise (``None``: noise-free)."""
        ...

    def set_lighting(
        self, soil_rgb: Any | None, azimuth_deg: float, elevation_deg: float
    ) -> None: ...


def corner_pixels(width: int, height: int) -> NDArray[np.int64]:
    """The four corner pixels: a frustum's ground footprint is the hull of the apex and the far
    ends of the corner rays (the projection of a convex pyramid)."""
    return np.array([0, width - 1, (height - 1) * width, height * width - 1], np.int64)
