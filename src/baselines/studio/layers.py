"""The terrain as map layers: hillshade and contours in lat/lon, and elevation at a point.

Leaflet places an image overlay between two lat/lon corners in Web-Mercator, so the image rows
are sampled evenly in Mercator y (not in latitude) and the hillshade and contours line up with
the drawn field at any zoom. Elevations come from the scenario's own terrain source: the DEM
(bicubic, as generation samples it), the terrain mesh (linear over its triangulated vertices)
or the plane; off the terrain they are NaN, drawn transparent and read out as "off terrain".
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from scenario_gen.arrays import FloatArray
from scenario_gen.dem import Dem, load_embedded, load_geotiff
from scenario_gen.geodesy import GeoFrame
from scenario_gen.sources import DEFAULT_PLANE_DATUM, load_mesh_vertices
from scenario_gen.spec import TerrainSpec
from scenario_gen.terrain import hillshade

EARTH_R = 6_378_137.0  # WGS84 semi-major axis: Web-Mercator's sphere
PLANE_HALF_M = 500.0  # a plane has no edge: show this much around its datum


class Elevation:
    """Heights (the source's metres: orthometric from a DEM) at lon/lat, NaN off the terrain."""

    extent: tuple[float, float, float, float]  # west, south, east, north, degrees
    label: str

    def __call__(self, lon: FloatArray, lat: FloatArray) -> FloatArray:
        raise NotImplementedError


class DemElevation(Elevation):
    def __init__(self, dem: Dem) -> None:
        self.dem = dem
        self.label = dem.source
        rows, cols = dem.shape
        c = np.array([0, cols, cols, 0, cols / 2, 0, cols, cols / 2], np.float64)
        r = np.array([0, 0, rows, rows, 0, rows / 2, rows / 2, rows], np.float64)
        lon, lat = dem.to_lonlat().transform(*dem.pixel_to_crs(c, r))
        self.extent = (
            float(np.min(lon)),
            float(np.min(lat)),
            float(np.max(lon)),
            float(np.max(lat)),
        )
        holes = dem.hole_mask
        self._filled = np.where(holes, np.nanmean(dem.elevation), dem.elevation)
        self._holes = holes.astype(np.float64)
        self._from = dem.from_lonlat()

    def __call__(self, lon: FloatArray, lat: FloatArray) -> FloatArray:
        col, row = self.dem.lonlat_to_pixel(
            np.asarray(lon, np.float64), np.asarray(lat, np.float64), self._from
        )
        col, row = col - 0.5, row - 0.5
        rows, cols = self.dem.shape
        z = ndimage.map_coordinates(self._filled, [row, col], order=3, mode="nearest")
        off = (col < 0) | (row < 0) | (col > cols - 1) | (row > rows - 1)
        if self._holes.any():
            off |= ndimage.map_coordinates(self._holes, [row, col], order=1, cval=1.0) > 0
        return np.where(off, np.nan, z)


class MeshElevation(Elevation):
    def __init__(self, path: str, datum: tuple[float, float, float], up_axis: str) -> None:
        from scipy.interpolate import LinearNDInterpolator

        v, _ = load_mesh_vertices(path, up_axis)
        self.geo = GeoFrame(*datum)
        self.label = f"mesh {path}"
        self._interp = LinearNDInterpolator(v[:, :2], v[:, 2])
        lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
        lat, lon, _ = self.geo.enu_to_geodetic(np.array([lo[0], hi[0]]), np.array([lo[1], hi[1]]))
        self.extent = (float(lon[0]), float(lat[0]), float(lon[1]), float(lat[1]))

    def __call__(self, lon: FloatArray, lat: FloatArray) -> FloatArray:
        x, y, _ = self.geo.geodetic_to_enu(lat, lon, self.geo.alt)  # on the datum level
        z = np.asarray(self._interp(np.asarray(x), np.asarray(y)), np.float64)
        return z + self.geo.alt


class PlaneElevation(Elevation):
    def __init__(self, spec: TerrainSpec) -> None:
        self.geo = GeoFrame(*(spec.datum if spec.datum is not None else DEFAULT_PLANE_DATUM))
        self.label = f"plane, slope {spec.slope_deg:g}°"
        g = math.tan(math.radians(spec.slope_deg))
        a = math.radians(spec.aspect_deg)
        self._grad = (-g * math.sin(a), -g * math.cos(a))
        d = PLANE_HALF_M
        lat, lon, _ = self.geo.enu_to_geodetic(np.array([-d, d]), np.array([-d, d]))
        self.extent = (float(lon[0]), float(lat[0]), float(lon[1]), float(lat[1]))

    def __call__(self, lon: FloatArray, lat: FloatArray) -> FloatArray:
        x, y, _ = self.geo.geodetic_to_enu(lat, lon, self.geo.alt)  # on the datum level
        return self.geo.alt + self._grad[0] * np.asarray(x) + self._grad[1] * np.asarray(y)


def elevation_source(spec: TerrainSpec) -> Elevation:
    """The heights a scenario with this terrain spec is generated from."""
    if spec.source == "embedded":
        return DemElevation(load_embedded())
    if spec.source == "dem":
        assert spec.path is not None  # the spec was checked by the CLI's own parser
        return DemElevation(
            load_geotiff(spec.path, spec.fill_max_pixels, vertical_unit=spec.vertical_unit)
        )
    if spec.source == "mesh":
        assert spec.path is not None and spec.datum is not None
        return MeshElevation(spec.path, spec.datum, spec.up_axis)
    return PlaneElevation(spec)


def merc_y(lat: FloatArray | float) -> Any:
    return np.arcsinh(np.tan(np.radians(lat)))


def merc_lat(y: FloatArray) -> FloatArray:
    return np.degrees(np.arctan(np.sinh(y)))


def nice_interval(relief: float, lines: int = 12) -> float:
    """A contour interval of 1, 2 or 5 × 10^k metres giving about ``lines`` contours."""
    raw = max(relief, 1e-3) / lines
    k = 10.0 ** math.floor(math.log10(raw))
    return next(m * k for m in (1.0, 2.0, 5.0, 10.0) if m * k >= raw)


@dataclass(frozen=True)
class Layer:
    png: bytes
    bounds: tuple[tuple[float, float], tuple[float, float]]  # (south, west), (north, east)
    zmin: float
    zmax: float
    interval: float


def render(
    elev: Elevation, bbox: tuple[float, float, float, float], max_px: int = 900
) -> Layer | None:
    """Hillshade and labelled contours of ``elev`` over a lon/lat box, as a transparent PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    w0, s0, e0, n0 = elev.extent
    west, south, east, north = (
        max(bbox[0], w0),
        max(bbox[1], s0),
        min(bbox[2], e0),
        min(bbox[3], n0),
    )
    if not (east > west and north > south):
        return None
    ys, yn = float(merc_y(south)), float(merc_y(north))
    xspan = math.radians(east - west)
    w = max_px if xspan >= yn - ys else max(16, round(max_px * xspan / (yn - ys)))
    h = max_px if yn - ys >= xspan else max(16, round(max_px * (yn - ys) / xspan))
    lon = np.linspace(west, east, w)
    lat = merc_lat(np.linspace(yn, ys, h))  # row 0 north
    glon, glat = np.meshgrid(lon, lat)
    z = elev(glon.ravel(), glat.ravel()).reshape(h, w)
    ok = np.isfinite(z)
    if not ok.any():
        return None
    zmin, zmax = float(np.nanmin(z)), float(np.nanmax(z))
    mid = math.radians(0.5 * (south + north))
    dx = EARTH_R * math.cos(mid) * math.radians(east - west) / max(w - 1, 1)
    dy = EARTH_R * math.radians(north - south) / max(h - 1, 1)
    zf = np.where(ok, z, zmin)
    shade = hillshade(zf, dx, -dy)  # row 0 north
    rgba = np.empty((h, w, 4))
    tint = (zf - zmin) / max(zmax - zmin, 1e-9)
    base = np.stack([0.55 + 0.25 * tint, 0.62 + 0.15 * tint, 0.45 + 0.05 * tint], axis=-1)
    rgba[..., :3] = base * (0.35 + 0.65 * shade[..., None])
    rgba[..., 3] = np.where(ok, 1.0, 0.0)
    fig = Figure(figsize=(w / 100, h / 100), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_axis_off()
    ax.imshow(rgba, extent=(0, w, 0, h), origin="upper", interpolation="nearest")
    interval = nice_interval(zmax - zmin)
    levels = np.arange(math.floor(zmin / interval) * interval, zmax + interval, interval)
    if len(levels) > 1:
        gx, gy = np.meshgrid(np.arange(w) + 0.5, h - np.arange(h) - 0.5)
        cs = ax.contour(
            gx,
            gy,
            np.where(ok, z, np.nan),
            levels=levels,
            colors="#4a3520",
            linewidths=0.6,
            alpha=0.8,
        )
        ax.clabel(cs, levels[:: max(1, len(levels) // 6)], fontsize=7, fmt="%g m")
    ax.set_xlim(0, w)
    ax.set_ylim(0, h)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", transparent=True, metadata={"Software": None})
    return Layer(buf.getvalue(), ((south, west), (north, east)), zmin, zmax, interval)


def around(
    latlon_box: tuple[float, float, float, float], pad_m: float
) -> tuple[float, float, float, float]:
    """A lon/lat box grown by ``pad_m`` metres each side (west, south, east, north)."""
    west, south, east, north = latlon_box
    dlat = math.degrees(pad_m / EARTH_R)
    dlon = dlat / max(math.cos(math.radians(0.5 * (south + north))), 1e-6)
    return (west - dlon, south - dlat, east + dlon, north + dlat)
