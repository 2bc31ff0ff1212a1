"""GIS: the terrain as GeoTIFF and the field, rows, plants, route and (when the field has any)
obstacles as GeoPackage and GeoJSON.

The GeoTIFF lives in a local projected CRS whose x/y are the scenario's ENU x/y, so each pixel
centre is a terrain node and no resampling happens: a transverse Mercator centred on the datum
with scale factor 1 + h0/R (h0 the datum's ellipsoidal height, R the Gaussian radius there).
ENU is a plane tangent at the datum's height while a map projection maps the ellipsoid
surface; the scale factor lifts it to the datum's height, leaving a residual of about
(z − h0)·d/R (≈ 1 mm at 50 m relief and 130 m from the datum). The export measures the
actual residual over the terrain's nodes and reports it (``crs_error_mm``).

That CRS has no EPSG code, so a copy resampled (bilinear) into the datum's UTM zone,
``terrain_utm.tif``, serves the tools that need one; the export measures how far it departs
from the terrain at the plants (``utm_error_mm``). Every GeoTIFF declares NoData (``NODATA``):
reprojected, the pixels outside the terrain read NoData, not a 0 m border.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from pyproj import CRS, Transformer
from pyproj.crs import CompoundCRS

from ..arrays import FloatArray
from ..geojson import (
    collection,
    field_features,
    obstacle_features,
    plant_features,
    route_features,
    row_features,
)
from ..model import Scenario
from ..vertical import ORTHOMETRIC, in_metres, of_scenario
from .crs import enu_crs_error, local_crs, utm_epsg
from .gpkg import Layer, write_gpkg

LOCAL_SRS_ID = 100000
#: NoData of every GeoTIFF written: no ground on Earth is this low, and the DEM reader takes it
#: as nodata even untagged (``dem.SENTINELS``)
NODATA = -9999.0


def with_heights(scn: Scenario, crs: CRS) -> CRS:
    """``crs`` with the vertical CRS of the scenario's heights where they are orthometric in a
    declared datum (a DEM's, not converted), so the GeoTIFF says what its values are; else
    ``crs`` (ellipsoidal or undeclared heights: the band description and tags say)."""
    h = of_scenario(scn.info)
    if h.reference != ORTHOMETRIC or not h.crs:
        return crs
    vert = in_metres(CRS.from_user_input(h.crs))  # the values are metres (older records
    # name the DEM's own vertical CRS, in feet where it was)
    return CompoundCRS(f"{crs.name} + {vert.name}", [crs, vert])


def terrain_altitudes(scn: Scenario) -> FloatArray:
    """Altitude of every terrain node (rows south to north, like ``heights``): the scenario's
    heights, whose reference ``vertical.of_scenario`` gives."""
    t = scn.terrain
    gx, gy = np.meshgrid(t.xs, t.ys)
    return np.asarray(scn.geo.enu_to_geodetic(gx, gy, t.heights)[2])


def write_geotiff(scn: Scenario, path: Path, crs: CRS) -> None:
    import rasterio
    from affine import Affine

    t = scn.terrain
    ny, nx = t.shape
    s = t.spacing
    # pixel centres on the nodes; row 0 is the northern row
    transform = Affine(s, 0.0, t.x0 - s / 2, 0.0, -s, t.y0 + (ny - 1) * s + s / 2)
    alt = terrain_altitudes(scn)[::-1].astype(np.float32)
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=nx,
        height=ny,
        count=1,
        dtype="float32",
        crs=rasterio.crs.CRS.from_wkt(with_heights(scn, crs).to_wkt()),
        transform=transform,
        nodata=NODATA,
        compress="deflate",
        predictor=3,
        tiled=True,
        blockxsize=256,
        blockysize=256,
    ) as ds:
        heights = of_scenario(scn.info).label()
        ds.write(alt, 1)
        ds.set_band_description(1, f"elevation (m): {heights}")
        ds.units = ("metre",)  # GDAL's band unit: a CRS in feet says nothing of the values
        ds.update_tags(
            AGRINAV_HEIGHTS=heights,
            AGRINAV_SCENARIO=scn.spec.name,
            AGRINAV_SEED=str(scn.seed),
            AGRINAV_DATUM=f"{scn.geo.lat} {scn.geo.lon} {scn.geo.alt}",
            AGRINAV_FRAME="x/y = ENU metres from the datum (pixel centres on terrain nodes)",
            AGRINAV_SOURCE_CRS=str(scn.info.get("dem_crs", "none")),
        )


def write_resampled(src: Path, dst: Path, crs: CRS, resolution: float | None = None) -> None:
    """``src`` resampled (bilinear) into ``crs`` (pixel size ``resolution`` in its units, or
    GDAL's choice); NoData outside the terrain."""
    import rasterio
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    with rasterio.open(src) as s:
        dst_crs = rasterio.crs.CRS.from_wkt(crs.to_wkt())
        grid = _across_antimeridian(s, crs) if crs.is_geographic else None
        if grid is not None:
            transform, w, h = grid
        else:
            transform, w, h = calculate_default_transform(
                s.crs, dst_crs, s.width, s.height, *s.bounds, resolution=resolution
            )
        profile = s.profile | {
            "crs": dst_crs,
            "transform": transform,
            "width": w,
            "height": h,
            "nodata": NODATA,
        }
        with rasterio.open(dst, "w", **profile) as d:
            reproject(
                rasterio.band(s, 1),
                rasterio.band(d, 1),
                resampling=Resampling.bilinear,
                src_nodata=NODATA,
                dst_nodata=NODATA,
            )
            d.update_tags(**s.tags())
            d.set_band_description(1, s.descriptions[0] or "")
            d.units = s.units


def _across_antimeridian(src: Any, crs: CRS) -> tuple[Any, int, int] | None:
    """A longitude/latitude grid for ``src`` where its footprint crosses 180° (GDAL's own
    choice is then 0 pixels wide): longitudes run on past 180° (or below −180°) from the
    footprint's west edge; pixels as GDAL sizes them (the footprint's diagonal over the
    source's). None where the footprint does not cross."""
    from rasterio.transform import from_origin

    n = 64  # points along each edge: the footprint's curved sides, to well under a pixel
    t = np.linspace(0.0, 1.0, n)
    w, h = src.width, src.height
    cols = np.concatenate([t * w, np.full(n, w), t[::-1] * w, np.zeros(n)])
    rows = np.concatenate([np.zeros(n), t * h, np.full(n, h), t[::-1] * h])
    x, y = src.transform @ (cols, rows)
    to = Transformer.from_crs(src.crs.to_wkt(), crs, always_xy=True)
    lon, lat = (np.asarray(v, float) for v in to.transform(x, y))
    ref = float(lon[0])
    unwrapped = ref + (lon - ref + 180.0) % 360.0 - 180.0
    if float(unwrapped.min()) >= -180.0 and float(unwrapped.max()) <= 180.0:
        return None
    west, east = float(unwrapped.min()), float(unwrapped.max())
    south, north = float(lat.min()), float(lat.max())
    res = math.hypot(east - west, north - south) / math.hypot(w, h)
    width, height = math.ceil((east - west) / res), math.ceil((north - south) / res)
    return from_origin(west, north, res, res), width, height


def resampling_error(scn: Scenario, path: Path) -> float:
    """Largest |height read bilinearly from ``path`` − the scenario's ground| at the plants (m);
    NaN without plants."""
    import rasterio
    from scipy import ndimage

    p = scn.plants
    if len(p) == 0:
        return float("nan")
    lat, lon, alt = scn.geo.enu_to_geodetic(p.x, p.y, scn.terrain.height_at(p.x, p.y))
    with rasterio.open(path) as ds:
        x, y = Transformer.from_crs("EPSG:4326", ds.crs.to_wkt(), always_xy=True).transform(
            lon, lat
        )
        col, row = ~ds.transform @ (np.asarray(x), np.asarray(y))
        z = ds.read(1).astype(np.float64)
    got = ndimage.map_coordinates(z, [np.asarray(row) - 0.5, np.asarray(col) - 0.5], order=1)
    return float(np.abs(got - alt).max())


def export_gis(scn: Scenario, out: Path) -> dict[str, Any]:
    from .preview import render_export_preview
    from .readme import gis_readme

    crs = local_crs(scn.geo)
    (out / "crs_local.wkt").write_text(crs.to_wkt(pretty=True) + "\n")
    err = enu_crs_error(scn, crs)
    write_geotiff(scn, out / "terrain.tif", crs)
    info: dict[str, Any] = {"crs_name": crs.name, "crs_error_mm": err * 1000.0}
    utm = utm_epsg(scn.geo.lat, scn.geo.lon)
    if utm is not None:
        utm_crs = with_heights(scn, CRS.from_epsg(utm))
        spacing = scn.terrain.spacing
        write_resampled(out / "terrain.tif", out / "terrain_utm.tif", utm_crs, spacing)
        err_utm = resampling_error(scn, out / "terrain_utm.tif") * 1000.0
        info |= {"utm_tif": "terrain_utm.tif", "utm_crs": f"EPSG:{utm}", "utm_error_mm": err_utm}
    dem_crs = scn.info.get("dem_crs")
    if dem_crs:
        dem_out = with_heights(scn, CRS.from_user_input(dem_crs))
        write_resampled(out / "terrain.tif", out / "terrain_dem_crs.tif", dem_out)
        info |= {"dem_tif": "terrain_dem_crs.tif", "dem_crs": str(dem_crs)}
    p, r = scn.plants, scn.route
    lat, lon, alt = scn.geo.enu_to_geodetic(p.x, p.y, p.z)
    rlat, rlon, _ = scn.geo.enu_to_geodetic(r.xyz[:, 0], r.xyz[:, 1], r.xyz[:, 2])
    full = {
        "field": field_features(scn, None),
        "rows": row_features(scn, None),
        "plants": plant_features(scn, lat, lon, alt, None),
        "route": route_features(scn, rlat, rlon, None),
    }
    if len(scn.obstacles):  # no layer at all without obstacles: those exports keep their bytes
        full["obstacles"] = gis_obstacle_features(scn, None)
    kinds = {name: _layer_type(feats) for name, feats in full.items()}
    label = of_scenario(scn.info).label()
    write_gpkg(
        out / "layers.gpkg",
        [
            Layer(n, kinds[n], f, description=f"AgriNav {scn.spec.name}: {n}; heights {label}")
            for n, f in full.items()
        ],
        {4326: CRS.from_epsg(4326)},
    )
    rounded = {
        "field": field_features(scn),
        "rows": row_features(scn),
        "plants": plant_features(scn, lat, lon, alt),
        "route": route_features(scn, rlat, rlon),
    }
    if len(scn.obstacles):
        rounded["obstacles"] = gis_obstacle_features(scn)
    for name, feats in rounded.items():
        (out / f"{name}.geojson").write_text(json.dumps(collection(name, feats)))
    info["layers"] = {n: len(f) for n, f in full.items()}
    info["heights"] = label
    (out / "README.md").write_text(gis_readme(scn, info))
    render_export_preview(scn, out / "preview.png", geotiff=out / "terrain.tif")
    return info


def gis_obstacle_features(scn: Scenario, decimals: int | None = 8) -> list[dict[str, Any]]:
    """The scenario's obstacle footprints (``geojson.obstacle_features``: id, kind, size, yaw)
    with the rest of each pose, as the plants layer has it: roll, pitch and ENU x/y/z."""
    o = scn.obstacles
    feats = obstacle_features(scn, decimals)
    for i, f in enumerate(feats):
        extra = {
            "roll": (float(o.roll[i]), 6),
            "pitch": (float(o.pitch[i]), 6),
            "x_enu": (float(o.x[i]), 4),
            "y_enu": (float(o.y[i]), 4),
            "z_enu": (float(o.z[i]), 4),
        }
        f["properties"] |= {
            k: (round(v, d) if decimals is not None else v) for k, (v, d) in extra.items()
        }
    return feats


def _layer_type(features: list[dict[str, Any]]) -> str:
    """The GeoPackage geometry type of a layer: its features' type, promoted to Multi- when any
    feature is (lines and fields cut at the antimeridian)."""
    kinds = {f["geometry"]["type"] for f in features}
    for single in ("Polygon", "LineString"):
        if f"Multi{single}" in kinds:
            return f"MULTI{single.upper()}"
    return next(iter(kinds)).upper() if len(kinds) == 1 else "GEOMETRY"
