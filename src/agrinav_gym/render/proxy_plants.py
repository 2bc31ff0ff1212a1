"""Plants as analytic proxies: no pybullet body per plant.

The depth camera intersects vertical cylinders: every plant has a core from the ground to its
top, and species with planar leaves (maize) add a leaf band above the bare lower stalk whose
reach into the inter-row follows the leaf plane's azimuth (the plant's yaw) against the row, so
a tall crop's leaves close over the lane at the camera's height, as in the field. The core's
radius, the band's base and its reach are fitted to the crop meshes per species and growth
stage (``proxy_params``; docs/camera.md), not chosen by hand. A scenario with a user
``crop.model`` draws its crops with the shape measured from that model when the scenario was
generated (``scenario_gen.model_shape``): core, band base and the band's radii along the
model's own axes, so the band's reach across the row follows each plant's yaw.
Per plant this holds a handful of floats plus its KD-tree node: a few hundred bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from scenario_gen import CATALOG, Scenario
from scenario_gen.arrays import FloatArray
from scenario_gen.crops import WEED_SPECIES
from scenario_gen.models import model_shape

from .proxy_params import ParamsFn, proxy_params


@dataclass(frozen=True, eq=False)
class PlantField:
    # visible cylinders (depth camera): plant i's core is cylinder i, leaf bands follow
    xy: FloatArray  # (m, 2)
    z: FloatArray  # cylinder bottom
    top: FloatArray  # cylinder top
    radius: FloatArray
    is_weed: NDArray[np.bool_]
    tree: cKDTree
    max_radius: float
    n_plants: int  # cylinders [0, n_plants) are the plants' cores, the rest leaf bands

    @classmethod
    def from_scenario(cls, scn: Scenario, params: ParamsFn | None = None) -> PlantField:
        """The proxies of ``scn``'s plants; ``params(species, growth)`` gives (fill, base, reach)
        (default: the fitted ``proxy_params``, or the user model's own shape)."""
        user = (
            model_shape(scn.crop_model) if scn.crop_model is not None and params is None else None
        )
        params = params or proxy_params
        p = scn.plants
        names = np.unique(p.species)
        radius = np.empty(len(p))
        leaf = np.empty(len(p))
        base = np.empty(len(p))
        # fraction of the leaf plane's reach that points across the rows
        across = np.abs(np.sin(p.yaw - scn.rows.direction_at(p.x, p.y)))
        for name in names:
            sp = CATALOG[str(name)]
            m = p.species == name
            if user is not None and name != WEED_SPECIES:  # the crops are the user's model
                h = p.height[m]
                turn = p.yaw[m] - scn.rows.angle
                radius[m] = user.core * h
                leaf[m] = user.band(np.sin(turn), np.cos(turn)) * h
                base[m] = user.base * h
                continue
            growth = sp.growth_of_stage(p.stage[m])
            scale = p.height[m] / np.maximum(sp.height(growth), 1e-6)
            width = sp.canopy_width(growth) * scale
            fill, frac, reach = params(str(name), growth)
            radius[m] = fill * width
            leaf[m] = 0.5 * reach * width * across[m] if sp.planar_leaves else 0.0
            base[m] = frac * p.height[m]
        xy = np.column_stack([p.x, p.y]).astype(np.float64)
        band = np.flatnonzero((leaf > radius) & ~p.is_weed)
        cyl_xy = np.concatenate([xy, xy[band]])
        cyl_radius = np.concatenate([radius, leaf[band]])
        tree = cKDTree(cyl_xy if len(cyl_xy) else np.zeros((1, 2)))
        return cls(
            cyl_xy,
            np.concatenate([p.z, p.z[band] + base[band]]),
            np.concatenate([p.z + p.height, p.z[band] + p.height[band]]),
            cyl_radius,
            np.concatenate([p.is_weed, np.zeros(len(band), bool)]),
            tree,
            float(cyl_radius.max()) if len(cyl_radius) else 0.0,
            len(p),
        )

    def __len__(self) -> int:
        return self.n_plants
