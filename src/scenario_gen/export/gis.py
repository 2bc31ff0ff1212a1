"""GIS: the terrain as GeoTIFF and the field, rows, plants and route as GeoPackage and GeoJSON.

The GeoTIFF lives in a local projected CRS whose x/y are the scenario's ENU x/y, so each pixel
centre is a terrain node and no resampling happens: a transverse Mercator centred on the datum
with scale factor 1 + h0/R (h0 the datum's ellipsoidal height, R the Gaussian radius there).
ENU is a plane tangent at the datum's height while a map projection maps the ellipsoid
surface; the scale factor lifts it to the datum's height, leaving a residual of about
(z − h0)·d/R (≈ 1 mm at 50 m relief and 130 m from the datum). The export measures the
actual residual over the terrain's nodes and reports it (``crs_error_mm``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pyproj import CRS, Transformer
from pyproj.crs import GeographicCRS, ProjectedCRS
from pyproj.crs.coordinate_operation import TransverseMercatorConversion

from ..dem import height_reference
from ..geodesy import GeoFrame
from ..geojson import collection, field_features, plant_features, route_features, row_features
from ..model import Scenario
from .gpkg import Layer, write_gpkg

FloatArray = NDArray[np.float64]
WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3
LOCAL_SRS_ID = 100000


def gaussian_radius(lat_deg: float) -> float:
    """√(M·N): the mean radius of curvature of the WGS84 ellipsoid at ``lat_deg``."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    w = 1.0 - WGS84_E2 * s2
    return WGS84_A * math.sqrt(1.0 - WGS84_E2) / w


def local_crs(geo: GeoFrame) -> CRS:
    """The projected CRS whose x/y equal ENU x/y at the datum (see the module docstring)."""
    k0 = 1.0 + geo.alt / gaussian_radius(geo.lat)
    conv = TransverseMercatorConversion(
        latitude_natural_origin=geo.lat,
        longitude_natural_origin=geo.lon,
        false_easting=0.0,
        false_northing=0.0,
        scale_factor_natural_origin=k0,
    )
    return ProjectedCRS(
        conv,
        name=f"AgriNav local ENU at {geo.lat:.6f}, {geo.lon:.6f}, {geo.alt:.1f} m",
        geodetic_crs=GeographicCRS(name="WGS 84", datum="WGS84"),
    )


def enu_crs_error(scn: Scenario, crs: CRS, samples: int = 41) -> float:
    """Largest horizontal distance (m) between ENU x/y and the CRS's x/y over the terrain."""
    t = scn.terrain
    iy = np.unique(np.linspace(0, t.shape[0] - 1, samples).astype(int))
    ix = np.unique(np.linspace(0, t.shape[1] - 1, samples).astype(int))
    gx, gy = np.meshgrid(t.xs[ix], t.ys[iy])
    gz = t.heights[np.ix_(iy, ix)]
    lat, lon, _ = scn.geo.enu_to_geodetic(gx, gy, gz)
    px, py = Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon, lat)
    return float(np.hypot(px - gx, py - gy).max())


def heights(scn: Scenario) -> str:
    """What the scenario's heights are, in words (orthometric from a DEM, with its datum)."""
    return height_reference(scn.spec.terrain.source, scn.info)


def terrain_altitudes(scn: Scenario) -> FloatArray:
    """The height of every terrain node (rows south to north, like ``heights``), as the
    scenario's heights are (``dem.height_reference``: a DEM's are orthometric)."""
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
        crs=rasterio.crs.CRS.from_wkt(crs.to_wkt()),
        transform=transform,
        compress="deflate",
        predictor=3,
        tiled=True,
        blockxsize=256,
        blockysize=256,
    ) as ds:
        ds.write(alt, 1)
        ds.set_band_description(1, f"elevation (m, {heights(scn)})")
        ds.update_tags(
            AGRINAV_SCENARIO=scn.spec.name,
            AGRINAV_SEED=str(scn.seed),
            AGRINAV_DATUM=f"{scn.geo.lat} {scn.geo.lon} {scn.geo.alt}",
            AGRINAV_FRAME="x/y = ENU metres from the datum (pixel centres on terrain nodes)",
            AGRINAV_SOURCE_CRS=str(scn.info.get("dem_crs", "none")),
        )


def write_dem_crs_geotiff(src: Path, dst: Path, dem_crs: str) -> None:
    """``src`` resampled (bilinear) into the source DEM's CRS; NaN outside the terrain."""
    import rasterio
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    with rasterio.open(src) as s:
        dst_crs = rasterio.crs.CRS.from_user_input(dem_crs)
        transform, w, h = calculate_default_transform(s.crs, dst_crs, s.width, s.height, *s.bounds)
        profile = s.profile | {
            "crs": dst_crs,
            "transform": transform,
            "width": w,
            "height": h,
            "nodata": float("nan"),
        }
        with rasterio.open(dst, "w", **profile) as d:
            reproject(
                rasterio.band(s, 1),
                rasterio.band(d, 1),
                resampling=Resampling.bilinear,
                dst_nodata=float("nan"),
            )
            d.update_tags(**s.tags())


def export_gis(scn: Scenario, out: Path) -> dict[str, Any]:
    from .preview import render_export_preview
    from .readme import gis_readme

    crs = local_crs(scn.geo)
    (out / "crs_local.wkt").write_text(crs.to_wkt(pretty=True) + "\n")
    err = enu_crs_error(scn, crs)
    write_geotiff(scn, out / "terrain.tif", crs)
    info: dict[str, Any] = {"crs_name": crs.name, "crs_error_mm": err * 1000.0}
    dem_crs = scn.info.get("dem_crs")
    if dem_crs:
        write_dem_crs_geotiff(out / "terrain.tif", out / "terrain_dem_crs.tif", str(dem_crs))
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
    kinds = {
        "field": "MULTIPOLYGON" if scn.field.geom_type == "MultiPolygon" else "POLYGON",
        "rows": "LINESTRING",
        "plants": "POINT",
        "route": "LINESTRING",
    }
    write_gpkg(
        out / "layers.gpkg",
        [
            Layer(n, kinds[n], f, description=f"AgriNav {scn.spec.name}: {n}")
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
    for name, feats in rounded.items():
        (out / f"{name}.geojson").write_text(json.dumps(collection(name, feats)))
    info["layers"] = {n: len(f) for n, f in full.items()}
    (out / "README.md").write_text(gis_readme(scn, info))
    render_export_preview(scn, out / "preview.png", geotiff=out / "terrain.tif")
    return info
