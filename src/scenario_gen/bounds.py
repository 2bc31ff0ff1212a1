"""What a scenario may ask for: memory bounds checked before allocating, and the LoD rule.

Every bound is checked from the spec and the field polygon *before* the arrays it limits are
allocated, so an absurd input is refused in milliseconds instead of exhausting memory. The costs
per item were measured on the generator (``benchmarks/bench_bounds.py`` prints them); each
bound keeps its stage under about 1.5 GB:

=========================  ==========  ===============================================
quantity                   bound       cost that sets it
=========================  ==========  ===============================================
plants + weeds             1,000,000   ≈ 0.4 kB to generate, ≈ 1.4 kB to save, each
candidate grid positions   4,000,000   ≈ 0.1 kB each (row x plant grid over the bbox)
terrain samples            10,000,000  ≈ 0.1 kB each (grid, relief, k-NN tree)
route waypoints            2,000,000   ≈ 0.1 kB each (100 km at 5 cm)
DEM pixels read            16,000,000  ≈ 0.1 kB each when the site is searched
=========================  ==========  ===============================================

The LoD rule (``check_lod``): the terrain grid spacing must be at most

* ``layout.row_spacing / 4`` when furrows are on: a sine ridge sampled N times per period keeps,
  in the worst phase, cos(π/N) of its height — 71 % at N = 4, 50 % at 3, nothing at 2;
* ``furrows.roughness_length`` when roughness is on: a Gaussian filter narrower than one sample
  cannot make the correlation length asked for;
* 10 m always: the Bullet manual (the physics engine the envs use) asks for triangles of at
  most about 10 units; on 30 m cells (LoD 12) a 0.6 m robot was seen to fall through the ground.
"""

from __future__ import annotations

import math

from shapely.geometry.base import BaseGeometry

from .errors import InputError
from .geodesy import GSD_Z0, ground_sample_distance
from .spec import ScenarioSpec

MAX_PLANTS = 1_000_000
MAX_CANDIDATES = 4_000_000
MAX_TERRAIN_SAMPLES = 10_000_000
MAX_ROUTE_WAYPOINTS = 2_000_000
MAX_DEM_PIXELS = 16_000_000
MAX_GROUND_SPACING = 10.0  # m: Bullet's triangle-size guidance
#: What a loaded scenario may hold (generation never writes outside these): a grid at least as
#: fine as LoD 22 allows (≈ 0.04 m) but not finer than a millimetre, an origin within 100 km
#: of the datum (a field is local: the ENU tangent plane is ~0.8 m off the ellipsoid there),
#: heights within 10 km of the datum, and plants under 30 m (the catalog's tallest is 2.5 m).
MIN_GROUND_SPACING = 0.001
MAX_ENU_OFFSET_M = 100_000.0
MAX_ENU_HEIGHT_M = 10_000.0
MAX_PLANT_HEIGHT_M = 30.0
RIDGE_SAMPLES = 4  # per row period: worst-case ridge kept cos(pi/4) = 71 %
#: A plane is the tangent plane at its datum; at distance d it lies d²/2R above the ellipsoid
#: (2.0 m at 5 km) and its vertical is tilted by d/R (0.045° at 5 km). Rectangles reach 3.6 km.
MAX_PLANE_RADIUS_M = 5000.0


def grid_bound(spec: ScenarioSpec) -> tuple[float, str]:
    """Largest terrain grid spacing the spec allows, metres, and the reason in words."""
    bounds = [(MAX_GROUND_SPACING, "10 m: Bullet contact on larger triangles is unreliable")]
    f = spec.furrows
    if f.enabled and f.depth > 0:
        bounds.append(
            (
                spec.layout.row_spacing / RIDGE_SAMPLES,
                f"{RIDGE_SAMPLES} samples per {spec.layout.row_spacing:g} m row period keep "
                "at least 71 % of the furrow ridge (furrows.enabled)",
            )
        )
    if f.roughness > 0:
        bounds.append(
            (
                f.roughness_length,
                f"furrows.roughness_length {f.roughness_length:g} m needs samples at most that "
                "far apart",
            )
        )
    return min(bounds)


def min_lod(bound_m: float, lat_deg: float) -> int | None:
    """Smallest Web-Mercator zoom whose spacing at ``lat_deg`` is at most ``bound_m``."""
    lod = max(0, math.ceil(math.log2(GSD_Z0 * math.cos(math.radians(lat_deg)) / bound_m) - 1e-12))
    return lod if lod <= 22 else None


def check_lod(spec: ScenarioSpec, lat_deg: float) -> float:
    """The grid spacing of ``terrain.lod`` at ``lat_deg``, or an error stating the LoD rule."""
    lod = spec.terrain.lod
    spacing = ground_sample_distance(lod, lat_deg)
    bound, why = grid_bound(spec)
    if spacing <= bound * (1 + 1e-9):
        return spacing
    need = min_lod(bound, lat_deg)
    fix = (
        f"use LoD >= {need} at latitude {lat_deg:.2f}°"
        if need is not None
        else "no LoD up to 22 is that fine here: widen the rows or disable furrows"
    )
    raise InputError(
        "terrain.lod",
        lod,
        f"gives a {spacing:.3g} m grid at latitude {lat_deg:.2f}°; allowed: at most "
        f"{bound:.3g} m ({why}); {fix}",
    )


def check_budget(spec: ScenarioSpec, field: BaseGeometry, spacing: float) -> None:
    """Refuse a field whose plants, weeds, terrain or route would exceed the memory bounds."""
    lay = spec.layout
    xmin, ymin, xmax, ymax = field.bounds
    m = spec.terrain.margin
    samples = (math.floor((xmax - xmin + 2 * m) / spacing) + 2) * (
        math.floor((ymax - ymin + 2 * m) / spacing) + 2
    )
    if samples > MAX_TERRAIN_SAMPLES:
        raise InputError(
            "terrain.lod",
            spec.terrain.lod,
            f"gives {samples:,} terrain samples ({spacing:.3g} m over the field and "
            f"terrain.margin); allowed: at most {MAX_TERRAIN_SAMPLES:,} (lower the LoD, the "
            "margin or the field)",
        )
    area = float(field.area)
    plants = area / (lay.row_spacing * lay.plant_spacing)
    if plants > MAX_PLANTS:
        raise InputError(
            "layout.plant_spacing/row_spacing",
            (lay.plant_spacing, lay.row_spacing),
            f"would plant about {plants:,.0f} plants on {area:,.0f} m²; allowed: at most "
            f"{MAX_PLANTS:,} plants and weeds (coarser spacing or a smaller field)",
        )
    weeds = lay.weed_density * area
    if plants + weeds > MAX_PLANTS:
        raise InputError(
            "layout.weed_density",
            lay.weed_density,
            f"would add about {weeds:,.0f} weeds to {plants:,.0f} plants; allowed: at most "
            f"{MAX_PLANTS:,} plants and weeds in all",
        )
    r = spec.route
    diag = math.hypot(xmax - xmin, ymax - ymin)
    rows = diag / lay.row_spacing + 1
    lanes = min(r.lanes, rows)
    along = diag if lay.row_geometry == "straight" else 0.5 * math.pi * diag  # an arc's chord
    turn = math.pi * lay.row_spacing
    if r.turn != "semicircle":  # the keyhole, longest, turns through < 3π at the radius
        turn = 3 * math.pi * max(r.turn_radius, lay.row_spacing) + r.footprint[0]
    length = lanes * (along + 2 * r.turn_offset + turn) + 2 * r.lead_in
    waypoints = length / r.spacing
    if waypoints > MAX_ROUTE_WAYPOINTS:
        raise InputError(
            "route.lanes/spacing",
            (r.lanes, r.spacing),
            f"would make a route of up to {length / 1000:,.1f} km = {waypoints:,.0f} waypoints; "
            f"allowed: at most {MAX_ROUTE_WAYPOINTS:,} waypoints (fewer lanes or a coarser "
            "route.spacing)",
        )
