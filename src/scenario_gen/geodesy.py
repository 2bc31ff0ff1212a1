"""WGS84 geodesy: a local East-North-Up frame at a datum, through pyproj.

lat/lon/alt (EPSG:4979, ellipsoidal height) -> geocentric ECEF (EPSG:4978) -> rotation into the
tangent plane at the datum. Unlike the source paper's equirectangular approximation this is exact
at any distance, so GPS readings simulated from ENU positions are real coordinates.

Heights are ellipsoidal in this frame. A DEM's heights are usually orthometric (above a geoid):
``dem`` converts them where the file declares its vertical datum and PROJ has the geoid grid,
and otherwise uses them as if ellipsoidal and says so (``vertical``). Over a field the geoid
separation is a constant to well under a millimetre per metre, so it shifts every height alike
and cancels in the local frame; only absolute altitudes carry it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from pyproj import CRS, Transformer
from pyproj.transformer import AreaOfInterest

from .arrays import FloatArray
from .errors import InputError

#: How far from its datum a field's points may lie (straight-line, m): what a loaded scenario
#: may hold (bounds.MAX_ENU_OFFSET_M, which imports this module).
MAX_LOCAL_M = 100_000.0

#: The latitude the Web-Mercator tile pyramid reaches (atan(sinh π)), degrees.
MAX_SITE_LAT = 85.06
#: Web-Mercator ground sample distance at zoom 0 and the equator, metres per 256-px tile pixel.
GSD_Z0 = 156543.03392


def ground_sample_distance(lod: int, lat_deg: float) -> float:
    """Metres per pixel of the Web-Mercator tile pyramid at zoom ``lod`` and ``lat_deg``."""
    if not isinstance(lod, (int, np.integer)) or isinstance(lod, bool) or not 0 <= lod <= 22:
        raise InputError("terrain.lod", lod, "allowed: an integer zoom level 0..22")
    if not -MAX_SITE_LAT <= lat_deg <= MAX_SITE_LAT:
        raise InputError(
            "the site's latitude",
            lat_deg,
            f"allowed: -{MAX_SITE_LAT}..{MAX_SITE_LAT} (the terrain grid's spacing is a "
            "Web-Mercator zoom level, terrain.lod, which does not reach the poles)",
        )
    return GSD_Z0 * math.cos(math.radians(lat_deg)) / 2**lod


def _check_latlon(lat: float, lon: float, alt: float, where: str) -> None:
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        raise InputError(f"{where}.lat", lat, "allowed: degrees in -90..90")
    if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
        raise InputError(f"{where}.lon", lon, "allowed: degrees in -180..180")
    # Ellipsoidal heights of the ground: the Dead Sea shore is ≈ −430 m (geoid −20 m), Everest
    # ≈ 8,850 m; beyond -1,000..10,000 m a datum is a typo (10¹² m was accepted).
    if not (math.isfinite(alt) and -1000.0 <= alt <= 10_000.0):
        raise InputError(f"{where}.alt", alt, "allowed: a ground height in metres, -1000..10000")


def area_of(crs: CRS, x: ArrayLike, y: ArrayLike) -> AreaOfInterest | None:
    """The lon/lat box of points in ``crs`` (through PROJ's default transformation: metres
    off at worst, plenty to pick the transformations valid there); None if they do not map."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        tr = Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True)
    with np.errstate(all="ignore"):
        lon, lat = tr.transform(np.asarray(x, np.float64), np.asarray(y, np.float64))
    lon, lat = np.asarray(lon), np.asarray(lat)
    ok = np.isfinite(lon) & np.isfinite(lat) & (np.abs(lon) <= 180) & (np.abs(lat) <= 90)
    if not ok.any():
        return None
    return AreaOfInterest(
        float(lon[ok].min()), float(lat[ok].min()), float(lon[ok].max()), float(lat[ok].max())
    )


#: the accuracy a transformation to WGS84 must have (PROJ's statement) when a better one's grid
#: is missing, for a field file and a DEM alike: NAD83 (4 m), OSGB36 (2 m) pass, NAD27 without
#: its grids (7-10 m) does not
MAX_SHIFT_M = 5.0


def best_transformer(
    src: CRS,
    dst: CRS,
    area: AreaOfInterest | None = None,
    *,
    tolerance_m: float = 0.0,
    local_only: bool = False,
) -> Transformer | str:
    """PROJ's most accurate transformation from ``src`` to ``dst`` over ``area`` (x, y in GIS
    order: lon, lat), or why it cannot be had.

    When the best one's grid is not installed, PROJ's best without it is taken only if it is
    good to ``tolerance_m`` (its stated accuracy; a ballpark never is), else the missing grid
    is named: ``Transformer.from_crs`` would fall back with a warning (NAD27 → WGS84 without
    its grids: 10 m). With ``local_only`` PROJ's network access must be off (a grid would be
    fetched, and the result would depend on the network). Without ``area`` the best
    transformation anywhere is taken, which may be another region's.
    """
    from pyproj import network
    from pyproj.datadir import get_user_data_dir
    from pyproj.transformer import TransformerGroup

    if local_only and network.is_network_enabled():
        return (
            "PROJ network access is on (pyproj.network); only locally installed grids are "
            "used: turn it off"
        )
    with warnings.catch_warnings():  # "best transformation is not available": said below
        warnings.simplefilter("ignore", UserWarning)
        group = TransformerGroup(src, dst, always_xy=True, area_of_interest=area)
    if not group.transformers:
        return f"PROJ knows no transformation from {src.name} to {dst.name}"
    best: Transformer = group.transformers[0]
    if group.best_available:
        return best
    accuracy = best.accuracy if "ballpark" not in best.description.lower() else -1.0
    if 0.0 <= accuracy <= tolerance_m:
        return best
    ops = _regional(group.unavailable_operations, area)[:1]
    grids = [g.short_name for op in ops for g in op.grids if not g.available]
    names = ", ".join(grids) or "of its best transformation"
    without = f"{accuracy:g} m" if accuracy >= 0 else "an unknown accuracy (a ballpark)"
    return (
        f"PROJ's grid {names} is not installed and without it the transformation is good to "
        f"{without} (copy the grid into {get_user_data_dir()}, or fetch it once with "
        f"`pyproj sync --file {grids[0] if grids else 'NAME'}`)"
    )


def _regional(ops: list[Any], area: AreaOfInterest | None) -> list[Any]:
    """``ops`` whose area of use holds ``area``'s centre, the most local first (PROJ sorts by
    accuracy: a Canadian grid's box reaches Iowa, but Iowa's own grid is what covers it)."""
    if area is None:
        return ops
    x = 0.5 * (area.west_lon_degree + area.east_lon_degree)
    y = 0.5 * (area.south_lat_degree + area.north_lat_degree)

    def size(op: Any) -> float:
        a = op.area_of_use
        if a is None:
            return math.inf
        w, s, e, n = a.bounds
        return (e - w) * (n - s) if w <= x <= e and s <= y <= n else math.inf

    return sorted(ops, key=size)


@dataclass(frozen=True)
class GeoFrame:
    """Local ENU tangent frame at a WGS84 datum (degrees, metres)."""

    lat: float
    lon: float
    alt: float = 0.0
    _to_ecef: Transformer = field(init=False, repr=False, compare=False)
    _origin: FloatArray = field(init=False, repr=False, compare=False)
    _rot: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check_latlon(self.lat, self.lon, self.alt, "datum")
        to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
        origin = np.array(to_ecef.transform(self.lon, self.lat, self.alt), dtype=np.float64)
        sl, cl = math.sin(math.radians(self.lat)), math.cos(math.radians(self.lat))
        so, co = math.sin(math.radians(self.lon)), math.cos(math.radians(self.lon))
        # Rows are the E, N, U unit vectors in ECEF.
        rot = np.array(
            [[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]], dtype=np.float64
        )
        object.__setattr__(self, "_to_ecef", to_ecef)
        object.__setattr__(self, "_origin", origin)
        object.__setattr__(self, "_rot", rot)

    # Transformers hold PROJ contexts that do not pickle; rebuild them from the datum.
    def __getstate__(self) -> dict[str, Any]:
        return {"lat": self.lat, "lon": self.lon, "alt": self.alt}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for key, value in state.items():
            object.__setattr__(self, key, value)
        self.__post_init__()

    def to_dict(self) -> dict[str, float]:
        return {"lat": self.lat, "lon": self.lon, "alt": self.alt}

    def geodetic_to_enu(
        self, lat: ArrayLike, lon: ArrayLike, alt: ArrayLike = 0.0
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Degrees and ellipsoidal metres -> ENU metres (vectorized)."""
        lat_a, lon_a, alt_a = np.broadcast_arrays(
            np.asarray(lat, np.float64), np.asarray(lon, np.float64), np.asarray(alt, np.float64)
        )
        X, Y, Z = self._to_ecef.transform(lon_a, lat_a, alt_a)
        d = np.stack([np.asarray(X), np.asarray(Y), np.asarray(Z)], axis=-1) - self._origin
        enu = d @ self._rot.T
        return enu[..., 0], enu[..., 1], enu[..., 2]

    def local_enu(
        self, lat: ArrayLike, lon: ArrayLike, alt: ArrayLike, what: str
    ) -> tuple[FloatArray, FloatArray]:
        """East and north (m) of points a field may hold: each within ``MAX_LOCAL_M`` of the
        datum, straight-line, else refused naming ``what[k]``. The tangent plane's east and
        north alone would put a point on the far side of the Earth back near the datum."""
        x, y, z = self.geodetic_to_enu(lat, lon, alt)
        reach = np.sqrt(x * x + y * y + z * z)
        if np.any(reach > MAX_LOCAL_M):
            k = int(np.flatnonzero(reach.ravel() > MAX_LOCAL_M)[0])
            la, lo = np.broadcast_arrays(np.asarray(lat, float), np.asarray(lon, float))
            dist = float(reach.ravel()[k])
            raise InputError(
                f"{what}[{k}]",
                [float(la.ravel()[k]), float(lo.ravel()[k])],
                f"is {dist / 1000:,.0f} km from the datum ({self.lat:.6f}, {self.lon:.6f}); "
                f"allowed: points within {MAX_LOCAL_M / 1000:g} km of it (a field's local "
                "frame reaches no further)",
            )
        return x, y

    def enu_to_geodetic(
        self, x: ArrayLike, y: ArrayLike, z: ArrayLike = 0.0
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """ENU metres -> (lat, lon, alt) in degrees and ellipsoidal metres (vectorized)."""
        x_a, y_a, z_a = np.broadcast_arrays(
            np.asarray(x, np.float64), np.asarray(y, np.float64), np.asarray(z, np.float64)
        )
        enu = np.stack([x_a, y_a, z_a], axis=-1)
        ecef = enu @ self._rot + self._origin
        lon, lat, alt = self._to_ecef.transform(
            ecef[..., 0], ecef[..., 1], ecef[..., 2], direction="INVERSE"
        )
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)

    def point_to_geodetic(self, x: float, y: float, z: float = 0.0) -> tuple[float, float, float]:
        """One ENU point -> (lat, lon, alt); the scalar path an env calls at sensor rate."""
        r = self._rot
        ex = r[0, 0] * x + r[1, 0] * y + r[2, 0] * z + self._origin[0]
        ey = r[0, 1] * x + r[1, 1] * y + r[2, 1] * z + self._origin[1]
        ez = r[0, 2] * x + r[1, 2] * y + r[2, 2] * z + self._origin[2]
        lon, lat, alt = self._to_ecef.transform(
            float(ex), float(ey), float(ez), direction="INVERSE"
        )
        return float(lat), float(lon), float(alt)

    def gsd(self, lod: int) -> float:
        return ground_sample_distance(lod, self.lat)
