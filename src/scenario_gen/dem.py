"""Digital elevation models: the embedded USGS sample DEM and any GeoTIFF via rasterio.

A ``Dem`` is a north-up-or-not raster in any CRS with an affine transform and explicit nodata.
Small nodata holes are filled (GDAL's inverse-distance fill); pixels in larger holes stay marked
so a field over them is refused rather than silently interpolated. Sampling is bicubic
(spline, order 3), which is what a 30-90 m DEM needs before it is resampled to a 0.1 m grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from affine import Affine
from numpy.typing import NDArray
from pyproj import CRS, Geod, Transformer
from scipy import ndimage

from .errors import InputError

FloatArray = NDArray[np.float64]

EMBEDDED_NAME = "jacksboro_fault_dem.npz"
EMBEDDED_CREDIT = (
    "USGS 3 arc-second DEM around the Jacksboro fault, Tennessee (public domain), "
    "as shipped in matplotlib's sample data"
)


@dataclass(frozen=True)
class Dem:
    """A single-band elevation raster with georeference."""

    elevation: FloatArray  # (rows, cols), metres; NaN where nodata could not be filled
    transform: Affine  # pixel (col, row) corner -> CRS x, y
    crs: CRS
    source: str

    @property
    def shape(self) -> tuple[int, int]:
        return self.elevation.shape

    @property
    def hole_mask(self) -> NDArray[np.bool_]:
        return ~np.isfinite(self.elevation)

    def to_lonlat(self) -> Transformer:
        return Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True)

    def from_lonlat(self) -> Transformer:
        return Transformer.from_crs("EPSG:4326", self.crs, always_xy=True)

    def pixel_to_crs(self, col: FloatArray, row: FloatArray) -> tuple[FloatArray, FloatArray]:
        a, b, c, d, e, f = tuple(self.transform)[:6]
        return a * col + b * row + c, d * col + e * row + f

    def crs_to_pixel(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        a, b, c, d, e, f = tuple(~self.transform)[:6]
        return a * x + b * y + c, d * x + e * y + f

    def pixel_size_m(self) -> tuple[float, float]:
        """Ground size (dx, dy) of one pixel at the raster centre, metres."""
        rows, cols = self.shape
        c, r = cols / 2.0, rows / 2.0
        px, py = self.pixel_to_crs(np.array([c, c + 1, c]), np.array([r, r, r + 1]))
        lon, lat = self.to_lonlat().transform(px, py)
        geod = Geod(ellps="WGS84")
        _, _, dx = geod.inv(lon[0], lat[0], lon[1], lat[1])
        _, _, dy = geod.inv(lon[0], lat[0], lon[2], lat[2])
        return float(dx), float(dy)

    def sample_lonlat(self, lon: FloatArray, lat: FloatArray, what: str) -> FloatArray:
        """Bicubic elevation at lon/lat points; refuses points off the raster or over holes."""
        x, y = self.from_lonlat().transform(lon, lat)
        col, row = self.crs_to_pixel(np.asarray(x), np.asarray(y))
        col, row = col - 0.5, row - 0.5  # pixel centres
        rows, cols = self.shape
        off = (col < 0) | (row < 0) | (col > cols - 1) | (row > rows - 1)
        if off.any():
            i = int(np.argmax(off))
            raise InputError(
                what,
                f"lat {float(lat.flat[i]):.5f}, lon {float(lon.flat[i]):.5f}",
                f"is off the DEM {self.source} (field and margin must lie inside its "
                f"{rows}x{cols}-pixel extent)",
            )
        holes = self.hole_mask
        if holes.any():
            near = ndimage.map_coordinates(holes.astype(np.float64), [row, col], order=1)
            if (near > 0).any():
                i = int(np.argmax(near > 0))
                raise InputError(
                    what,
                    f"lat {float(lat.flat[i]):.5f}, lon {float(lon.flat[i]):.5f}",
                    f"lies over a nodata hole larger than terrain.fill_max_pixels in "
                    f"{self.source}; move the field or raise the fill limit",
                )
        filled = _nearest_fill(self.elevation) if holes.any() else self.elevation
        return np.asarray(ndimage.map_coordinates(filled, [row, col], order=3, mode="nearest"))

    def pick_site(
        self, mode: str, extent_m: float, max_slope_deg: float = 90.0
    ) -> tuple[float, float]:
        """Centre (lat, lon) of the flattest or steepest window of ``extent_m`` metres.

        Windows that touch water (DEMs flatten lakes and reservoirs into large areas of one
        exact elevation), a nodata hole or the raster edge are not candidates.
        """
        dx, dy = self.pixel_size_m()
        win = max(3, math.ceil(extent_m / min(dx, dy)) | 1)
        rows, cols = self.shape
        if win > min(rows, cols):
            raise InputError(
                "field",
                f"{extent_m:.0f} m",
                f"is larger than the DEM {self.source} ({cols * dx:.0f} x {rows * dy:.0f} m)",
            )
        filled = _nearest_fill(self.elevation)
        gy, gx = np.gradient(filled, dy, dx)
        slope = np.degrees(np.arctan(np.hypot(gx, gy)))
        mean = ndimage.uniform_filter(slope, win, mode="nearest")
        avoid = self.hole_mask | water_mask(filled)
        bad = ndimage.maximum_filter(avoid.astype(np.uint8), win + 2) > 0
        half = win // 2 + 2
        bad[:half] = bad[-half:] = True
        bad[:, :half] = bad[:, -half:] = True
        if mode == "flattest":
            score = np.where(bad, np.inf, mean)
            idx = int(np.argmin(score))
        else:
            score = np.where(bad | (mean > max_slope_deg), -np.inf, mean)
            idx = int(np.argmax(score))
        if not np.isfinite(score.flat[idx]):
            raise InputError(
                "terrain.site",
                mode,
                f"no valid window of {extent_m:.0f} m in "
                f"{self.source} (holes, edges or max_slope_deg exclude all)",
            )
        r, c = divmod(idx, cols)
        x, y = self.pixel_to_crs(np.array([c + 0.5]), np.array([r + 0.5]))
        lon, lat = self.to_lonlat().transform(x[0], y[0])
        return float(lat), float(lon)


def water_mask(elev: FloatArray, min_pixels: int = 12) -> NDArray[np.bool_]:
    """Pixels in connected areas of identical elevation of at least ``min_pixels`` pixels."""
    same = np.zeros(elev.shape, bool)
    same[1:-1, 1:-1] = (
        (elev[1:-1, 1:-1] == elev[:-2, 1:-1])
        & (elev[1:-1, 1:-1] == elev[2:, 1:-1])
        & (elev[1:-1, 1:-1] == elev[1:-1, :-2])
        & (elev[1:-1, 1:-1] == elev[1:-1, 2:])
    )
    labels, n = ndimage.label(same)
    if n == 0:
        return same
    sizes = np.bincount(labels.ravel())
    big = sizes >= min_pixels
    big[0] = False
    return ndimage.binary_dilation(big[labels])


def _nearest_fill(a: FloatArray) -> FloatArray:
    holes = ~np.isfinite(a)
    if not holes.any():
        return a
    idx = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
    return a[tuple(idx)]


def fill_small_holes(elev: FloatArray, max_pixels: int) -> FloatArray:
    """Fill nodata components of at most ``max_pixels`` pixels; larger ones stay NaN."""
    holes = ~np.isfinite(elev)
    if not holes.any():
        return elev
    if holes.all():
        raise InputError("terrain.path", "all nodata", "the DEM holds no valid elevation")
    labels, n = ndimage.label(holes)
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    small = (sizes <= max_pixels) & (np.arange(n + 1) > 0)
    fill_mask = small[labels]
    if not fill_mask.any():
        return elev
    from rasterio.fill import fillnodata

    valid = np.isfinite(elev)
    work = np.where(valid, elev, 0.0).astype(np.float32)
    dist = float(max(2.0, math.sqrt(max_pixels) * 2))
    filled = fillnodata(
        work, mask=valid.astype(np.uint8), max_search_distance=dist, smoothing_iterations=0
    ).astype(np.float64)
    out = elev.copy()
    out[fill_mask] = filled[fill_mask]
    # Whatever fillnodata could not reach falls back to the nearest valid pixel.
    still = fill_mask & ~np.isfinite(out)
    if still.any():
        out[still] = _nearest_fill(np.where(valid, elev, np.nan))[still]
    return out


def load_embedded() -> Dem:
    """The USGS DEM matplotlib ships: 3 arc-second, lon -84.41..-84.08, lat 36.45..36.73.

    Its ``ymin`` key holds the *northern* edge (36.733) and ``ymax`` the southern one: row 0 is
    north, as in any north-up raster and as matplotlib's own examples plot it.
    """
    from matplotlib import cbook

    d: Any = cbook.get_sample_data(EMBEDDED_NAME)
    elev = np.asarray(d["elevation"], dtype=np.float64)
    north = float(max(d["ymin"], d["ymax"]))
    west = float(d["xmin"])
    transform = Affine(float(d["dx"]), 0.0, west, 0.0, -float(d["dy"]), north)
    return Dem(elev, transform, CRS.from_epsg(4326), "embedded USGS Jacksboro DEM")


def load_geotiff(path: str | Path, fill_max_pixels: int) -> Dem:
    import rasterio
    from rasterio.errors import RasterioIOError

    p = Path(path)
    if not p.is_file():
        raise InputError("terrain.path", str(path), "allowed: an existing GeoTIFF file")
    try:
        with rasterio.open(p) as ds:
            if ds.crs is None:
                raise InputError(
                    "terrain.path", str(path), "has no CRS; allowed: a georeferenced GeoTIFF"
                )
            if ds.transform.is_identity:
                raise InputError(
                    "terrain.path",
                    str(path),
                    "has no geotransform; allowed: a georeferenced GeoTIFF",
                )
            band = ds.read(1, masked=True)
            elev = np.ma.filled(band.astype(np.float64), np.nan)
            transform, crs = ds.transform, CRS.from_wkt(ds.crs.to_wkt())
    except RasterioIOError as exc:
        raise InputError("terrain.path", str(path), f"cannot be read as a raster ({exc})") from None
    elev[~np.isfinite(elev)] = np.nan
    elev = fill_small_holes(elev, fill_max_pixels)
    return Dem(elev, transform, crs, p.name)
