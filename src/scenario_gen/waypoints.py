"""Nav2 GPS waypoints in, an ENU route out: the seed robot's experiment as it was given.

The format is the one Nav2's GPS waypoint follower reads and ``agrinav export --to nav2``
writes (``config/gps_waypoints.yaml``)::

    waypoints:
      - {latitude: 36.5491, longitude: -84.1412, yaw: 1.5708}   # yaw: rad, ENU, optional

Each waypoint goes through the scenario's datum (WGS84 → ENU, ``GeoFrame``) and the route is
the global plan Nav2's planner makes between them on an empty map: straight legs, resampled at
the route spacing. A point is ``furrow`` where its leg runs along the rows (within
``FURROW_ALIGN_DEG`` of the row direction) inside the planted area, ``headland`` elsewhere.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray

from .arrays import FloatArray
from .bounds import MAX_ROUTE_WAYPOINTS
from .errors import InputError, Notice
from .geodesy import MAX_SITE_LAT, GeoFrame
from .routes import FURROW, HEADLAND, Route
from .schema import load_yaml
from .terrain import Terrain

#: How far a leg's direction may turn from the rows' and still be a furrow leg.
FURROW_ALIGN_DEG = 10.0
MAX_WAYPOINTS = 10_000
#: The shortest route the envs drive at their defaults (``task.success_tolerance`` 0.3 m +
#: 1 m, agrinav_gym's reset rule): a shorter one made a scenario no env would reset on.
MIN_ROUTE_M = 1.3
#: waypoints closer than this are one point to an RTK receiver (u-blox ZED-F9P datasheet:
#: 0.01 m + 1 ppm CEP, fixed), so the leg between them has no heading to plan or export
MIN_LEG_M = 0.01
#: a leg within this of a whole number of route spacings is that many points: a waypoint
#: file read back from its export (lat/lon to 1e-9°, ≈ 0.1 mm) plans the same route
WHOLE_SPACINGS_M = 1e-5


def read_gps_waypoints(path: str | Path, what: str = "--waypoints") -> FloatArray:
    """(n, 3) latitude, longitude (degrees) and yaw (rad; NaN when absent) of a Nav2 GPS
    waypoint file, every entry checked. An ``altitude`` (metres) is accepted and not used: the
    route follows the terrain."""
    data: Any = load_yaml(path, what)
    items = data.get("waypoints") if isinstance(data, dict) else None
    if not isinstance(items, list) or not 2 <= len(items) <= MAX_WAYPOINTS:
        raise InputError(
            what,
            str(path),
            f"allowed: a mapping with 'waypoints': a list of 2-{MAX_WAYPOINTS} "
            "{latitude, longitude, yaw} entries (Nav2's GPS waypoint format)",
        )
    extra_top = sorted(str(k) for k in data if k != "waypoints")
    if extra_top:
        # Nav2's file holds the list alone: another key is a typo or a different file
        raise InputError(what, extra_top, "unknown top-level keys; allowed: waypoints")
    out = np.empty((len(items), 3))
    for k, wp in enumerate(items):
        where = f"{what} waypoints[{k}]"
        if not isinstance(wp, dict) or not {"latitude", "longitude"} <= set(wp):
            raise InputError(where, wp, "allowed: a mapping with latitude and longitude")
        extra = set(wp) - {"latitude", "longitude", "yaw", "altitude"}
        if extra:
            raise InputError(
                where,
                sorted(extra),
                "unknown keys; allowed: latitude, longitude, yaw, altitude",
            )
        if wp.get("altitude") is not None:
            # a GeoPoint's third field, as GNSS loggers write it: checked, then left to the
            # terrain (the route lies on the ground, whatever height a receiver once read)
            _number(wp["altitude"], f"{where}.altitude", -500.0, 9000.0)
        out[k] = [
            _number(wp["latitude"], f"{where}.latitude", -90.0, 90.0),
            _number(wp["longitude"], f"{where}.longitude", -180.0, 180.0),
            # yaw: null reads as an absent yaw, as YAML writers emit for a missing value
            _number(
                math.nan if wp.get("yaw") is None else wp["yaw"],
                f"{where}.yaw",
                -4 * math.pi,
                4 * math.pi,
                True,
            ),
        ]
    return out


def _number(v: Any, where: str, lo: float, hi: float, nan_ok: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        hint = ""
        if isinstance(v, str) and ":" in v and where.endswith(("latitude", "longitude")):
            hint = " in decimal degrees (degrees:minutes:seconds is not read: 36:30:36 is 36.51)"
        raise InputError(where, v, f"allowed: a number in [{lo:g}, {hi:g}]{hint}")
    try:
        x = float(v)
    except OverflowError:  # YAML reads integers of any length
        x = math.inf
    if nan_ok and math.isnan(x):
        return x
    if not (math.isfinite(x) and lo <= x <= hi):
        raise InputError(where, v, f"allowed: a number in [{lo:g}, {hi:g}]")
    return x


def waypoint_route(
    wps: FloatArray,
    geo: GeoFrame,
    terrain: Terrain,
    spacing: float,
    rows: Any = None,
    field: Any = None,
    what: str = "--waypoints",
    terrain_source: str = "embedded",
) -> tuple[Route, list[int]]:
    """The straight-leg plan through ``wps`` (read by ``read_gps_waypoints``) in ENU, on the
    terrain, every ``spacing`` metres, and the indices of its points at the waypoints (the
    goals Nav2's waypoint follower sends one by one); a waypoint off the terrain is refused by
    number.

    A point is ``furrow`` where it lies in ``field`` (the planting area) on a leg running along
    the rows there: within ``FURROW_ALIGN_DEG`` of the row direction at that point
    (``rows.direction_at``: one angle for straight rows, the local tangent of curved or contour
    rows)."""

    def advice() -> str:  # asked only once a waypoint is refused
        if _on_terrain_swapped(wps, geo, terrain):  # moving the site would be the wrong fix
            return (
                "every waypoint lies on the terrain with latitude and longitude swapped: check "
                "which the file gives first"
            )
        return _site_advice(wps, terrain_source)

    # Nav2's GPS waypoints carry no altitude: take the datum's, not 0 (a point hundreds of
    # metres below the tangent plane lies millimetres off sideways at tens of metres).
    try:
        x, y = geo.local_enu(wps[:, 0], wps[:, 1], geo.alt, f"{what} waypoints")
    except InputError as exc:
        raise InputError(
            exc.field, exc.value, f"off the terrain: {exc.allowed}; {advice()}"
        ) from None
    xy = np.column_stack([x, y])
    inside = terrain.contains(xy[:, 0], xy[:, 1])
    if not np.all(inside):
        k = int(np.flatnonzero(~np.asarray(inside))[0])
        raise InputError(
            f"{what} waypoints[{k}]",
            [float(wps[k, 0]), float(wps[k, 1])],
            f"is {float(np.hypot(*xy[k])):.1f} m from the datum, off the terrain (the field's "
            "site and its margin); allowed: waypoints on the scenario's terrain — " + advice(),
        )
    legs = np.diff(xy, axis=0)
    length = np.hypot(legs[:, 0], legs[:, 1])
    if (length < MIN_LEG_M).any():
        k = int(np.flatnonzero(length < MIN_LEG_M)[0])
        raise InputError(
            f"{what} waypoints[{k + 1}]",
            f"{length[k] * 1000:.3g} mm from waypoints[{k}]",
            f"allowed: at least {MIN_LEG_M * 100:g} cm from the one before (closer, they are one "
            "point to an RTK fix, and the leg between them no heading): merge them",
        )
    if length.sum() < MIN_ROUTE_M:
        raise InputError(
            what,
            f"{length.sum():.2f} m of route",
            f"allowed: at least {MIN_ROUTE_M:g} m (the envs' success tolerance 0.3 m + 1 m)",
        )
    n_total = sum(_points(float(d), spacing) for d in length) + 1
    if n_total > MAX_ROUTE_WAYPOINTS:
        raise InputError(
            what,
            f"{length.sum():.0f} m of route",
            f"is {n_total:,} points at {spacing:g} m; allowed: at most {MAX_ROUTE_WAYPOINTS:,}",
        )
    pts, heading = [xy[:1]], [math.atan2(legs[0, 1], legs[0, 0])]
    goals = [0]
    for k in range(len(legs)):
        n = _points(float(length[k]), spacing)
        goals.append(goals[-1] + n)
        t = np.arange(1, n + 1) / n
        pts.append(xy[k] + t[:, None] * legs[k])
        heading += [math.atan2(legs[k, 1], legs[k, 0])] * n
    p = np.vstack(pts)
    along = _along(np.asarray(heading), rows, p)
    z = terrain.height_at(p[:, 0], p[:, 1])
    inside = (
        shapely.contains_xy(field, p[:, 0], p[:, 1])
        if field is not None
        else np.zeros(len(p), bool)
    )
    seg = np.where(np.asarray(along) & inside, FURROW, HEADLAND)
    return Route(np.column_stack([p, z]), seg, np.full(len(p), -1, np.int64)), goals


def _points(length: float, spacing: float) -> int:
    """Route points on a leg ``length`` long at most ``spacing`` apart (its start not counted)."""
    whole = round(length / spacing)
    if whole >= 1 and abs(length - whole * spacing) < WHOLE_SPACINGS_M:
        return whole
    return max(math.ceil(length / spacing), 1)


#: legs a note names one by one (a file of a thousand waypoints is a count past these)
NOTE_LEGS = 8


def note_legs_on_rows(
    route: Route, goals: list[int], crops: FloatArray, row_spacing: float
) -> None:
    """Note the furrow legs that run along a crop row instead of between two (a file of row
    lines where lane centres were meant, or a route shifted by half a row): a robot on them
    drives over the plants. A leg is on a row where the median sideways distance from its
    points to their nearest plant is under a quarter of the row spacing (between rows it is
    half the spacing)."""
    from scipy.spatial import cKDTree

    furrow = route.segment == FURROW
    if len(crops) == 0 or not furrow.any():
        return
    tree = cKDTree(crops)
    on_rows = []
    for k in range(len(goals) - 1):
        idx = np.arange(goals[k] + 1, goals[k + 1] + 1)
        idx = idx[furrow[idx]]
        if len(idx) < 2:
            continue
        p = route.xyz[idx, :2]
        d = p[-1] - p[0]
        u = d / max(float(np.hypot(*d)), 1e-9)
        _, near = tree.query(p)
        rel = crops[near] - p
        side = float(np.median(np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0])))
        if side < 0.25 * row_spacing:
            on_rows.append(f"{k}→{k + 1} ({100 * side:.0f} cm)")
    if on_rows:
        shown = ", ".join(on_rows[:NOTE_LEGS])
        if len(on_rows) > NOTE_LEGS:
            shown += f" and {len(on_rows) - NOTE_LEGS} more ({len(on_rows)} in all)"
        warnings.warn(
            Notice(
                f"route.waypoints: the legs {shown} run along a crop row, not "
                "between two (median sideways distance to the nearest plant; between rows it "
                f"is {50 * row_spacing:.0f} cm): a robot on them drives over the plants"
            ),
            stacklevel=2,
        )


def _site_advice(wps: FloatArray, source: str) -> str:
    """Where the terrain would have to be for the waypoints, in the fields ``source`` reads:
    the centre of the waypoints' own latitude/longitude box (across the antimeridian where
    they straddle it)."""
    lat = float(wps[:, 0].min() + wps[:, 0].max()) / 2.0
    lon0 = float(wps[0, 1])
    d = (wps[:, 1] - lon0 + 180.0) % 360.0 - 180.0  # east of the first, in (-180, 180]
    lon = (lon0 + float(d.min() + d.max()) / 2.0 + 180.0) % 360.0 - 180.0
    if abs(lat) > MAX_SITE_LAT:
        return (
            f"no site can hold them: they lie at latitude {lat:.4f}, beyond the ±{MAX_SITE_LAT}° "
            "the terrain grid reaches (a Web-Mercator zoom level, terrain.lod)"
        )
    reach = "and a field and terrain.margin that reach them"
    if source in ("embedded", "dem"):
        cover = "" if source == "embedded" else " (on a DEM that covers them)"
        return (
            f"to centre the site on them set terrain.site=latlon, terrain.lat={lat:.7f}, "
            f"terrain.lon={lon:.7f}{cover}, {reach}"
        )
    if source == "plane":
        return f"to put the plane under them set terrain.datum=[{lat:.7f}, {lon:.7f}, ALT], {reach}"
    return f"a terrain mesh and --datum that cover them (their centre: {lat:.7f}, {lon:.7f})"


def _on_terrain_swapped(wps: FloatArray, geo: GeoFrame, terrain: Any) -> bool:
    """Whether the waypoints, latitude and longitude exchanged, would all lie on the terrain
    (the commonest slip in a hand-written file: GeoJSON and many GIS tools give lon first)."""
    if not np.all(np.abs(wps[:, 1]) <= 90.0):
        return False
    try:
        x, y = geo.local_enu(wps[:, 1], wps[:, 0], geo.alt, "waypoints")
    except InputError:  # far away that way round too
        return False
    return bool(np.all(terrain.contains(np.asarray(x), np.asarray(y))))


def _along(heading: FloatArray, rows: Any, p: FloatArray) -> NDArray[np.bool_]:
    """Whether each point's leg (``heading``) runs along the rows at that point, either way."""
    if rows is None:
        return np.zeros(len(p), bool)
    d = heading - np.asarray(rows.direction_at(p[:, 0], p[:, 1]))
    off = np.abs((d + 0.5 * math.pi) % math.pi - 0.5 * math.pi)
    return off <= math.radians(FURROW_ALIGN_DEG)


def route_to_gps(route: Route, geo: GeoFrame) -> FloatArray:
    """(n, 2) latitude, longitude of a route's points (for round trips and exports)."""
    lat, lon, _ = geo.enu_to_geodetic(route.xyz[:, 0], route.xyz[:, 1], route.xyz[:, 2])
    return np.column_stack([lat, lon])
