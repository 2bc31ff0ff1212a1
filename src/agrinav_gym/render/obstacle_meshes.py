"""Obstacles (stones, litter, fallen stalks) as the mesh camera sees them: real triangles.

Obstacles are few (tens to a few thousand per field) and each has a shape of its own, so
nothing is shared between them: each obstacle's mesh (``Obstacles.mesh``, ENU) becomes one
``Prototype`` whose vertices are already in scene coordinates (ENU minus the scene's origin,
float32: the same triangles for Embree and the rasteriser) and whose placement is the identity.
``MeshScene`` puts them all in one static Embree scene (geometry id = obstacle index) and hands
them to the rasteriser as slots of their own; the label is ``OBSTACLE`` and the instance id
the obstacle's row in obstacles.csv.

Colours (assumed, for a plausible RGB image, not measured): stones grey-brown, each stone its
own shade and each face a little darker or lighter (the facets of a rough stone); litter one
bright plastic colour per item; stalks straw to dry-leaf brown. Each is drawn from the
obstacle's own ``shape`` seed and index, so the same field looks the same every time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray
from scenario_gen.obstacles import LITTER, STONE, Obstacles

from .classes import OBSTACLE
from .plant_meshes import Prototype

#: linear RGB in [0, 1]: a stone's base colour and the spread of its shade
STONE_RGB = np.array([0.47, 0.43, 0.38])
STONE_SHADE = 0.18  # ± relative, per stone
STONE_FACET = 0.06  # ± relative, per face
#: saturated plastic colours (bags, bottles, wrap, twine)
LITTER_RGB = np.array(
    [
        [0.85, 0.12, 0.10],  # red
        [0.10, 0.35, 0.85],  # blue
        [0.95, 0.80, 0.10],  # yellow
        [0.95, 0.45, 0.05],  # orange
        [0.93, 0.93, 0.90],  # white
        [0.10, 0.60, 0.55],  # teal
        [0.80, 0.20, 0.60],  # magenta
    ]
)
#: a fallen stalk: between dry straw and a browned leaf
STALK_STRAW = np.array([0.78, 0.68, 0.42])
STALK_DRY = np.array([0.55, 0.44, 0.26])


def obstacle_colour(obs: Obstacles, i: int, n_faces: int) -> NDArray[np.uint8]:
    """(n_faces, 3) 8-bit face colours of obstacle ``i`` (module docstring)."""
    kind = str(obs.kind[i])
    rng = np.random.default_rng([int(obs.shape[i]), i])
    if kind == STONE:
        base = STONE_RGB * (1.0 + STONE_SHADE * rng.uniform(-1.0, 1.0))
        faces = base[None, :] * (1.0 + STONE_FACET * rng.uniform(-1.0, 1.0, (n_faces, 1)))
    elif kind == LITTER:
        faces = np.tile(LITTER_RGB[int(rng.integers(len(LITTER_RGB)))], (n_faces, 1))
    else:
        a = rng.uniform()
        faces = np.tile((1.0 - a) * STALK_STRAW + a * STALK_DRY, (n_faces, 1))
    return np.asarray(np.round(np.clip(faces, 0.0, 1.0) * 255.0), np.uint8)


@dataclass(frozen=True, eq=False)
class ObstacleMeshes:
    """One prototype per obstacle, its vertices in scene coordinates (ENU − ``origin``)."""

    prototypes: tuple[Prototype, ...]
    x: FloatArray  # the footprint centres (ENU), for choosing those near a view
    y: FloatArray
    reach: float  # farthest any obstacle's geometry reaches horizontally from (x, y), m

    @classmethod
    def of(cls, obs: Obstacles, origin: FloatArray) -> ObstacleMeshes:
        protos = []
        reach = 0.0
        o = np.asarray(origin, np.float64)
        for i in range(len(obs)):
            v, f = obs.mesh(i)
            a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
            n = np.cross(b - a, c - a)  # outward: the faces are wound counter-clockwise
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
            r = float(np.hypot(v[:, 0] - obs.x[i], v[:, 1] - obs.y[i]).max())
            reach = max(reach, r)
            protos.append(
                Prototype(
                    name=f"{obs.kind[i]}#{i}",
                    vertices=np.ascontiguousarray(v - o, np.float32),
                    faces=np.ascontiguousarray(f, np.uint32),
                    face_rgb=obstacle_colour(obs, i, len(f)),
                    normals=n.astype(np.float32),
                    uv=None,
                    texture=None,
                    height=float(v[:, 2].max() - v[:, 2].min()),
                    radius=r,
                    label=OBSTACLE,
                )
            )
        return cls(tuple(protos), np.asarray(obs.x, float), np.asarray(obs.y, float), reach)

    def __len__(self) -> int:
        return len(self.prototypes)
