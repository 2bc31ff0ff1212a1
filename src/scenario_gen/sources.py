"""Where terrain heights come from: DEM (embedded or GeoTIFF), terrain mesh, or a plane.

Each source is opened into a ``Site``: the ENU frame (datum) and a vectorized function giving
ENU heights at ENU points. ``build_terrain`` then samples it on the level-of-detail grid.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray
from .bounds import MAX_ENU_HEIGHT_M, MAX_PLANE_RADIUS_M, MAX_TERRAIN_SAMPLES
from .dem import EMBEDDED_CREDIT, SWAPPED, Dem, load_embedded, load_geotiff
from .errors import InputError, Notice
from .field import centroid_latlon
from .geodesy import GeoFrame
from .meshsurface import TriangleSurface
from .model_mesh import check_gltf, collada_unit, file_up_axis
from .spec import TerrainSpec
from .terrain import Terrain, grid_for_bounds
from .vertical import DATUM_HEIGHTS

HeightFn = Callable[[FloatArray, FloatArray], FloatArray]

#: Datum used for a plane when the spec gives none: a crop field near León, Spain (42.6° N),
#: the latitude of design.md's LoD example ("Frames, units, randomness"). Any datum works; GPS
#: needs one.
DEFAULT_PLANE_DATUM = (42.6, -5.57, 830.0)
MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".dae", ".stl")
MAX_MESH_BYTES = 512 * 2**20  # a terrain mesh this large holds ~10 M triangles


@dataclass
class Site:
    geo: GeoFrame
    heights: HeightFn
    centre: tuple[float, float] = (0.0, 0.0)  # ENU point a rectangular field is centred on
    credit: str = ""
    info: dict[str, Any] = field(default_factory=dict)


def open_site(
    spec: TerrainSpec, field_ll: BaseGeometry | None, extent_m: float, margin: float = 0.0
) -> Site:
    """Open the terrain source; ``field_ll`` is a GeoJSON field (lon/lat), ``extent_m`` the
    size a rectangle field and its margin need, ``margin`` the terrain kept around the field."""
    if spec.source in ("embedded", "dem"):
        return _dem_site(spec, field_ll, extent_m, margin)
    if spec.source == "plane":
        return _plane_site(spec, None if field_ll is None else centroid_latlon(field_ll))
    return _mesh_site(spec)


def _lonlat_box(
    lon0: float, lat0: float, lon1: float, lat1: float, pad_m: float
) -> tuple[float, float, float, float]:
    """A lon/lat box grown by ``pad_m`` metres (10 % more: the metres-per-degree are local)."""
    dlat = 1.1 * pad_m / 110_574.0 + 1e-9
    coslat = max(math.cos(math.radians(max(abs(lat0), abs(lat1)))), 1e-6)
    dlon = 1.1 * pad_m / (111_320.0 * coslat) + 1e-9
    return lon0 - dlon, lat0 - dlat, lon1 + dlon, lat1 + dlat


def terrain_grid(
    site: Site, bounds: tuple[float, float, float, float], lod: int
) -> tuple[float, float, int, int, float]:
    """(x0, y0, nx, ny, spacing) of the LoD grid over ``bounds``, refused when too large."""
    spacing = site.geo.gsd(lod)
    x0, y0, nx, ny = grid_for_bounds(*bounds, spacing)
    if nx * ny > MAX_TERRAIN_SAMPLES:
        raise InputError(
            "terrain.lod",
            lod,
            f"gives a {nx}x{ny} grid over the field; "
            f"allowed: at most {MAX_TERRAIN_SAMPLES:,} samples (lower the LoD or the margin)",
        )
    return x0, y0, nx, ny, spacing


def _on_raster(dem: Any, lon: float, lat: float) -> bool:
    """Whether (lon, lat) — both valid as such — falls inside ``dem``'s raster."""
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return False
    try:
        col, row = dem.lonlat_to_pixel(np.array([lon]), np.array([lat]))
    except Exception:  # pyproj: a point outside the CRS's area
        return False
    rows, cols = dem.shape
    return bool(0 <= float(col[0]) <= cols and 0 <= float(row[0]) <= rows)


def build_terrain(site: Site, bounds: tuple[float, float, float, float], lod: int) -> Terrain:
    x0, y0, nx, ny, spacing = terrain_grid(site, bounds, lod)
    gx, gy = np.meshgrid(x0 + spacing * np.arange(nx), y0 + spacing * np.arange(ny))
    z = site.heights(gx.ravel(), gy.ravel()).reshape(ny, nx)
    return Terrain(z, x0, y0, spacing, lod)


# ----------------------------------------------------------------------------- DEM
def _dem_site(
    spec: TerrainSpec, field_ll: BaseGeometry | None, extent_m: float, margin: float
) -> Site:
    if spec.source == "embedded" and spec.path is not None:
        raise InputError("terrain.path", spec.path, "is only used with terrain.source dem or mesh")
    if spec.source == "dem" and spec.path is None:
        raise InputError("terrain.path", None, "terrain.source=dem needs a GeoTIFF path")
    if spec.source != "dem" and spec.vertical_unit != "auto":
        raise InputError(
            "terrain.vertical_unit",
            spec.vertical_unit,
            f"allowed: auto with terrain.source={spec.source} (it is a GeoTIFF DEM's unit)",
        )
    need: tuple[float, float, float, float] | None = None
    if field_ll is not None:
        lat, lon = centroid_latlon(field_ll)
        how = "field centroid"
        lon0, lat0, lon1, lat1 = field_ll.bounds
        need = _lonlat_box(lon0, lat0, lon1, lat1, margin)
    elif spec.site == "latlon":
        if spec.lat is None or spec.lon is None:
            raise InputError(
                "terrain.lat/lon",
                (spec.lat, spec.lon),
                "terrain.site=latlon needs both terrain.lat and terrain.lon",
            )
        lat, lon = spec.lat, spec.lon
        how = "given lat/lon"
        need = _lonlat_box(lon, lat, lon, lat, extent_m / 2)
    if spec.source == "embedded":
        dem = load_embedded()
        credit = EMBEDDED_CREDIT
    else:
        assert spec.path is not None
        dem = load_geotiff(
            spec.path,
            spec.fill_max_pixels,
            need,
            f"terrain.site={spec.site} searches it",
            spec.vertical_unit,
        )
        credit = f"DEM {Path(spec.path).name}"
    if need is None:
        lat, lon = dem.pick_site(spec.site, extent_m, spec.max_slope_deg)
        how = f"{spec.site} window of {extent_m:.0f} m"
    what = "field" if field_ll is not None else "terrain.site"
    try:
        alt = float(dem.sample_lonlat(np.array([lon]), np.array([lat]), what)[0])
    except InputError as exc:
        if "off the DEM" in str(exc) and _on_raster(dem, lon=lat, lat=lon):
            raise InputError(exc.field, exc.value, exc.allowed + SWAPPED) from None
        raise
    geo = GeoFrame(lat, lon, alt)
    info = {
        "dem": dem.source,
        "dem_crs": dem.crs.to_string(),
        "site": how,
        "heights": dem.heights.to_dict(),
    }
    return Site(geo, _dem_heights(dem, geo, info), credit=credit, info=info)


def _dem_heights(dem: Dem, geo: GeoFrame, info: dict[str, Any]) -> HeightFn:
    """The DEM's heights in ENU; the first call (the terrain grid) records in ``info`` the
    share of it read from nodata pixels that ``terrain.fill_max_pixels`` filled, and notes it:
    that ground is interpolated, not measured."""

    def heights(x: FloatArray, y: FloatArray) -> FloatArray:
        lat, lon, _ = geo.enu_to_geodetic(x, y, 0.0)
        if "dem_filled_share" not in info and dem.filled is not None:
            share = dem.filled_fraction(lon, lat)
            info["dem_filled_share"] = round(share, 4)
            if share > 0:
                warnings.warn(
                    Notice(
                        f"{100 * share:.1f} % of the terrain grid lies over nodata holes of "
                        f"{dem.source} that terrain.fill_max_pixels filled (interpolated "
                        "heights, not measured; scenario.json info.dem_filled_share)"
                    ),
                    stacklevel=2,
                )
        h = dem.sample_lonlat(lon, lat, "field")
        # Exact ENU height of the surface point (earth curvature included: -2 cm at 500 m).
        _, _, z = geo.geodetic_to_enu(lat, lon, h)
        return z

    return heights


# ----------------------------------------------------------------------------- plane
def _plane_site(spec: TerrainSpec, field_lonlat: tuple[float, float] | None) -> Site:
    """A plane through the datum; under a GeoJSON field without a datum, through its centroid
    at 0 m (the plane then lies where the field is, not at the default datum far away)."""
    if spec.datum is not None:
        lat, lon, alt = spec.datum
    elif field_lonlat is not None:
        lat, lon, alt = field_lonlat[0], field_lonlat[1], 0.0
    else:
        lat, lon, alt = DEFAULT_PLANE_DATUM
    geo = GeoFrame(lat, lon, alt)
    g = math.tan(math.radians(spec.slope_deg))
    a = math.radians(spec.aspect_deg)
    down = (math.sin(a), math.cos(a))  # unit vector pointing downhill (east, north)

    def heights(x: FloatArray, y: FloatArray) -> FloatArray:
        return -g * (x * down[0] + y * down[1])

    return Site(
        geo,
        heights,
        credit="procedural plane",
        info={
            "slope_deg": spec.slope_deg,
            "aspect_deg": spec.aspect_deg,
            "heights": DATUM_HEIGHTS.to_dict(),
        },
    )


# ----------------------------------------------------------------------------- mesh
def load_mesh_vertices(
    path: str | Path, up_axis: str = "auto"
) -> tuple[FloatArray, NDArray[np.int64]]:
    """Vertices (N, 3) in ENU axes (x east, y north, z up) and faces of a terrain mesh."""
    import trimesh

    p = Path(path)
    if not p.is_file():
        raise InputError("terrain.path", str(path), "allowed: an existing mesh file")
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(
            "terrain.path", str(path), f"allowed: a mesh file ({', '.join(MESH_SUFFIXES)})"
        )
    size = p.stat().st_size
    if size > MAX_MESH_BYTES:
        raise InputError(
            "terrain.path", str(path), f"is {size:,} bytes; allowed: at most {MAX_MESH_BYTES:,}"
        )
    suffix = p.suffix.lower()
    if suffix in (".glb", ".gltf"):
        check_gltf(p, p, "terrain.path", look=False)
    try:
        mesh: Any = trimesh.load(p, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise InputError(
            "terrain.path", str(path), f"cannot be read as a mesh ({exc.__class__.__name__}: {exc})"
        ) from None
    v = np.asarray(getattr(mesh, "vertices", np.empty((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(mesh, "faces", np.empty((0, 3))), dtype=np.int64)
    if len(faces) == 0 and _points_only(p):
        raise InputError(
            "terrain.path",
            str(path),
            "holds points and no triangles (a point cloud?); "
            "allowed: a triangle mesh of the ground (mesh the cloud first, e.g. a DEM from it)",
        )
    if len(v) < 3 or v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
        raise InputError("terrain.path", str(path), "holds no usable vertices")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InputError("terrain.path", str(path), "holds no triangles (a point cloud?)")
    if faces.min() < 0 or faces.max() >= len(v):
        raise InputError("terrain.path", str(path), "has faces indexing missing vertices")
    if suffix == ".dae":
        v = v * collada_unit(p)  # <unit meter="0.01">: trimesh reads the numbers as written
    up = file_up_axis(p, up_axis, "terrain.path", "terrain.up_axis")
    if up == "y":  # glTF: +Y up, +Z toward the viewer -> east = X, north = -Z, up = Y
        v = np.column_stack([v[:, 0], -v[:, 2], v[:, 1]])
    return v, faces


def _points_only(p: Path) -> bool:
    """Whether the file holds a point cloud (and no triangles): trimesh's ``force="mesh"``
    reads one as an empty mesh."""
    import trimesh

    try:
        scene: Any = trimesh.load(p, force="scene", process=False)
    except Exception:  # it failed to read as a mesh too: that error is said
        return False
    return any(isinstance(g, trimesh.PointCloud) for g in scene.geometry.values())


def _mesh_site(spec: TerrainSpec) -> Site:
    if spec.path is None:
        raise InputError("terrain.path", None, "terrain.source=mesh needs a mesh file")
    if spec.datum is None:
        raise InputError(
            "terrain.datum", None, "terrain.source=mesh needs the lat, lon, alt of the mesh origin"
        )
    v, faces = load_mesh_vertices(spec.path, spec.up_axis)
    geo = GeoFrame(*spec.datum)
    surface = TriangleSurface(v, faces)
    if surface.count == 0:
        raise InputError(
            "terrain.path", str(spec.path), "holds no triangle that is not vertical (no ground)"
        )
    name = Path(str(spec.path)).name
    centre = _ground_centre(surface)
    far = math.hypot(*centre)
    if far > MAX_PLANE_RADIUS_M:
        # the frame is the datum's tangent plane: far out it drops below the ground (0.2 km
        # at 50 km) and its axes turn; a mesh that far is in projected coordinates (UTM)
        raise InputError(
            "terrain.path",
            str(spec.path),
            f"has its ground {far / 1000:,.1f} km from its origin (terrain.datum's point); "
            f"allowed: within {MAX_PLANE_RADIUS_M / 1000:g} km, in metres east, north, up of "
            "the datum (a mesh in projected coordinates, e.g. UTM, shifted so that its origin "
            "is the datum)",
        )
    zc = surface.heights(np.array([centre[0]]), np.array([centre[1]]))[0]
    if abs(float(zc[0])) > MAX_ENU_HEIGHT_M:
        raise InputError(
            "terrain.path",
            str(spec.path),
            f"has its ground {float(zc[0]):,.0f} m above its origin (terrain.datum's altitude); "
            f"allowed: within {MAX_ENU_HEIGHT_M:,.0f} m (heights relative to the datum: put the "
            "ground's altitude in terrain.datum, not in the mesh)",
        )

    def heights(x: FloatArray, y: FloatArray) -> FloatArray:
        z, low, covered = surface.layers(x, y)
        if np.any(z - low > LAYER_GAP_M):
            warnings.warn(
                Notice(
                    f"terrain.path {name}: the field's ground holds surfaces stacked more than "
                    f"{LAYER_GAP_M:g} m apart (a roof, a tree crown, the crop of a "
                    "photogrammetry tile): the topmost is taken as the ground; cut the mesh to "
                    "the bare ground (a DTM) where that is not it"
                ),
                stacklevel=2,
            )
        if not covered.all():
            i = int(np.argmin(covered))
            raise InputError(
                "field",
                f"ENU ({x[i]:.1f}, {y[i]:.1f}) m",
                f"lies off the terrain mesh {name}: no triangle under it (the field and "
                "terrain.margin must lie on the mesh)",
            )
        return z

    return Site(
        geo,
        heights,
        centre=centre,
        credit=f"mesh {name}",
        info={
            "mesh_vertices": len(v),
            "mesh_triangles": surface.count,
            "heights": DATUM_HEIGHTS.to_dict(),
        },
    )


#: surfaces of a terrain mesh stacked further apart than this over one point are two layers
#: (a roof over the ground), not a ridge's or a furrow's relief folded by the mesher
LAYER_GAP_M = 0.5


def _ground_centre(surface: TriangleSurface) -> tuple[float, float]:
    """Where a field is laid out on a mesh by default: the centre of the box of its ground
    (its non-vertical triangles, so an unused vertex moves nothing) where ground lies there,
    else the area-weighted median of its triangles (a stray triangle far off, an L-shaped
    tile)."""
    a, b, c = surface.a, surface.b, surface.c
    pts = np.concatenate([a, b, c])[:, :2]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid = 0.5 * (lo + hi)
    _, covered = surface.heights(mid[:1], mid[1:])
    if covered.all():
        return float(mid[0]), float(mid[1])
    area = 0.5 * np.abs(surface.det)
    cen = (a + b + c)[:, :2] / 3.0

    def median(x: FloatArray) -> float:
        order = np.argsort(x, kind="stable")
        cum = np.cumsum(area[order])
        return float(x[order][np.searchsorted(cum, 0.5 * cum[-1])])

    return median(cen[:, 0]), median(cen[:, 1])


def export_terrain_mesh(terrain: Terrain, path: str | Path) -> None:
    """Write the terrain as a mesh (GLB/glTF in Y-up, anything else in ENU Z-up)."""
    p = Path(path)
    y_up = p.suffix.lower() in (".glb", ".gltf")
    save_mesh(terrain.to_trimesh(y_up=y_up), p)


def save_mesh(mesh: Any, path: Path) -> None:
    """Write a trimesh whose vertices are ENU (Z up) or, for glTF, already Y-up. COLLADA gets
    ``<up_axis>Z_UP</up_axis>``: trimesh's writer always says Y_UP, and Blender and assimp
    then turn the data by 90° about x, standing a field on its edge."""
    if path.suffix.lower() != ".dae":
        mesh.export(path)
        return
    data: bytes = mesh.export(file_type="dae")
    old, new = b"<up_axis>Y_UP</up_axis>", b"<up_axis>Z_UP</up_axis>"
    if data.count(old) != 1:
        raise RuntimeError(f"trimesh's COLLADA writer changed: {data.count(old)} Y_UP up axes")
    path.write_bytes(data.replace(old, new))
