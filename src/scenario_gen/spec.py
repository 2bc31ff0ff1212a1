"""Declarative scenario specification: frozen, typed, validated; YAML in, YAML/JSON out.

Every field carries its unit and allowed range in its metadata, and ``from_dict`` rejects unknown
keys and bad values with a message that names the dotted field, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

import yaml

from .crops import CROP_SPECIES
from .schema import from_mapping, merge, plain
from .schema import param as _f
from .turns import TURN_TYPES


@dataclass(frozen=True)
class TerrainSpec:
    source: str = _f("embedded", "terrain source", choices=("embedded", "dem", "mesh", "plane"))
    path: str | None = _f(
        None, "GeoTIFF DEM (source=dem) or terrain mesh (source=mesh); stored resolved"
    )
    site: str = _f(
        "flattest",
        "how the field centre is chosen on a DEM",
        choices=("flattest", "steepest", "latlon"),
    )
    lat: float | None = _f(None, "site latitude, degrees (site=latlon)", -90, 90)
    lon: float | None = _f(None, "site longitude, degrees (site=latlon)", -180, 180)
    max_slope_deg: float = _f(
        90.0,
        "site=steepest picks the steepest DEM window (at least 3 pixels and the field's size "
        "across) whose mean slope is at most this; the field inside it can be steeper "
        "(the scenario's info.slope_deg measures it)",
        0,
        90,
    )
    datum: tuple[float, float, float] | None = _f(
        None,
        "lat, lon (WGS84 degrees), alt (metres above the WGS84 ellipsoid) of the mesh origin "
        "(source=mesh, required) or of the plane (source=plane; null: the field file's "
        "centroid at 0 m, else 42.6 N 5.57 W 830 m); a DEM fixes its own datum, so "
        "embedded/dem refuse it",
    )
    lod: int = _f(
        20,
        "level of detail: Web-Mercator zoom; sets the grid spacing (at most row_spacing/4 with "
        "furrows, roughness_length with roughness, 10 m always)",
        0,
        22,
    )
    margin: float = _f(8.0, "terrain kept around the field, metres", 0, 1000)
    slope_deg: float = _f(
        0.0,
        "plane: slope, degrees (the env takes less than atan(soil.friction): 31° at 0.6)",
        0,
        60,
    )
    aspect_deg: float = _f(
        0.0, "plane: downhill direction, degrees clockwise from north", -360, 360
    )
    fill_max_pixels: int = _f(64, "DEM nodata holes up to this many pixels are filled", 0, 10**7)
    vertical_unit: str = _f(
        "auto",
        "unit of a GeoTIFF DEM's heights (auto: its vertical CRS's, else its band unit, else "
        "metres; a DEM in a feet CRS that declares neither is refused until this says)",
        choices=("auto", "m", "ft", "us_ft"),
    )
    up_axis: str = _f(
        "auto",
        "mesh up axis (auto: y for glTF/GLB, a COLLADA file's declared up_axis, Y_UP where "
        "none; z otherwise)",
        choices=("auto", "y", "z"),
    )


@dataclass(frozen=True)
class FieldSpec:
    geojson: str | None = _f(
        None,
        "field polygon file: GeoJSON (RFC 7946 lon/lat, or the CRS its crs member names), "
        "GeoPackage, Shapefile or KML (these three need the gis extra: pyogrio) in any CRS "
        "the file declares; its Polygon/MultiPolygon features are merged (holes and parts are "
        "kept unplanted; lanes end at them); stored resolved",
    )
    layer: str | None = _f(
        None,
        "layer of the field file holding the field (null: its only layer, or its only layer "
        "with polygons; a file with several is refused)",
    )
    width: float = _f(30.0, "rectangle size across the rows, metres", 0, 5000, above=True)
    length: float = _f(40.0, "rectangle size along the rows, metres", 0, 5000, above=True)
    angle_deg: float = _f(
        0.0, "rectangle long-side direction, degrees counter-clockwise from east", -360, 360
    )


@dataclass(frozen=True)
class LayoutSpec:
    row_spacing: float = _f(0.75, "distance between crop rows, metres", 0.05, 50)
    plant_spacing: float = _f(0.18, "distance between plants in a row, metres", 0.02, 50)
    rows: int | None = _f(
        None,
        "number of crop rows, centred across the planting area (null: as many as fit)",
        1,
        100_000,
    )
    plants_per_row: int | None = _f(
        None,
        "plant positions per row, centred along the planting area (null: as many as fit)",
        1,
        10_000_000,
    )
    row_angle_deg: float | None = _f(
        None,
        "row direction, degrees counter-clockwise from east (null: along the field)",
        -360,
        360,
    )
    # Planters place seed within ≈1 cm across the row; a 0.616 m robot in 0.75 m rows has
    # 5 cm of clearance per side, so more lateral scatter means crops hit even on the line.
    jitter_lateral: float = _f(
        0.01, "std of plant offset across the row, metres (clipped at 3 std <= row_spacing/2)", 0, 1
    )
    jitter_longitudinal: float = _f(
        0.02,
        "std of plant offset along the row, metres (clipped at 3 std <= plant_spacing/2)",
        0,
        1,
    )
    # Planting drift (scenario_gen/drift.py, docs/localisation.md "Rows off the map"): the
    # planted rows wander off the lines the planter logged; the route and exported rows stay
    # on the logged lines. Off by default.
    drift_amplitude: float = _f(
        0.0,
        "largest lateral offset of a planted row from its logged line, metres (RTK-guided "
        "planter ≈ 0.02-0.05, SBAS or other non-RTK guidance ≈ 0.1-0.3; 0: none; "
        "3 jitter_lateral + drift_amplitude <= row_spacing/2)",
        0,
        1,
    )
    drift_wavelength: float = _f(
        50.0,
        "longest wavelength of the drift along the row, metres (assumed; swept 10-500)",
        1,
        100_000,
    )
    drift_pass_rows: int = _f(
        1,
        "rows planted in one planter pass, which drift together (a planter's row count, e.g. "
        "4-24; 1: every row on its own)",
        1,
        1000,
    )
    gap_prob: float = _f(0.02, "probability that a single plant is missing", 0, 1)
    gap_run_prob: float = _f(0.0, "probability per plant that a run of missing plants starts", 0, 1)
    gap_run_mean: float = _f(4.0, "mean length of a run of missing plants, plants", 1, 10**4)
    weed_density: float = _f(0.0, "weeds per square metre of planted area", 0, 100)
    headland: float = _f(4.0, "unplanted strip at both row ends, metres", 0, 500)
    edge_margin: float = _f(0.3, "unplanted margin along the field edge, metres", 0, 500)
    row_geometry: str = _f(
        "straight",
        "shape of the rows: straight (parallel lines at row_angle_deg), curved (concentric "
        "arcs bending left or right at random, radius from curve_radius) or contour (parallel "
        "to the terrain contour through the field centre); spacing is kept along the normal",
        choices=("straight", "curved", "contour"),
    )
    curve_radius: tuple[float, float] = _f(
        (30.0, 80.0),
        "radius of the tightest row, metres: curved draws it uniformly from [low, high] per "
        "seed; contour rows are straightened where they would curve tighter than low",
        15,
        100_000,
    )


@dataclass(frozen=True)
class CropSpec:
    species: str = _f("corn", "crop species", choices=CROP_SPECIES)
    stage: int = _f(3, "growth stage, 1 (early) .. the species' last stage", 1, 10)
    growth: float | None = _f(None, "continuous growth 0..1 (overrides stage)", 0, 1)
    height_std: float = _f(
        0.08,
        "relative std of plant height between plants (drawn within 3 std: at most 0.3 keeps "
        "every plant above a tenth of the nominal height)",
        0,
        0.3,
    )
    model: str | None = _f(
        None,
        "user plant model: a mesh file (COLLADA, glTF/GLB, OBJ, PLY, STL) with the files it "
        "references (textures, .mtl, .bin), or a .zip of them, at most 50,000 triangles; "
        "copied into the scenario folder (models/)",
    )
    model_scale: str = _f(
        "stage",
        "size of crop.model: 'stage' scales it to the growth stage's height (as the catalog "
        "plants), 'native' keeps the file's own size (metres; COLLADA's unit applied); "
        "height_std varies both",
        choices=("stage", "native"),
    )
    model_up_axis: str = _f(
        "auto",
        "the axis crop.model's file stands along: auto (y for glTF/GLB, as the format says; "
        "a COLLADA file's declared up_axis, Y_UP where none; z otherwise), y (e.g. an OBJ "
        "from Blender's default export), z",
        choices=("auto", "y", "z"),
    )


@dataclass(frozen=True)
class FurrowSpec:
    enabled: bool = _f(
        False,
        "ridge/furrow micro-relief along the rows (ridge-tilled or bedded planting; off: flat "
        "planting, the default — roughness applies either way)",
    )
    depth: float = _f(0.12, "ridge height above the furrow bottom when enabled, metres", 0, 1)
    profile: str = _f("sine", "cross-section of the ridges", choices=("sine", "trapezoid"))
    taper: float = _f(
        1.0, "distance over which relief fades out at the planted edge, metres", 0.01, 100
    )
    roughness: float = _f(0.005, "std of random soil roughness, metres", 0, 0.5)
    roughness_length: float = _f(0.3, "correlation length of the roughness, metres", 0.01, 100)


@dataclass(frozen=True)
class RouteSpec:
    lanes: int = _f(2, "lanes (furrows between adjacent rows) the zigzag route drives", 1, 10**4)
    first_lane: int | None = _f(
        None,
        "index of the first lane among those with crop on both sides (null: centred)",
        0,
        10**6,
    )
    spacing: float = _f(0.05, "waypoint spacing, metres (at most 0.1)", 0.005, 0.1)
    lead_in: float = _f(
        2.0, "headland run before the first lane and after the last, metres", 0, 100
    )
    turn_offset: float = _f(1.0, "how far past the crop the U-turn starts, metres", 0, 100)
    turn: str = _f(
        "semicircle",
        "headland turn between lanes: semicircle (diameter = the lane spacing), omega (bulb: "
        "away, loop, away; forward), keyhole (toward, loop through the neck; forward) or "
        "three_point (forward, reverse, forward: two cusps); all but semicircle keep "
        "turn_radius, start where the swept footprint clears the crop by turn_clearance and "
        "must fit the field",
        choices=TURN_TYPES,
    )
    turn_radius: float = _f(
        0.9,
        "smallest turning radius of the omega, keyhole and three_point turns, metres (0.9: "
        "where Nav2 RPP starts slowing down for curvature)",
        0.1,
        100,
    )
    footprint: tuple[float, float] = _f(
        (0.724, 0.616),
        "robot footprint length and width the turns are sized for, metres (Summit-XL)",
        0.05,
        20,
    )
    turn_clearance: float = _f(
        0.1, "room between the turn's swept footprint and any crop plant, metres", 0, 10
    )
    waypoints: str | None = _f(
        None,
        "Nav2 GPS waypoint YAML ({waypoints: [{latitude, longitude, yaw}]}; an altitude is read "
        "and not used): the route is the straight-leg plan through them instead of the zigzag "
        "(scenario_gen.waypoints); stored resolved",
    )


@dataclass(frozen=True)
class ObstacleSpec:
    stone_density: float = _f(
        0.0,
        "surface stones per square metre of field (assumed: 1/m² of 6-20 cm stones covers "
        "≈ 1 % of the ground, FAO's 'very few' surface fragments)",
        0,
        50,
    )
    stone_size: tuple[float, float] = _f(
        (0.06, 0.2),
        "range of a stone's longest diameter, metres, drawn log-uniformly (FAO 2006 coarse "
        "fragments: 'stones' 6-20 cm, 'boulders' 20-60 cm)",
        0.01,
        2,
    )
    litter_density: float = _f(
        0.0, "litter items (bags, sheets, bottles, cans) per square metre of field", 0, 50
    )
    litter_size: tuple[float, float] = _f(
        (0.08, 0.4), "range of a litter item's longest side, metres, log-uniform (assumed)", 0.01, 2
    )
    stalk_lodging: float = _f(
        0.0,
        "fraction of crop plants fallen (lodged) from their base across the ground (maize "
        "loses 5-20 % of its yield to lodging: Flint-Garcia et al. 2003)",
        0,
        1,
    )
    lodging_spread_deg: float = _f(
        30.0,
        "std of a fallen stalk's direction about the field's wind direction (drawn per field), "
        "degrees",
        0,
        180,
    )


@dataclass(frozen=True)
class ScenarioSpec:
    name: str = _f("custom", "scenario name")
    terrain: TerrainSpec = dc_field(default_factory=TerrainSpec)
    field: FieldSpec = dc_field(default_factory=FieldSpec)
    layout: LayoutSpec = dc_field(default_factory=LayoutSpec)
    crop: CropSpec = dc_field(default_factory=CropSpec)
    furrows: FurrowSpec = dc_field(default_factory=FurrowSpec)
    route: RouteSpec = dc_field(default_factory=RouteSpec)
    obstacles: ObstacleSpec = dc_field(default_factory=ObstacleSpec)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ScenarioSpec:
        spec: ScenarioSpec = from_mapping(cls, data, "")
        return spec

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = plain(dataclasses.asdict(self))
        return out

    def replace(self, overrides: dict[str, Any]) -> ScenarioSpec:
        """A copy with nested or dotted overrides applied (``{"layout.row_spacing": 0.76}``)."""
        return ScenarioSpec.from_dict(merge(self.to_dict(), overrides))

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)
