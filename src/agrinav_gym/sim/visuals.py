"""Plant visuals for the GUI and ``rgb_array`` views only, loaded on first render.

Each plant is a low-poly cross (two vertical quads, canopy-wide and plant-tall); plants are
merged into one static visual mesh per tile and species so a whole field costs a few bodies,
never one per plant (design.md, "Measured facts to design around"). Tiles stay under
pybullet's per-mesh vertex cap.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pybullet as p

from scenario_gen import CATALOG, Scenario, Terrain

from ..render.shading import SOIL_RGB

MAX_VERTICES = 100_000  # below pybullet's ≈130k per-mesh cap
_CROSS_X = np.array(
    [[-1, 0, 0], [1, 0, 0], [1, 0, 1], [-1, 0, 1], [0, -1, 0], [0, 1, 0], [0, 1, 1], [0, -1, 1]],
    dtype=np.float64,
)
_CROSS_F = np.array(
    [[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [4, 6, 5], [4, 7, 6]],
    dtype=np.int64,
)


SOIL_RGBA = [*SOIL_RGB, 1.0]


def load_terrain_visual(client: int, scn: Scenario, max_vertices: int = 60_000) -> int:
    """The terrain as a soil-coloured visual mesh (physics uses the heightfield patch)."""
    t = scn.terrain
    ny, nx = t.shape
    step = max(1, int(np.ceil(np.sqrt(nx * ny / max_vertices))))
    coarse: Any = Terrain(t.heights[::step, ::step], t.x0, t.y0, t.spacing * step).to_trimesh()
    verts, faces = np.asarray(coarse.vertices), np.asarray(coarse.faces)
    vs = p.createVisualShape(
        p.GEOM_MESH,
        vertices=verts.tolist(),
        indices=faces.ravel().tolist(),
        rgbaColor=SOIL_RGBA,
        physicsClientId=client,
    )
    return int(p.createMultiBody(0, -1, vs, physicsClientId=client))


def load_plant_visuals(client: int, scn: Scenario) -> int:
    """Create the merged plant meshes; returns how many bodies were added."""
    pl = scn.plants
    if len(pl) == 0:
        return 0
    p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 0, physicsClientId=client)
    per = MAX_VERTICES // len(_CROSS_X)
    bodies = 0
    for name in np.unique(pl.species):
        sp = CATALOG[str(name)]
        idx = np.flatnonzero(pl.species == name)
        growth = sp.growth_of_stage(pl.stage[idx])
        # crosses narrower than the leaf span, so the lane (and the robot in it) stays in view
        half = 0.3 * sp.canopy_width(growth) * pl.height[idx] / np.maximum(sp.height(growth), 1e-6)
        colour = [c / 255 for c in sp.colour] + [1.0]
        for start in range(0, len(idx), per):
            sel = idx[start : start + per]
            h = half[start : start + per]
            c, s = np.cos(pl.yaw[sel]), np.sin(pl.yaw[sel])
            local = _CROSS_X[None] * np.stack([h, h, pl.height[sel]], axis=1)[:, None, :]
            x = pl.x[sel, None] + c[:, None] * local[..., 0] - s[:, None] * local[..., 1]
            y = pl.y[sel, None] + s[:, None] * local[..., 0] + c[:, None] * local[..., 1]
            z = pl.z[sel, None] + local[..., 2]
            verts = np.stack([x, y, z], axis=-1).reshape(-1, 3)
            faces = _CROSS_F[None] + len(_CROSS_X) * np.arange(len(sel))[:, None, None]
            vs = p.createVisualShape(
                p.GEOM_MESH,
                vertices=verts.tolist(),
                indices=faces.ravel().tolist(),
                rgbaColor=colour,
                physicsClientId=client,
            )
            p.createMultiBody(0, -1, vs, physicsClientId=client)
            bodies += 1
    p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 1, physicsClientId=client)
    return bodies
