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
from dataclasses import dataclass

from shapely.geometry.base import BaseGeometry

from .errors import InputError
from .geodesy import GSD_Z0, MAX_LOCAL_M, ground_sample_distance
from .schema import field_info
from .spec import ScenarioSpec

MAX_PLANTS = 1_000_000
#: stones, litter and fallen stalks: each is a mesh of up to a few hundred triangles and, in
#: the simulator, a collision body
MAX_OBSTACLES = 20_000
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
MAX_ENU_OFFSET_M = MAX_LOCAL_M
MAX_ENU_HEIGHT_M = 10_000.0
MAX_PLANT_HEIGHT_M = 30.0
#: plants.csv keeps heights to 0.1 mm, which a model kept at a sub-millimetre native size
#: rounds to 0: a plant is at least a centimetre tall
MIN_PLANT_HEIGHT_M = 0.01
RIDGE_SAMPLES = 4  # per row period: worst-case ridge kept cos(pi/4) = 71 %
#: A plane is the tangent plane at its datum; at distance d it lies d²/2R above the ellipsoid
#: (2.0 m at 5 km) and its vertical is tilted by d/R (0.045° at 5 km). Rectangles reach 3.6 km.
MAX_PLANE_RADIUS_M = 5000.0


@dataclass(frozen=True)
class GridRule:
    """A bound the spec sets on the terrain grid spacing, and what else would meet it: the
    spacing-limited field raised to ``factor`` × the spacing, or ``off`` (a setting)."""

    bound: float  # m
    why: str  # what sets it, naming the fields and their values
    field: str | None = None
    factor: float = 1.0
    off: str | None = None

    def others(self, spacing: float) -> list[str]:
        """The other ways to meet the rule at ``spacing`` that the fields' ranges allow."""
        out = []
        if self.field is not None:
            need = self.factor * spacing
            info = field_info(ScenarioSpec, self.field)
            hi = info[1].get("hi") if info is not None and info[1] else None
            if hi is None or need <= hi:
                out.append(f"{self.field} >= {need:.3g} m")
        if self.off is not None:
            out.append(self.off)
        return out


def grid_rules(spec: ScenarioSpec) -> list[GridRule]:
    """Every bound on the terrain grid spacing the spec sets."""
    rules = [GridRule(MAX_GROUND_SPACING, "Bullet's contact is unreliable on larger triangles")]
    f, lay = spec.furrows, spec.layout
    if f.enabled and f.depth > 0:
        rules.append(
            GridRule(
                lay.row_spacing / RIDGE_SAMPLES,
                f"{RIDGE_SAMPLES} samples per layout.row_spacing {lay.row_spacing:g} m row period "
                "keep at least 71 % of the furrow ridge of furrows.enabled",
                "layout.row_spacing",
                RIDGE_SAMPLES,
                "furrows.enabled false",
            )
        )
    if f.roughness > 0:
        rules.append(
            GridRule(
                f.roughness_length,
                f"furrows.roughness_length {f.roughness_length:g} m needs samples at most that "
                "far apart",
                "furrows.roughness_length",
                1.0,
                "furrows.roughness 0",
            )
        )
    return rules


def grid_bound(spec: ScenarioSpec) -> tuple[float, str]:
    """Largest terrain grid spacing the spec allows, metres, and the reason in words."""
    rule = min(grid_rules(spec), key=lambda r: r.bound)
    return rule.bound, rule.why


def min_lod(bound_m: float, lat_deg: float) -> int | None:
    """Smallest Web-Mercator zoom whose spacing at ``lat_deg`` is at most ``bound_m``."""
    lod = max(0, math.ceil(math.log2(GSD_Z0 * math.cos(math.radians(lat_deg)) / bound_m) - 1e-12))
    return lod if lod <= 22 else None


def terrain_samples(spec: ScenarioSpec, field: BaseGeometry, spacing: float) -> int:
    """Terrain grid nodes over the field's bounding box and ``terrain.margin`` at ``spacing``."""
    xmin, ymin, xmax, ymax = field.bounds
    m = spec.terrain.margin
    return (math.floor((xmax - xmin + 2 * m) / spacing) + 2) * (
        math.floor((ymax - ymin + 2 * m) / spacing) + 2
    )


def max_lod(spec: ScenarioSpec, field: BaseGeometry, lat_deg: float) -> int | None:
    """The finest LoD whose terrain stays within ``MAX_TERRAIN_SAMPLES`` (None: not even 0)."""
    for lod in range(22, -1, -1):
        spacing = ground_sample_distance(lod, lat_deg)
        if terrain_samples(spec, field, spacing) <= MAX_TERRAIN_SAMPLES:
            return lod
    return None


def check_lod(spec: ScenarioSpec, lat_deg: float, field: BaseGeometry | None = None) -> float:
    """The grid spacing of ``terrain.lod`` at ``lat_deg``, or one error naming every rule the
    LoD breaks — each bound the spec sets on the spacing (with the fields that set it, their
    values and the LoD or values that meet it) and, given the ``field``, the terrain's size —
    and the range of LoDs that meets them all."""
    lod = spec.terrain.lod
    spacing = ground_sample_distance(lod, lat_deg)
    broken: list[str] = []
    need = 0
    for rule in grid_rules(spec):
        if spacing <= rule.bound * (1 + 1e-9):
            continue
        lo = min_lod(rule.bound, lat_deg)
        need = 23 if lo is None else max(need, lo)
        meet = [f"LoD >= {lo}" if lo is not None else "no LoD up to 22", *rule.others(spacing)]
        broken.append(f"at most {rule.bound:.3g} m ({rule.why}): " + ", or ".join(meet))
    top = None
    if field is not None:
        top = max_lod(spec, field, lat_deg)
        samples = terrain_samples(spec, field, spacing)
        if samples > MAX_TERRAIN_SAMPLES:
            ok = f"LoD <= {top}" if top is not None else "no LoD"
            broken.append(
                f"{samples:,} terrain samples ({spacing:.3g} m over the field and terrain.margin "
                f"{spec.terrain.margin:g} m); allowed: at most {MAX_TERRAIN_SAMPLES:,}: {ok}, "
                "or a smaller margin or field"
            )
    if not broken:
        return spacing
    if need > 22:
        fix = "no LoD is that fine: change a value " + (
            "the rule names" if len(broken) == 1 else "each rule names"
        )
    elif top is not None and need > top:
        fix = (
            f"no LoD meets both: the spacing rules need LoD >= {need}, the terrain's size "
            f"LoD <= {top} (a smaller field or terrain.margin, or relax a rule)"
        )
    elif need and top is not None and top < 22:
        fix = f"use LoD {need}..{top} at latitude {lat_deg:.2f}°"
    elif need:
        fix = f"use LoD >= {need} at latitude {lat_deg:.2f}°"
    else:
        fix = f"use LoD <= {top} at latitude {lat_deg:.2f}° (or a smaller margin or field)"
    rules = "; ".join(f"({i}) {b}" for i, b in enumerate(broken, 1))
    count = "a rule" if len(broken) == 1 else f"{len(broken)} rules"
    raise InputError(
        "terrain.lod",
        lod,
        f"gives a {spacing:.3g} m grid at latitude {lat_deg:.2f}° and breaks {count}: "
        f"{rules}; {fix}",
    )


def check_plants(spec: ScenarioSpec, field: BaseGeometry) -> float:
    """About how many plants the field holds, or an error where its plants and weeds would
    exceed ``MAX_PLANTS``. Checked before the terrain's LoD: what a smaller field mends first
    (a field too large for both is told about its plants, not a LoD that cannot help)."""
    lay = spec.layout
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
    return plants


def check_budget(spec: ScenarioSpec, field: BaseGeometry, spacing: float) -> None:
    """Refuse a field whose plants, weeds, terrain or route would exceed the memory bounds."""
    lay = spec.layout
    xmin, ymin, xmax, ymax = field.bounds
    samples = terrain_samples(spec, field, spacing)
    if samples > MAX_TERRAIN_SAMPLES:  # check_lod with the field has said so with the rest
        raise InputError(
            "terrain.lod",
            spec.terrain.lod,
            f"gives {samples:,} terrain samples ({spacing:.3g} m over the field and "
            f"terrain.margin); allowed: at most {MAX_TERRAIN_SAMPLES:,} (lower the LoD, the "
            "margin or the field)",
        )
    area = float(field.area)
    plants = check_plants(spec, field)
    o = spec.obstacles
    for key, count in (
        ("stone_density", o.stone_density * area),
        ("litter_density", o.litter_density * area),
        ("stalk_lodging", o.stalk_lodging * plants),
    ):
        if count > MAX_OBSTACLES:
            raise InputError(
                f"obstacles.{key}",
                getattr(o, key),
                f"would place about {count:,.0f} obstacles on {area:,.0f} m²; allowed: at most "
                f"{MAX_OBSTACLES:,} of each kind",
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
