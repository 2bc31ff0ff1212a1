"""Generation: a spec and a seed in, a ``Scenario`` out, deterministic to the bit (design.md,
"The scenario pipeline")."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from . import crops
from .arrays import FloatArray
from .bounds import (
    MAX_PLANE_RADIUS_M,
    MAX_PLANT_HEIGHT_M,
    MIN_PLANT_HEIGHT_M,
    check_budget,
    check_lod,
    check_plants,
)
from .crops import scaled_by_height
from .drift import apply_drift, drift_phases
from .errors import InputError
from .field import check_field, long_axis_deg, lonlat_to_enu, rectangle
from .fieldfile import read_field
from .furrows import add_relief
from .geodesy import GeoFrame
from .layout import Layout, layout
from .model import Plants, Scenario
from .models import inspect_model
from .obstacles import Obstacles, place_obstacles
from .routes import Route, zigzag
from .rowcurve import row_curve
from .sources import Site, build_terrain, open_site
from .spec import CropSpec, ObstacleSpec, ScenarioSpec, TerrainSpec
from .terrain import Terrain
from .waypoints import note_legs_on_rows, read_gps_waypoints, waypoint_route

#: Independent random streams, one per generation step, spawned from the seed so that changing
#: one parameter (say the weed density) does not reshuffle every other random choice.
#: New streams go at the end: spawned children are indexed, so earlier streams keep their bits.
STREAMS = ("jitter", "gaps", "weeds", "plants", "roughness", "rows", "drift", "obstacles")


def orientation(zx: FloatArray, zy: FloatArray, yaw: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(roll, pitch) that, with ``yaw``, put a plant's z axis on the surface normal.

    With R = Rz(yaw)·Ry(pitch)·Rx(roll), the z axis is Rz(yaw)·(cosφ·sinθ, −sinφ, cosφ·cosθ).
    Matching the normal (−zx, −zy, 1)/‖·‖ expressed in the yaw-rotated frame gives
    θ = atan(−zx′) and φ = atan(zy′·cosθ).
    """
    c, s = np.cos(yaw), np.sin(yaw)
    zxp = zx * c + zy * s
    zyp = -zx * s + zy * c
    pitch = np.arctan(-zxp)
    roll = np.arctan(zyp * np.cos(pitch))
    return roll, pitch


def place_plants(
    lay: Layout,
    terrain: Terrain,
    crop: CropSpec,
    growth: float,
    rng: np.random.Generator,
    nominal: float | None = None,
) -> Plants:
    """Heights, orientation, size and species for a layout, vectorized (design.md, "The
    scenario pipeline"); crops are ``nominal`` metres tall (default: the growth stage's
    height) before the height spread."""
    z, zx, zy = terrain.idw(lay.x, lay.y)
    sp = crops.species(crop.species)
    n, weed = len(lay.x), lay.is_weed
    spread = np.clip(rng.standard_normal(n), -3.0, 3.0) * crop.height_std
    weed_sp = crops.CATALOG[crops.WEED_SPECIES]
    weed_growth = rng.random(n)
    yaw = rng.uniform(-math.pi, math.pi, n)
    crop_h = float(sp.height(growth)) if nominal is None else float(nominal)
    height = np.where(weed, weed_sp.height(weed_growth), crop_h * (1 + spread))
    stage = np.where(weed, weed_sp.stage_of_growth(weed_growth), float(sp.stage_of_growth(growth)))
    roll, pitch = orientation(zx, zy, yaw)
    return Plants(
        lay.x,
        lay.y,
        z,
        roll,
        pitch,
        yaw,
        height,
        np.where(weed, crops.WEED_SPECIES, sp.name).astype(str),
        stage,
        lay.row,
    )


def _check_native_height(height: float, height_std: float) -> None:
    """A model kept at its own size makes plants of its height (± 3 height_std): within what a
    scenario may hold, or the folder written would not load."""
    lo, hi = MIN_PLANT_HEIGHT_M / (1 - 3 * height_std), MAX_PLANT_HEIGHT_M / (1 + 3 * height_std)
    if not lo <= height <= hi:
        raise InputError(
            "crop.model",
            f"{height:.4g} m tall as read",
            f"with crop.model_scale native (and height_std {height_std:g}) allowed: a model "
            f"{lo:.3g}..{hi:.3g} m tall (a file in millimetres or centimetres? "
            "crop.model_scale stage scales it to the growth stage's height)",
        )


#: The fields ``check_spec`` relates to one another (keep in step with it): a randomization is
#: checked over the extremes of each group's fields together, every other field alone.
COUPLED_FIELDS: tuple[frozenset[str], ...] = (
    frozenset({"crop.species", "crop.stage"}),
    frozenset({"terrain.datum", "terrain.source"}),
    frozenset({"layout.jitter_lateral", "layout.row_spacing", "layout.drift_amplitude"}),
    frozenset({"layout.jitter_longitudinal", "layout.plant_spacing"}),
)


def check_spec(spec: ScenarioSpec) -> None:
    """Cross-field checks that need no terrain or files (each field alone was checked when the
    spec was built): an env validates randomization ranges with this before any reset."""
    if not isinstance(spec, ScenarioSpec):
        raise InputError(
            "spec",
            spec,
            "allowed: a ScenarioSpec (scenario_gen.preset(NAME) for a preset, "
            "ScenarioSpec.from_dict for a mapping)",
        )
    name = spec.name
    if not (0 < len(name) <= 100 and name.isprintable() and "--" not in name):
        # the name goes into XML comments (where "--" is illegal), YAML comments and file
        # headers: one printable line keeps every export well-formed
        raise InputError(
            "name", name, "allowed: 1-100 printable characters on one line, without '--'"
        )
    sp = crops.species(spec.crop.species)
    if spec.crop.stage > sp.stages:
        raise InputError(
            "crop.stage",
            spec.crop.stage,
            f"allowed: 1..{sp.stages} for {sp.name} ({', '.join(sp.stage_names)})",
        )
    t = spec.terrain
    if t.datum is not None and t.source in ("embedded", "dem"):
        raise InputError(
            "terrain.datum",
            list(t.datum),
            f"is not used with terrain.source={t.source}: a DEM fixes the datum at the field "
            "centre; allowed: null, or terrain.source mesh or plane",
        )
    if spec.field.layer is not None and spec.field.geojson is None:
        raise InputError(
            "field.layer", spec.field.layer, "names a layer of field.geojson, which is not set"
        )
    lay = spec.layout
    lo, hi = lay.curve_radius
    if lo > hi:
        raise InputError("layout.curve_radius", [lo, hi], "allowed: [low, high] with low <= high")
    for key in ("stone_size", "litter_size"):
        lo, hi = getattr(spec.obstacles, key)
        if lo > hi:
            raise InputError(f"obstacles.{key}", [lo, hi], "allowed: [low, high] with low <= high")
    # Jitter is clipped at 3 std: within half a spacing, no plant can pass the midpoint to its
    # neighbouring row (or position), so every plant's row stays what the layout says.
    for name, std, spacing in (
        ("jitter_lateral", lay.jitter_lateral, lay.row_spacing),
        ("jitter_longitudinal", lay.jitter_longitudinal, lay.plant_spacing),
    ):
        if 3 * std > spacing / 2 + 1e-12:
            which = "row_spacing" if name == "jitter_lateral" else "plant_spacing"
            raise InputError(
                f"layout.{name}",
                std,
                f"allowed: at most layout.{which}/6 = {spacing / 6:.4g} m (the 3-std clip must "
                f"stay within half the {spacing:g} m spacing)",
            )
    # Drift moves a whole row: with the jitter's clip it must stay within half a row spacing of
    # its logged line, so that no plant reaches the next lane's centre.
    if lay.drift_amplitude + 3 * lay.jitter_lateral > lay.row_spacing / 2 + 1e-12:
        room = lay.row_spacing / 2 - 3 * lay.jitter_lateral
        raise InputError(
            "layout.drift_amplitude",
            lay.drift_amplitude,
            f"allowed: at most layout.row_spacing/2 - 3 layout.jitter_lateral = {room:.4g} m",
        )


def check_fields_used(spec: ScenarioSpec) -> None:
    """Refuse a terrain field the spec's source or site does not read (a user who set it
    expects it to move the terrain). For the spec a user gives, not for a randomization's
    draws: drawing ``terrain.site`` and ``terrain.max_slope_deg`` together is a valid range
    even where a draw's site does not read the slope."""
    t, field_file = spec.terrain, spec.field.geojson is not None
    default = TerrainSpec()
    dem = t.source in ("embedded", "dem")
    unused: list[tuple[str, str]] = []
    if t.site != default.site and not dem:
        why = f"is a DEM's site search; with terrain.source={t.source} terrain.datum places it"
        unused.append(("site", why))
    elif t.site != default.site and field_file:
        unused.append(("site", "is a DEM's site search; a field file fixes the site"))
    for name in ("lat", "lon"):
        if getattr(t, name) is not None and (t.site != "latlon" or not dem):
            where = "terrain.datum" if not dem else "terrain.site=latlon"
            unused.append((name, f"is read with terrain.site=latlon on a DEM only; set {where}"))
    if t.max_slope_deg != default.max_slope_deg and (t.site != "steepest" or not dem):
        unused.append(("max_slope_deg", "bounds terrain.site=steepest on a DEM only"))
    if t.path is not None and t.source not in ("dem", "mesh"):
        unused.append(("path", "is the DEM or mesh file of terrain.source dem or mesh"))
    for name in ("slope_deg", "aspect_deg"):
        if getattr(t, name) != getattr(default, name) and t.source != "plane":
            unused.append((name, "shapes terrain.source=plane only"))
    if t.up_axis != default.up_axis and t.source != "mesh":
        unused.append(("up_axis", "is a terrain mesh's (terrain.source=mesh)"))
    if t.fill_max_pixels != default.fill_max_pixels and t.source != "dem":
        unused.append(("fill_max_pixels", "fills a GeoTIFF DEM's holes (terrain.source=dem)"))
    if unused:
        name, why = unused[0]
        raise InputError(
            f"terrain.{name}",
            getattr(t, name),
            f"is not used with terrain.source={t.source}, site={t.site}: it {why}; allowed: "
            "its default here",
        )


#: the spec's fields that name input files (dotted: section, field)
PATH_KEYS = ("terrain.path", "field.geojson", "crop.model", "route.waypoints")


def input_files(spec: ScenarioSpec) -> dict[str, str]:
    """The input files the spec names (``PATH_KEYS`` that are set), by key."""
    out = {}
    for key in PATH_KEYS:
        section, name = key.split(".")
        value = getattr(getattr(spec, section), name)
        if value is not None:
            out[key] = value
    return out


def resolve_paths(spec: ScenarioSpec) -> ScenarioSpec:
    """The spec with its input files as absolute, resolved paths (so that scenario.json
    regenerates the scenario from any working directory)."""
    over: dict[str, str] = {}
    for key, value in input_files(spec).items():
        try:
            resolved = str(Path(value).expanduser().resolve())
        except (OSError, RuntimeError) as exc:  # a symlink loop, an unreadable parent
            raise InputError(key, value, f"cannot be resolved ({exc})") from None
        if resolved != value:
            over[key] = resolved
    return spec.replace(over) if over else spec


def planting_drift(scn: Scenario) -> FloatArray:
    """The drift phases ``scn``'s rows were planted with (``drift.lane_error`` reads them):
    the ``drift`` stream's first draw, as ``generate`` made it."""
    return drift_phases(len(scn.rows.offsets), scn.spec.layout, streams(scn.seed)["drift"])


def streams(seed: int) -> dict[str, np.random.Generator]:
    """One independent generator per generation step (``STREAMS``), spawned from ``seed``."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
        raise InputError("seed", seed, "allowed: an integer in [0, 2**63)")
    children = np.random.SeedSequence(int(seed)).spawn(len(STREAMS))
    return dict(zip(STREAMS, (np.random.default_rng(s) for s in children), strict=True))


@dataclass(frozen=True)
class FieldPlan:
    """Where the field lies before any terrain is sampled: the site, the ENU field polygon, the
    row direction and the extent of the terrain grid (field plus margin)."""

    site: Site
    poly: Polygon | MultiPolygon
    angle: float  # rad, counter-clockwise from east
    bounds: tuple[float, float, float, float]


SiteOpener = Callable[[TerrainSpec, "BaseGeometry | None", float, float], Site]


def plan_field(
    spec: ScenarioSpec, field_ll: BaseGeometry | None, opener: SiteOpener = open_site
) -> FieldPlan:
    """Open the site and place the field (a lon/lat polygon, or the spec's rectangle).

    ``generate`` and the studio's live preview both call this, so the preview puts the field,
    the rows and the plants exactly where generation will; ``opener`` lets a caller cache sites.
    """
    if (
        field_ll is not None
        and spec.terrain.source in ("embedded", "dem")
        and spec.terrain.site == "latlon"
    ):
        raise InputError(
            "terrain.site",
            "latlon",
            "a field file fixes the site; leave terrain.site at its default",
        )
    m = spec.terrain.margin
    diag = math.hypot(spec.field.width, spec.field.length) + 2 * m
    site = opener(spec.terrain, field_ll, diag, m)
    if field_ll is not None:
        if spec.terrain.source == "plane":  # before the field is drawn on it
            check_on_plane(field_ll, spec.terrain, site.geo)
        poly = check_field(lonlat_to_enu(field_ll, site.geo), "field.geojson")
        default_angle = long_axis_deg(poly)
    else:
        poly = check_field(rectangle(spec.field, site.centre), "field")
        default_angle = spec.field.angle_deg
    check_plants(spec, poly)
    spacing = check_lod(spec, site.geo.lat, poly)
    check_budget(spec, poly, spacing)
    angle = math.radians(
        spec.layout.row_angle_deg if spec.layout.row_angle_deg is not None else default_angle
    )
    xmin, ymin, xmax, ymax = poly.bounds
    return FieldPlan(site, poly, angle, (xmin - m, ymin - m, xmax + m, ymax + m))


def growth_of(crop: CropSpec) -> float:
    """The crop's continuous growth in [0, 1]: ``crop.growth``, or that of ``crop.stage``."""
    sp = crops.species(crop.species)
    return float(crop.growth if crop.growth is not None else sp.growth_of_stage(crop.stage))


def generate(spec: ScenarioSpec, seed: int) -> Scenario:
    """Build the scenario ``spec`` describes; the same (spec, seed) gives the same bits.

    Every input is checked, and every memory bound estimated, before the large arrays are made.
    """
    rng = streams(seed)
    check_spec(spec)
    spec = resolve_paths(spec)
    t_start = time.perf_counter()
    growth = growth_of(spec.crop)
    user_model = (
        inspect_model(spec.crop.model, spec.crop.model_scale, spec.crop.model_up_axis)
        if spec.crop.model is not None
        else None
    )
    if user_model is not None and user_model.scale == "native":
        _check_native_height(user_model.size[2], spec.crop.height_std)
    field_ll = read_field(spec.field.geojson, spec.field.layer) if spec.field.geojson else None
    plan = plan_field(spec, field_ll)
    site, poly = plan.site, plan.poly
    base = build_terrain(site, plan.bounds, spec.terrain.lod)

    curve = row_curve(spec.layout, poly, plan.angle, plan.bounds, site.heights, rng["rows"])
    lay = layout(poly, spec.layout, plan.angle, rng["jitter"], rng["gaps"], rng["weeds"], curve)
    lay = apply_drift(lay, spec.layout, poly, rng["drift"])
    terrain = add_relief(base, lay.rows, lay.planting_area, spec.furrows, rng["roughness"])
    nominal = None  # crop.model_scale "native": the model's own height
    if user_model is not None and user_model.scale == "native":
        nominal = user_model.size[2]
    plants = place_plants(lay, terrain, spec.crop, growth, rng["plants"], nominal)
    lodging = lodge(plants, lay, spec.obstacles.stalk_lodging, rng["obstacles"])
    plants, lay = lodging.plants, lodging.layout  # a fallen plant leaves its place empty
    goals: dict[str, Any] = {}
    if spec.route.waypoints is not None:
        wps = read_gps_waypoints(spec.route.waypoints, "route.waypoints")
        # the file's yaws, kept so that an export writes the user's waypoints back as given
        goals["route_goal_yaw"] = [None if math.isnan(y) else float(y) for y in wps[:, 2]]
        route, goals["route_goals"] = waypoint_route(
            wps,
            site.geo,
            terrain,
            spec.route.spacing,
            lay.rows,
            lay.planting_area,
            "route.waypoints",
            spec.terrain.source,
        )
        crops = np.column_stack([lay.x, lay.y])[~lay.is_weed]
        note_legs_on_rows(route, goals["route_goals"], crops, spec.layout.row_spacing)
    else:
        if spec.layout.rows is not None and spec.layout.rows < 2:  # named, not the field
            raise InputError(
                "layout.rows",
                spec.layout.rows,
                "a lane needs a crop row on each side; allowed: at least 2 (or null: as many "
                "as fit), or a route through route.waypoints",
            )
        crops = np.column_stack([lay.x, lay.y])[~lay.is_weed]
        route = zigzag(lay.rows, spec.route, terrain, poly, crops)
    obstacles = field_obstacles(spec.obstacles, poly, terrain, lodging, route, rng["obstacles"])
    info = {
        "credit": site.credit,
        **site.info,
        "slope_deg": field_slope(base, poly),
        "growth": growth,
        **goals,
        "candidates": lay.candidates,
        "generate_seconds": time.perf_counter() - t_start,
    }
    return Scenario(
        spec, int(seed), site.geo, terrain, poly, lay.rows, plants, route, info, user_model,
        obstacles,
    )  # fmt: skip


SLOPE_NODES = 40_000  # grid nodes field_slope reads at most (a few ms)


def field_slope(base: Terrain, poly: BaseGeometry) -> dict[str, float] | None:
    """The ground's own slope over the field (degrees: median, 90th percentile and maximum over
    the grid nodes inside it), before ridges and roughness: what ``terrain.max_slope_deg``
    does not bound (it caps a coarser DEM window's mean; docs/design.md). None for a field
    that holds no grid node. At most ``SLOPE_NODES`` nodes are read (every k-th row and column):
    a 100,000-plant field's grid holds millions."""
    k = max(1, math.ceil(math.sqrt(base.size / SLOPE_NODES)))
    gx, gy = np.meshgrid(base.xs[::k], base.ys[::k])
    inside = shapely.contains_xy(poly, gx, gy)
    if not inside.any():
        return None
    s = base.slope_deg(gx[inside], gy[inside])
    p50, p90 = np.percentile(s, [50.0, 90.0])
    return {
        "median": round(float(p50), 1),
        "p90": round(float(p90), 1),
        "max": round(float(s.max()), 1),
    }


@dataclass(frozen=True, eq=False)
class Lodging:
    """The plants after lodging (``obstacles.stalk_lodging``): the standing ones, their layout
    and stalk radii, and the fallen crops' bases, stalk radii and heights."""

    plants: Plants
    layout: Layout
    stems: FloatArray
    fallen_xy: FloatArray  # (k, 2)
    fallen_stems: FloatArray
    fallen_heights: FloatArray


def lodge(plants: Plants, lay: Layout, fraction: float, rng: np.random.Generator) -> Lodging:
    """Fell a ``fraction`` of the crop plants (stream ``obstacles``; nothing drawn at 0).

    ``generate`` and the studio's live preview (which places the plants on flat ground: only
    their x/y and heights matter here) both call this, so they lodge the same plants."""
    lodged = _lodged(plants, fraction, rng)
    stems = scaled_by_height(plants.species, plants.stage, plants.height,
                             lambda sp, g: sp.stem_radius(g))  # fmt: skip
    if not lodged.any():
        return Lodging(plants, lay, stems, np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    standing = _without(plants, lodged)
    return Lodging(
        standing,
        replace(lay, x=standing.x, y=standing.y, row=standing.row, is_weed=standing.is_weed),
        stems[~lodged],
        np.column_stack([plants.x, plants.y])[lodged],
        stems[lodged],
        plants.height[lodged],
    )


def field_obstacles(
    spec: ObstacleSpec,
    poly: BaseGeometry,
    terrain: Terrain,
    lodging: Lodging,
    route: Route,
    rng: np.random.Generator,
) -> Obstacles:
    """The field's obstacles around its standing crop, the fallen stalks and the route's
    start (``obstacles.place_obstacles``); shared by ``generate`` and the studio's preview."""
    if spec.stone_density == 0 and spec.litter_density == 0 and not len(lodging.fallen_xy):
        return Obstacles.empty()  # nothing to place: no tree of the crop to build
    p = lodging.plants
    crop = ~p.is_weed
    return place_obstacles(
        spec,
        poly,
        terrain,
        np.column_stack([p.x, p.y])[crop],
        lodging.stems[crop],
        lodging.fallen_xy,
        lodging.fallen_stems,
        lodging.fallen_heights,
        (float(route.xyz[0, 0]), float(route.xyz[0, 1])) if len(route) else None,
        rng,
    )


def _lodged(plants: Plants, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """Which crop plants fell (``obstacles.stalk_lodging``); none drawn when it is 0."""
    out = np.zeros(len(plants), bool)
    if fraction > 0:
        crop = np.flatnonzero(~plants.is_weed)
        out[crop] = rng.random(len(crop)) < fraction
    return out


def _without(plants: Plants, drop: np.ndarray) -> Plants:
    keep = ~drop
    return Plants(**{k: v[keep] for k, v in plants.arrays().items()})


def check_on_plane(field_ll: BaseGeometry, terrain: TerrainSpec, geo: GeoFrame) -> None:
    """A plane is the tangent plane at its datum: a field file's field (lon/lat) must lie near
    it (bounds.py), measured straight-line (east and north alone would fold the far side of the
    Earth back onto the plane)."""
    lonlat = shapely.get_coordinates(field_ll)
    x, y, z = geo.geodetic_to_enu(lonlat[:, 1], lonlat[:, 0], geo.alt)
    reach = float(np.sqrt(x * x + y * y + z * z).max()) + terrain.margin
    if reach > MAX_PLANE_RADIUS_M:
        raise InputError(
            "terrain.datum",
            [geo.lat, geo.lon, geo.alt],
            f"the field and margin reach {reach / 1000:,.1f} km from the plane's datum; allowed: "
            f"within {MAX_PLANE_RADIUS_M / 1000:g} km (the tangent plane rises d²/2R above the "
            "ellipsoid: 2 m at 5 km); leave terrain.datum null to centre the plane on the field "
            "file's field",
        )
