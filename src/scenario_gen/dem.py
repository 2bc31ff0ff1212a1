"""Digital elevation models: the embedded USGS sample DEM and any GeoTIFF via rasterio.

A ``Dem`` is a north-up-or-not raster in any CRS with an affine transform and explicit nodata.
Small nodata holes are filled (GDAL's inverse-distance fill); pixels in larger holes stay marked
so a field over them is refused rather than silently interpolated. Sampling is bicubic
(spline, order 3), which is what a 30-90 m DEM needs before it is resampled to a 0.1 m grid.

A GeoTIFF is checked before its pixels are read: its georeference must be plausible (a pixel
between 1 cm and 10 km on the ground, geographic coordinates within lon/lat range — geographic
degrees labelled with a projected CRS give sub-millimetre "pixels"), and at most
``MAX_DEM_PIXELS`` are read: only the window around the field when the site is known (a
GeoJSON field or ``terrain.site: latlon``), the whole raster only when a site is searched.
Untagged nodata: when a file declares no nodata value, the common sentinels −32768, −9999 and
values at or below −1e38 (float32's lowest, −3.4e38) are nodata. Elevations outside
[−500, 9000] m are refused (the Dead Sea shore is −430 m, Everest 8849 m): a DEM in feet or
with an untagged odd sentinel says so instead of becoming a cliff.

Heights (``vertical``): a DEM whose CRS declares a vertical datum (a compound CRS) has its
heights converted to metres and, where PROJ has the geoid grid locally, to ellipsoidal
heights; every ``Dem`` says what its heights are (``Dem.heights``).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from affine import Affine
from numpy.typing import NDArray
from pyproj import CRS, Geod, Transformer
from pyproj.transformer import AreaOfInterest
from scipy import ndimage

from .antimeridian import wrap_lon
from .arrays import FloatArray
from .bounds import MAX_DEM_PIXELS
from .errors import InputError
from .geodesy import MAX_SHIFT_M, area_of, best_transformer
from .vertical import (
    ELLIPSOIDAL,
    NOT_DECLARED,
    ORTHOMETRIC,
    Heights,
    geoid_separation,
    split_crs,
    to_ellipsoidal,
    unit_factor,
)

EMBEDDED_NAME = "jacksboro_fault_dem.npz"
#: Bicubic spline prefiltering reaches across the whole array, decaying by 0.268 per pixel: a
#: window padded by 16 pixels samples like the whole raster to 1e-9 of the relief.
WINDOW_PAD = 16
SENTINELS = (-32768.0, -9999.0)
SENTINEL_FLOOR = -1e38
ELEVATION_RANGE = (-500.0, 9000.0)
PIXEL_RANGE_M = (0.01, 10_000.0)
EMBEDDED_CREDIT = (
    "USGS 3 arc-second DEM around the Jacksboro fault, Tennessee (public domain), "
    "as shipped in matplotlib's sample data"
)
EMBEDDED_HEIGHTS = Heights(
    ORTHOMETRIC,
    "the USGS DEM's vertical datum, which the sample file does not declare",
    "",
    "as ellipsoidal heights they read ≈ 31 m high (EGM96 puts the geoid 30.7 m below the "
    "ellipsoid there)",
)
#: the geoid undulation is computed on a lattice at most this many pixels apart and
#: interpolated bilinearly (geoid grids are 1' to 15', ≥ 1.8 km, apart)
GEOID_STEP_MAX = 256


#: a geographic DEM whose pixel width varies by more than this share over its rows gets each
#: row's own width in its window slopes; below it the centre's width errs by less than the
#: share (0.4 % on the embedded DEM, whose sites stay the ones every benchmark field is on)
ROW_WIDTH_SPREAD = 0.01


@dataclass(frozen=True)
class Dem:
    """A single-band elevation raster with georeference."""

    elevation: FloatArray  # (rows, cols), metres; NaN where nodata could not be filled
    transform: Affine  # pixel (col, row) corner -> CRS x, y
    crs: CRS  # horizontal
    source: str
    heights: Heights = NOT_DECLARED
    #: a window of a larger raster: its holes touching the window's edge, whose size is unknown
    #: (so never filled, whatever the limit); None for a whole raster
    open_holes: NDArray[np.bool_] | None = None
    #: pixels whose bicubic height reads a nodata pixel ``fill_small_holes`` filled (the
    #: filled pixels grown by 2: interpolated, not measured); None where nothing was filled
    filled: NDArray[np.bool_] | None = None
    #: where the DEM is used (lon/lat): PROJ's transformations to and from WGS84 are the ones
    #: for this area (a datum has many, each for its region); None: PROJ's choice anywhere
    area: AreaOfInterest | None = None

    def filled_fraction(self, lon: FloatArray, lat: FloatArray) -> float:
        """The share of the points at lon/lat whose height reads a filled pixel."""
        if self.filled is None or np.size(lon) == 0:
            return 0.0
        col, row = self.lonlat_to_pixel(lon, lat)
        r = np.clip(np.rint(np.asarray(row) - 0.5), 0, self.shape[0] - 1).astype(np.intp)
        c = np.clip(np.rint(np.asarray(col) - 0.5), 0, self.shape[1] - 1).astype(np.intp)
        return float(self.filled[r, c].mean())

    @property
    def shape(self) -> tuple[int, int]:
        return self.elevation.shape

    @property
    def hole_mask(self) -> NDArray[np.bool_]:
        return ~np.isfinite(self.elevation)

    def to_lonlat(self) -> Transformer:
        return Transformer.from_crs(
            self.crs, "EPSG:4326", always_xy=True, area_of_interest=self.area
        )

    def from_lonlat(self) -> Transformer:
        return Transformer.from_crs(
            "EPSG:4326", self.crs, always_xy=True, area_of_interest=self.area
        )

    def pixel_to_crs(self, col: FloatArray, row: FloatArray) -> tuple[FloatArray, FloatArray]:
        a, b, c, d, e, f = tuple(self.transform)[:6]
        return a * col + b * row + c, d * col + e * row + f

    def crs_to_pixel(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        a, b, c, d, e, f = tuple(~self.transform)[:6]
        return a * x + b * y + c, d * x + e * y + f

    def lonlat_to_pixel(
        self, lon: FloatArray, lat: FloatArray, transformer: Transformer | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Pixel coordinates (col, row; corners at integers) of lon/lat points. In a geographic
        CRS a longitude is taken by whole turns to the raster's side of ±180°, so a raster
        stored 0..360° (or past 180°) is reached by the -180..180° longitudes a datum uses."""
        tr = transformer or self.from_lonlat()
        x, y = (np.asarray(v, np.float64) for v in tr.transform(lon, lat))
        return self.crs_to_pixel(raster_side_x(self.crs, self.transform, self.shape, x), y)

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

    def row_widths_m(self) -> FloatArray:
        """Ground width of one pixel along each row at the raster's middle column, metres."""
        rows, cols = self.shape
        r = np.arange(rows, dtype=np.float64) + 0.5
        c = np.full(rows, cols / 2.0)
        x0, y0 = self.pixel_to_crs(c, r)
        x1, y1 = self.pixel_to_crs(c + 1.0, r)
        lon0, lat0 = self.to_lonlat().transform(x0, y0)
        lon1, lat1 = self.to_lonlat().transform(x1, y1)
        return np.asarray(Geod(ellps="WGS84").inv(lon0, lat0, lon1, lat1)[2], np.float64)

    def sample_lonlat(self, lon: FloatArray, lat: FloatArray, what: str) -> FloatArray:
        """Bicubic elevation at lon/lat points; refuses points off the raster or over holes."""
        col, row = self.lonlat_to_pixel(lon, lat)
        col, row = col - 0.5, row - 0.5  # pixel centres
        rows, cols = self.shape
        off = (col < 0) | (row < 0) | (col > cols - 1) | (row > rows - 1)
        if off.any():
            i = int(np.argmax(off))
            raise InputError(
                what,
                f"lat {float(lat.flat[i]):.5f}, lon {float(lon.flat[i]):.5f}",
                f"is off the DEM {self.source} (the field and its terrain.margin must lie "
                "inside the raster, away from its nodata border)",
            )
        holes = self.hole_mask
        if holes.any():
            near = ndimage.map_coordinates(holes.astype(np.float64), [row, col], order=1)
            if (near > 0).any():
                i = int(np.argmax(near > 0))
                where = f"lat {float(lat.flat[i]):.5f}, lon {float(lon.flat[i]):.5f}"
                if self.open_holes is not None:
                    op = ndimage.map_coordinates(
                        self.open_holes.astype(np.float64), [row, col], order=1
                    )
                    if op.flat[i] > 0:
                        raise InputError(
                            what,
                            where,
                            f"lies over a nodata area of {self.source} that reaches beyond the "
                            "window read around the field (its size unknown, it is not filled "
                            "whatever terrain.fill_max_pixels says); move the field off it",
                        )
                raise InputError(
                    what,
                    where,
                    f"lies over a nodata hole larger than terrain.fill_max_pixels in "
                    f"{self.source}; move the field or raise the fill limit",
                )
        return np.asarray(
            ndimage.map_coordinates(self.surface_grid(), [row, col], order=3, mode="nearest")
        )

    def surface_grid(self) -> FloatArray:
        """The grid ``sample_lonlat`` interpolates bicubically: the elevation, small holes filled
        from their nearest pixels."""
        return _nearest_fill(self.elevation) if self.hole_mask.any() else self.elevation

    @property
    def constant(self) -> bool:
        """Every known pixel holds the same height (a synthetic flat surface)."""
        known = self.elevation[np.isfinite(self.elevation)]
        return bool(known.size) and float(known.min()) == float(known.max())

    def window_slopes(self, extent_m: float) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Per pixel, the mean slope (degrees) of the window of ``extent_m`` metres centred on
        it — at least 3 pixels across — and whether that window is ruled out as a site."""
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
        if self.crs.is_geographic and rows > 1:
            # a degree of longitude shrinks with cos(latitude): where that moves the pixel width
            # by more than ROW_WIDTH_SPREAD over the raster, each row gets its own
            widths = self.row_widths_m()
            if np.ptp(widths) > ROW_WIDTH_SPREAD * dx:
                gx = gx * (dx / widths)[:, None]
        slope = np.degrees(np.arctan(np.hypot(gx, gy)))
        mean = ndimage.uniform_filter(slope, win, mode="nearest")
        # one level everywhere is a flat test surface, not a lake: there is nothing to tell
        # water from land by
        avoid = self.hole_mask if self.constant else self.hole_mask | water_mask(filled)
        bad = ndimage.maximum_filter(avoid.astype(np.uint8), win + 2) > 0
        half = win // 2 + 2
        bad[:half] = bad[-half:] = True
        bad[:, :half] = bad[:, -half:] = True
        return mean, bad

    def pick_site(
        self, mode: str, extent_m: float, max_slope_deg: float = 90.0
    ) -> tuple[float, float]:
        """Centre (lat, lon) of the flattest or steepest window of ``extent_m`` metres.

        Windows that touch water (DEMs flatten lakes and reservoirs into large areas of one
        exact elevation), a nodata hole or the raster edge are not candidates.
        """
        mean, bad = self.window_slopes(extent_m)
        rows, cols = self.shape
        if mode == "flattest":
            score = np.where(bad, np.inf, mean)
        else:
            score = np.where(bad | (mean > max_slope_deg), -np.inf, mean)
        if self.constant and not bad[rows // 2, cols // 2]:
            idx = rows // 2 * cols + cols // 2  # every window ties (0°): the middle one
        else:
            idx = int(np.argmin(score) if mode == "flattest" else np.argmax(score))
        if not np.isfinite(score.flat[idx]):
            raise InputError(
                "terrain.site",
                mode,
                f"no valid window of {extent_m:.0f} m in "
                f"{self.source} (nodata holes, water, the raster's edges or max_slope_deg "
                "exclude all)",
            )
        r, c = divmod(idx, cols)
        x, y = self.pixel_to_crs(np.array([c + 0.5]), np.array([r + 0.5]))
        lon, lat = self.to_lonlat().transform(x[0], y[0])
        return float(lat), float(wrap_lon(float(lon)))  # a raster stored 0..360°


#: said where a place is off the DEM but its coordinates read the other way round are on it
SWAPPED = (
    "; read as longitude for latitude it lies on the DEM: are the coordinates swapped? "
    "(GeoJSON and KML give longitude first)"
)


#: A flat area is water when at most this share of the pixels around it lie lower: a lake's
#: shore rises everywhere but at its outlet, while a terrace of a DEM stored in whole metres
#: has its whole downhill side lower (about half its rim) and a flat hilltop all of it.
WATER_MAX_LOWER_RIM = 0.25
_FOUR = ndimage.generate_binary_structure(2, 1)


def water_mask(elev: FloatArray, min_pixels: int = 12) -> NDArray[np.bool_]:
    """Pixels in connected areas of identical elevation of at least ``min_pixels`` pixels that
    lie in a basin (``WATER_MAX_LOWER_RIM``): lakes, reservoirs and the sea, which DEMs
    flatten, and not the flat steps of a gentle slope stored in whole metres."""
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
    water = np.zeros(n + 1, bool)
    rows, cols = elev.shape
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None or sizes[k] < min_pixels:
            continue
        r0, r1 = max(box[0].start - 2, 0), min(box[0].stop + 2, rows)
        c0, c1 = max(box[1].start - 2, 0), min(box[1].stop + 2, cols)
        e = elev[r0:r1, c0:c1]
        core = labels[r0:r1, c0:c1] == k
        level = e[core][0]
        flats, _ = ndimage.label(e == level, _FOUR)
        flat = np.isin(flats, np.unique(flats[core]))
        rim = ndimage.binary_dilation(flat, _FOUR) & ~flat
        water[k] = not rim.any() or float(np.mean(e[rim] < level)) <= WATER_MAX_LOWER_RIM
    return ndimage.binary_dilation(water[labels])


def _nearest_fill(a: FloatArray) -> FloatArray:
    holes = ~np.isfinite(a)
    if not holes.any():
        return a
    idx = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
    return a[tuple(idx)]


def _edge_labels(labels: NDArray[np.int32]) -> NDArray[np.int32]:
    """The labels (0 included) of the components that touch the array's edge."""
    return np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))


def edge_holes(elev: FloatArray) -> NDArray[np.bool_]:
    """The nodata pixels of the holes that touch the array's edge."""
    labels, _ = ndimage.label(~np.isfinite(elev))
    edge = _edge_labels(labels)
    return np.isin(labels, edge[edge > 0])


def fill_small_holes(elev: FloatArray, max_pixels: int, open_border: bool = False) -> FloatArray:
    """Fill nodata components of at most ``max_pixels`` pixels; larger ones stay NaN.

    With ``open_border`` (a window of a larger raster) a hole touching the window's edge may
    continue outside it, so it is never counted as small."""
    holes = ~np.isfinite(elev)
    if not holes.any():
        return elev
    if holes.all():
        raise InputError(
            "terrain.path",
            "all nodata",
            "the DEM window read around the field holds no valid elevation; allowed: a field "
            "over valid elevations"
            if open_border
            else "the DEM holds no valid elevation",
        )
    labels, n = ndimage.label(holes)
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    small = (sizes <= max_pixels) & (np.arange(n + 1) > 0)
    if open_border:
        small[_edge_labels(labels)] = False
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
    name = "embedded USGS Jacksboro DEM"
    return Dem(elev, transform, CRS.from_epsg(4326), name, EMBEDDED_HEIGHTS)


def check_georeference(
    transform: Affine, crs: CRS, shape: tuple[int, int], where: str
) -> tuple[float, float]:
    """Refuse an implausible georeference before reading pixels; the pixel size (dx, dy) in m."""
    rows, cols = shape
    grid = Dem(np.zeros((2, 2)), transform, crs, where)
    cx, cy = grid.pixel_to_crs(
        np.array([0.0, cols, 0.0, cols, cols / 2]), np.array([0.0, 0.0, rows, rows, rows / 2])
    )
    if not (np.isfinite(cx).all() and np.isfinite(cy).all()):
        raise InputError("terrain.path", where, "has a non-finite geotransform")
    if crs.is_geographic and not (
        (np.abs(cy) <= 90.0).all() and (cx >= -180.0).all() and (cx <= 360.0).all()
    ):
        raise InputError(
            "terrain.path",
            where,
            f"is labelled {crs.name} (degrees) but spans x {cx.min():.6g}..{cx.max():.6g}, "
            f"y {cy.min():.6g}..{cy.max():.6g}: outside longitude/latitude; allowed: the CRS "
            "its coordinates are in (projected metres labelled geographic?)",
        )
    try:
        with np.errstate(all="ignore"):
            px, py = grid.pixel_to_crs(
                np.array([cols / 2, cols / 2 + 1, cols / 2]),
                np.array([rows / 2, rows / 2, rows / 2 + 1]),
            )
            lon, lat = grid.to_lonlat().transform(px, py, errcheck=True)
            geod = Geod(ellps="WGS84")
            _, _, dx = geod.inv(lon[0], lat[0], lon[1], lat[1])
            _, _, dy = geod.inv(lon[0], lat[0], lon[2], lat[2])
    except Exception:  # pyproj raises ProjError (and others) for points outside the CRS
        dx = dy = float("nan")
    lo, hi = PIXEL_RANGE_M
    for size in (dx, dy):
        if not (math.isfinite(size) and lo <= size <= hi):
            raise InputError(
                "terrain.path",
                where,
                f"has pixels of {size:.3g} m on the ground in its CRS {crs.name}; allowed: "
                f"{lo:g} m to {hi:g} m (is the CRS mislabelled, e.g. degrees in a projected CRS?)",
            )
    return float(dx), float(dy)


def raster_side_x(crs: CRS, transform: Affine, shape: tuple[int, int], x: FloatArray) -> FloatArray:
    """CRS x of points, in a geographic CRS moved by whole turns to the raster's side of ±180°
    (the turn that brings each nearest the raster's centre): a raster stored 0..360° is then
    reached by -180..180° longitudes. Unchanged in a projected CRS."""
    if not crs.is_geographic:
        return x
    rows, cols = shape
    a, b, c = tuple(transform)[:3]
    mid = a * cols / 2.0 + b * rows / 2.0 + c
    return x + 360.0 * np.round((mid - x) / 360.0)


def lonlat_area(bbox: tuple[float, float, float, float]) -> AreaOfInterest:
    """PROJ's area of interest for a lon/lat box (west, south, east, north; a box run on past
    ±180° crosses the antimeridian: west > east)."""
    w, s, e, n = (float(v) for v in bbox)
    w, e = wrap_lon(w), wrap_lon(e)
    return AreaOfInterest(w, max(s, -90.0), e, min(n, 90.0))


def lonlat_window(
    transform: Affine,
    crs: CRS,
    shape: tuple[int, int],
    bbox: tuple[float, float, float, float],
) -> tuple[int, int, int, int] | None:
    """Pixel window (row0, row1, col0, col1) covering a lon/lat box, padded and clipped to the
    raster; None when the box misses the raster."""
    lon0, lat0, lon1, lat1 = bbox
    f = np.linspace(0.0, 1.0, 21)
    lon = np.concatenate(
        [lon0 + (lon1 - lon0) * f, np.full(21, lon1), lon0 + (lon1 - lon0) * f, np.full(21, lon0)]
    )
    lat = np.concatenate(
        [np.full(21, lat0), lat0 + (lat1 - lat0) * f, np.full(21, lat1), lat0 + (lat1 - lat0) * f]
    )
    to_crs = Transformer.from_crs(
        "EPSG:4326", crs, always_xy=True, area_of_interest=lonlat_area(bbox)
    )
    x, y = to_crs.transform(lon, lat)
    x = raster_side_x(crs, transform, shape, np.asarray(x))
    col, row = Dem(np.zeros((2, 2)), transform, crs, "").crs_to_pixel(x, np.asarray(y))
    if not (np.isfinite(col).all() and np.isfinite(row).all()):
        return None
    rows, cols = shape
    r0 = max(0, math.floor(row.min()) - WINDOW_PAD)
    r1 = min(rows, math.ceil(row.max()) + WINDOW_PAD + 1)
    c0 = max(0, math.floor(col.min()) - WINDOW_PAD)
    c1 = min(cols, math.ceil(col.max()) + WINDOW_PAD + 1)
    if r1 - r0 < 2 or c1 - c0 < 2:
        return None
    return r0, r1, c0, c1


def clean_elevation(
    elev: FloatArray,
    tagged: bool,
    where: str,
    offset: tuple[int, int] = (0, 0),
    scale: float = 1.0,
    linear: tuple[float, float] = (1.0, 0.0),
) -> FloatArray:
    """Untagged sentinels (of the stored values) to NaN, then the band's ``linear`` scale and
    offset, then times ``scale`` (metres per vertical unit); refuse elevations no terrain on
    Earth has (``offset``: the window's first row and column, so the pixel named is the
    raster's)."""
    if not tagged:
        sentinel = np.isin(elev, SENTINELS) | (elev <= SENTINEL_FLOOR)
        elev = np.where(sentinel, np.nan, elev)
    if linear != (1.0, 0.0):
        elev = elev * linear[0] + linear[1]
    if scale != 1.0:
        elev = elev * scale
    lo, hi = ELEVATION_RANGE
    with np.errstate(invalid="ignore"):
        bad = np.isfinite(elev) & ((elev < lo) | (elev > hi))
    if bad.any():
        ri, ci = np.unravel_index(int(np.argmax(bad)), elev.shape)
        value = float(elev[ri, ci])
        r, c = int(ri) + offset[0], int(ci) + offset[1]
        raise InputError(
            "terrain.path",
            where,
            f"holds elevation {value:.6g} at pixel (row {r}, col {c}); allowed: "
            f"metres in [{lo:g}, {hi:g}] (nodata must be tagged, or one of the sentinels "
            "-32768, -9999, <= -1e38)",
        )
    return elev


#: metres per unit of ``terrain.vertical_unit``
VERTICAL_UNITS = {"m": 1.0, "ft": 0.3048, "us_ft": 1200.0 / 3937.0}
#: metres per unit of a band unit string, by the words GDAL writers use ("metre", "m a.s.l.",
#: "US survey foot", "ftUS", ...)
_METRIC = {"m": 1.0, "metre": 1.0, "meter": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001}
_FEET = {"ft", "foot", "feet"}
_US = {"us", "survey", "ftus"}


def band_unit_metres(unit: str) -> tuple[str, float] | None:
    """(name, metres per unit) of a band unit string; None where it names no length unit."""
    words = set(
        re.findall(r"[a-z]+", unit.lower().replace("metres", "metre").replace("meters", "meter"))
    )
    if words & _US and (words & _FEET or "ftus" in words):
        return "us_ft", VERTICAL_UNITS["us_ft"]
    if words & _FEET:
        return "ft", VERTICAL_UNITS["ft"]
    metric = [w for w in words if w in _METRIC]
    if len(metric) == 1:
        return ("m" if _METRIC[metric[0]] == 1.0 else metric[0]), _METRIC[metric[0]]
    return None


def height_unit(vert: CRS | None, band_unit: str, crs: CRS, declared: str, where: str) -> float:
    """Metres per unit of a DEM's heights: its vertical CRS's unit, else its band unit, else
    ``declared`` (``terrain.vertical_unit``), else metres — except on a CRS measured in feet,
    where metres is a guess that turns a 3° field into 10°, so the user must say."""
    own = band_unit.strip()
    if vert is not None and vert.axis_info:
        if vert.axis_info[0].direction.lower() == "down":
            raise InputError(
                "terrain.path",
                where,
                f"declares depths ({vert.name}: positive downwards), not elevations; allowed: "
                "a DEM of heights (a vertical CRS whose axis is up)",
            )
        factor = unit_factor(vert)
        if declared != "auto" and abs(VERTICAL_UNITS[declared] - factor) > 1e-9:
            raise InputError(
                "terrain.vertical_unit",
                declared,
                f"{where} declares its heights in {vert.axis_info[0].unit_name} ({vert.name}); "
                "allowed: auto or that unit",
            )
        return factor
    if own:
        known = band_unit_metres(own)
        if known is None:
            raise InputError(
                "terrain.path",
                where,
                f"declares its band unit {band_unit!r}; allowed: a length (metres, cm, feet, "
                "US survey feet)",
            )
        if declared != "auto" and abs(VERTICAL_UNITS[declared] - known[1]) > 1e-12:
            raise InputError(
                "terrain.vertical_unit",
                declared,
                f"{where} declares its band unit {band_unit!r}; allowed: auto or {known[0]}",
            )
        return known[1]
    if declared != "auto":
        return VERTICAL_UNITS[declared]
    unit = crs.axis_info[0].unit_name if crs.axis_info else ""
    if "foot" in unit.lower() or "feet" in unit.lower():
        raise InputError(
            "terrain.vertical_unit",
            "auto",
            f"{where} is in {crs.name} ({unit}) and declares no unit for its heights; "
            "allowed: m, ft or us_ft, saying which",
        )
    return 1.0


def load_geotiff(
    path: str | Path,
    fill_max_pixels: int,
    need: tuple[float, float, float, float] | None = None,
    why_whole: str = "",
    vertical_unit: str = "auto",
) -> Dem:
    """A GeoTIFF DEM: the window around the lon/lat box ``need``, or (None) the whole raster,
    in metres (``height_unit``) after the band's scale and offset (GDAL's
    ``value · scale + offset``)."""
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning, RasterioError
    from rasterio.windows import Window

    p = Path(path)
    if not p.is_file():
        raise InputError("terrain.path", str(path), "allowed: an existing GeoTIFF file")
    try:
        with warnings.catch_warnings():
            # the georeference is checked below, in one line: not rasterio's two
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            ds = rasterio.open(p)
        with ds:
            if ds.crs is None and ds.gcps[0]:
                raise InputError(
                    "terrain.path",
                    str(path),
                    "is placed by ground control points only (no geotransform); allowed: a "
                    "GeoTIFF with a geotransform, e.g. gdalwarp's output from it",
                )
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
            if ds.count != 1:  # an RGB image or a multi-band product is not an elevation
                raise InputError(
                    "terrain.path", str(path), f"has {ds.count} bands; allowed: one elevation band"
                )
            if np.dtype(ds.dtypes[0]).kind not in "iuf":
                raise InputError(
                    "terrain.path", str(path), f"holds {ds.dtypes[0]} values; allowed: real numbers"
                )
            crs, vert, ellipsoidal = split_crs(CRS.from_wkt(ds.crs.to_wkt()))
            if not (crs.is_geographic or crs.is_projected):
                raise InputError(
                    "terrain.path",
                    str(path),
                    f"has the local (engineering) CRS {crs.name!r}, which is tied to no place "
                    "on Earth; allowed: a geographic or projected CRS",
                )
            metres = height_unit(vert, ds.units[0] or "", crs, vertical_unit, str(path))
            linear = (float(ds.scales[0]), float(ds.offsets[0]))
            if not all(math.isfinite(v) for v in linear) or linear[0] == 0.0:
                raise InputError(
                    "terrain.path",
                    str(path),
                    f"has band scale {linear[0]:g} and offset {linear[1]:g}; allowed: finite, "
                    "a non-zero scale",
                )
            shape = (ds.height, ds.width)
            check_georeference(ds.transform, crs, shape, str(path))
            area = _placement_area(ds.transform, crs, shape, need, str(path))
            if need is None:
                r0, r1, c0, c1 = 0, ds.height, 0, ds.width
                what = f"the whole DEM ({why_whole})"
                hint = (
                    "; give a GeoJSON field or terrain.site=latlon to read only the window "
                    "around the field"
                )
            else:
                win = lonlat_window(ds.transform, crs, shape, need)
                if win is None:
                    flipped = (need[1], need[0], need[3], need[2])
                    swapped = (
                        abs(need[1]) <= 180.0
                        and max(abs(need[0]), abs(need[2])) <= 90.0
                        and lonlat_window(ds.transform, crs, shape, flipped) is not None
                    )
                    raise InputError(
                        "field",
                        f"lon {need[0]:.5f}..{need[2]:.5f}, lat {need[1]:.5f}..{need[3]:.5f}",
                        f"is off the DEM {p.name}" + (SWAPPED if swapped else ""),
                    )
                r0, r1, c0, c1 = win
                what, hint = "the DEM window around the field", "; a smaller field or margin"
            pixels = (r1 - r0) * (c1 - c0)
            if pixels > MAX_DEM_PIXELS:
                raise InputError(
                    "terrain.path",
                    str(path),
                    f"{what} is {c1 - c0}x{r1 - r0} = {pixels:,} pixels; allowed: at most "
                    f"{MAX_DEM_PIXELS:,} read{hint}",
                )
            window = Window(c0, r0, c1 - c0, r1 - r0)
            band = ds.read(1, window=window, masked=True)
            tagged = ds.nodata is not None
            transform = ds.window_transform(window)
    except RasterioError as exc:
        raise InputError("terrain.path", str(path), f"cannot be read as a raster ({exc})") from None
    elev = np.ma.filled(band.astype(np.float64), np.nan)
    elev[~np.isfinite(elev)] = np.nan
    elev = clean_elevation(elev, tagged, str(path), (r0, c0), metres, linear)
    whole = (r0, c0) == (0, 0) and (r1, c1) == shape
    before = ~np.isfinite(elev)
    elev = fill_small_holes(elev, fill_max_pixels, open_border=not whole)
    newly = before & np.isfinite(elev)
    # bicubic reads the 4 × 4 pixels around a point: within 2 of a filled pixel reads it
    filled = ndimage.binary_dilation(newly, np.ones((5, 5), bool)) if newly.any() else None
    open_holes = None if whole else edge_holes(elev)
    if ellipsoidal:
        heights = Heights(ELLIPSOIDAL, "WGS 84", "", f"{p.name} declares a 3-D {crs.name}")
    elif vert is None:
        heights = NOT_DECLARED
    else:
        rows, cols = elev.shape
        cx, cy = Dem(elev, transform, crs, "").pixel_to_crs(
            np.array([0.0, cols, 0.0, cols]), np.array([0.0, 0.0, rows, rows])
        )
        tr, heights = to_ellipsoidal(crs, vert, area_of(crs, cx, cy))
        if tr is not None:
            elev = elev + _geoid(tr, transform, elev.shape)
    return Dem(elev, transform, crs, p.name, heights, open_holes, filled, area)


def _placement_area(
    transform: Affine,
    crs: CRS,
    shape: tuple[int, int],
    need: tuple[float, float, float, float] | None,
    where: str,
) -> AreaOfInterest | None:
    """The lon/lat box the DEM is used over (the field's, else the raster's), once PROJ's best
    transformation to WGS84 there is known to be installed or good to ``MAX_SHIFT_M``: a DEM
    is refused, as a field file is, rather than placed metres off (NAD27 without its grids)."""
    area: AreaOfInterest | None
    if need is not None:
        area = lonlat_area(need)
    else:
        rows, cols = shape
        grid = Dem(np.zeros((2, 2)), transform, crs, "")
        corners = np.array([0.0, cols, 0.0, cols]), np.array([0.0, 0.0, rows, rows])
        area = area_of(crs, *grid.pixel_to_crs(*corners))
    tr = best_transformer(crs, CRS.from_epsg(4326), area, tolerance_m=MAX_SHIFT_M)
    if isinstance(tr, str):
        raise InputError(
            "terrain.path", where, f"cannot be placed in WGS84 lon/lat ({crs.name}): {tr}"
        )
    return area


def _geoid(tr: Any, transform: Affine, shape: tuple[int, int]) -> FloatArray:
    """The geoid undulation at every pixel centre: exact on a lattice at most
    ``GEOID_STEP_MAX`` pixels apart, bilinear between (geoid grids are coarser still)."""
    rows, cols = shape
    step = max(1, math.ceil(max(rows, cols) / GEOID_STEP_MAX))
    lr = np.unique(np.append(np.arange(0, rows, step), rows - 1)).astype(np.float64)
    lc = np.unique(np.append(np.arange(0, cols, step), cols - 1)).astype(np.float64)
    grid = Dem(np.zeros((2, 2)), transform, CRS.from_epsg(4326), "")
    cc, rr = np.meshgrid(lc, lr)
    x, y = grid.pixel_to_crs(cc + 0.5, rr + 0.5)
    n = geoid_separation(tr, x, y)
    if step == 1:
        return n
    # lattice index of every pixel, then bilinear between lattice nodes
    ri = np.interp(np.arange(rows), lr, np.arange(len(lr)))
    ci = np.interp(np.arange(cols), lc, np.arange(len(lc)))
    rg, cg = np.meshgrid(ri, ci, indexing="ij")
    return np.asarray(ndimage.map_coordinates(n, [rg, cg], order=1, mode="nearest"))
