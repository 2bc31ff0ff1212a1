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

Obstacles (``scenario_gen.obstacles``) get stand-ins of the same vertical cylinders, so the
kernel needs nothing new (``obstacle_cylinders``): a stone or a piece of litter is one cylinder
of its footprint's area and its vertical extent, a fallen stalk a chain of short cylinders of
its radius along its length, no farther apart than its diameter (neighbours touch or overlap,
so no ray passes between them). They follow the plants' cylinders and are labelled
``OBSTACLE``; a field without obstacles has exactly the cylinders it had before.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from scenario_gen import CATALOG, Scenario
from scenario_gen.arrays import FloatArray
from scenario_gen.crops import WEED_SPECIES
from scenario_gen.models import model_shape
from scenario_gen.obstacles import STALK, Obstacles

from .proxy_params import ParamsFn, check_planting, proxy_params


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
    # cylinders [0, n_plants) are the plants' cores, then leaf bands, then obstacle stand-ins
    n_plants: int
    # per cylinder: the obstacle it stands in for (row of obstacles.csv), -1 for a plant's;
    # None: no obstacles
    obstacle: NDArray[np.int64] | None = None

    @classmethod
    def from_scenario(
        cls, scn: Scenario, params: ParamsFn | None = None, planting: str = "ridged"
    ) -> PlantField:
        """The proxies of ``scn``'s plants; ``params(species, growth)`` gives (fill, base, reach)
        (default: ``proxy_params`` from the table fitted on ``planting``, or the user model's
        own shape)."""
        check_planting(planting)
        user = (
            model_shape(scn.crop_model) if scn.crop_model is not None and params is None else None
        )
        if params is None:
            params = functools.partial(proxy_params, planting=planting)
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
        bottom = np.concatenate([p.z, p.z[band] + base[band]])
        top = np.concatenate([p.z + p.height, p.z[band] + p.height[band]])
        weed = np.concatenate([p.is_weed, np.zeros(len(band), bool)])
        owner = None
        if len(scn.obstacles):
            o_xy, o_bottom, o_top, o_radius, o_owner = obstacle_cylinders(scn.obstacles)
            cyl_xy = np.concatenate([cyl_xy, o_xy])
            cyl_radius = np.concatenate([cyl_radius, o_radius])
            bottom = np.concatenate([bottom, o_bottom])
            top = np.concatenate([top, o_top])
            weed = np.concatenate([weed, np.zeros(len(o_owner), bool)])
            owner = np.concatenate([np.full(len(cyl_xy) - len(o_owner), -1), o_owner])
        tree = cKDTree(cyl_xy if len(cyl_xy) else np.zeros((1, 2)))
        return cls(
            cyl_xy,
            bottom,
            top,
            cyl_radius,
            weed,
            tree,
            float(cyl_radius.max()) if len(cyl_radius) else 0.0,
            len(p),
            owner,
        )

    @property
    def is_obstacle(self) -> NDArray[np.bool_]:
        """Per cylinder: whether it stands in for an obstacle."""
        if self.obstacle is None:
            return np.zeros(len(self.radius), bool)
        return np.asarray(self.obstacle >= 0)

    def __len__(self) -> int:
        return self.n_plants


def obstacle_cylinders(
    obs: Obstacles,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.int64]]:
    """Vertical cylinders standing in for ``obs``: centres (m, 2), bottoms, tops, radii and the
    obstacle each stands for.

    A stone or a piece of litter: one cylinder around its footprint's centroid whose disc has
    the area of its footprint (the convex hull of its mesh seen from above), from its mesh's
    lowest point (a stone's buried part, so no ground shows under its rim on a slope) to its
    highest. A fallen stalk: cylinders of its radius (width / 2) centred on its axis every
    ``length / k`` with k the fewest steps no longer than its diameter, each spanning the
    stalk's cross-section there (axis height ± height / 2).
    """
    xy: list[FloatArray] = []
    lo: list[FloatArray] = []
    hi: list[FloatArray] = []
    rad: list[FloatArray] = []
    own: list[NDArray[np.int64]] = []
    for i in range(len(obs)):
        if str(obs.kind[i]) == STALK:
            length, dia = float(obs.length[i]), float(obs.width[i])
            k = max(1, math.ceil(length / max(dia, 1e-6)))
            s = np.linspace(-0.5 * length, 0.5 * length, k + 1)
            half = 0.5 * float(obs.height[i])
            # the axis in the stalk's frame: along x, half its height above the ground
            axis = np.column_stack([s, np.zeros_like(s), np.full_like(s, half)])
            pts = axis @ obs.rotation(i).T + np.array([obs.x[i], obs.y[i], obs.z[i]])
            xy.append(pts[:, :2])
            lo.append(pts[:, 2] - half)
            hi.append(pts[:, 2] + half)
            rad.append(np.full(len(s), 0.5 * dia))
            own.append(np.full(len(s), i, np.int64))
            continue
        v, _ = obs.mesh(i)
        hull = shapely.MultiPoint(v[:, :2]).convex_hull
        c = hull.centroid
        xy.append(np.array([[c.x, c.y]]))
        lo.append(np.array([v[:, 2].min()]))
        hi.append(np.array([v[:, 2].max()]))
        rad.append(np.array([math.sqrt(hull.area / math.pi)]))
        own.append(np.array([i], np.int64))
    return (
        np.concatenate(xy),
        np.concatenate(lo),
        np.concatenate(hi),
        np.concatenate(rad),
        np.concatenate(own),
    )
