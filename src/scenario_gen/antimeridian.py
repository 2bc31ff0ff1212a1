"""Geometries cut at the antimeridian, as RFC 7946 (GeoJSON, section 3.1.9) asks.

A field a few hundred metres across can straddle longitude ±180° (Fiji, Chukotka, Alaska's
Aleutians): its vertices then jump from +179.99… to −179.99…, and a GIS draws the polygon or
line around the whole globe. Here each line or ring is unwrapped along its vertices (consecutive
longitudes never more than 180° apart), and what lies east of +180° or west of −180° is cut off
and shifted back by 360°: the result is a Multi- geometry whose parts each stay on one side,
new vertices exactly on the meridian (heights interpolated linearly). A geometry that does not
cross is returned unchanged. Reading goes the other way: parts cut so are joined again
(``joined_across``).
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import shapely
from shapely.geometry import box, mapping, shape

from .arrays import FloatArray


def wrap_lon(lon: Any) -> Any:
    """Longitude(s) in [-180, 180): a raster stored 0..360°, or a field joined across the
    antimeridian, gives values past 180."""
    return (lon + 180.0) % 360.0 - 180.0


def unwrap_lon(lon: Any) -> FloatArray:
    """Longitudes with 360° added or subtracted so consecutive ones differ by at most 180°."""
    a = np.asarray(lon, np.float64)
    if a.size < 2:
        return a.copy()
    step = np.diff(a)
    # whole turns added to each value: a running sum of the steps would drift by rounding, and
    # a closed ring's last point must come back to its first exactly
    turns = np.round((wrap_lon(step) - step) / 360.0)
    return a + 360.0 * np.concatenate([[0.0], np.cumsum(turns)])


def joined_across(parts: list[Any]) -> list[Any]:
    """Lon/lat parts spanning more than 180° of longitude are a field cut at the antimeridian
    (as RFC 7946 asks, and as ``cut_geometry`` writes one): the western hemisphere's
    coordinates go 360° east, so the halves meet at 180° and merge into one again. Parts that
    span less are returned as they are."""
    lo = min(g.bounds[0] for g in parts)
    hi = max(g.bounds[2] for g in parts)
    if hi - lo <= 180.0:
        return parts

    def east(xy: FloatArray) -> FloatArray:
        out = np.array(xy, np.float64)
        out[:, 0] = np.where(out[:, 0] < 0.0, out[:, 0] + 360.0, out[:, 0])
        return out

    pieces = shapely.get_parts(np.array([shapely.transform(g, east) for g in parts]))
    return [shapely.union_all(pieces)]


def _crosses(lon: FloatArray) -> bool:
    u = unwrap_lon(lon)
    return bool(u.size) and (float(u.max()) > 180.0 or float(u.min()) < -180.0)


def split_line(coords: list[list[float]]) -> list[list[list[float]]]:
    """A line's vertices (lon, lat[, z]) as one or more lines, none crossing ±180°."""
    a = np.asarray(coords, np.float64)
    if len(a) < 2 or not _crosses(a[:, 0]):
        return [coords]
    a[:, 0] = unwrap_lon(a[:, 0])
    pieces: list[list[list[float]]] = []
    current = [a[0].tolist()]
    for p, q in itertools.pairwise(a):
        kp, kq = np.floor((p[0] + 180.0) / 360.0), np.floor((q[0] + 180.0) / 360.0)
        if kp != kq:  # the segment crosses a meridian ±180 (+ k·360): cut it there
            edge = 180.0 + 360.0 * min(kp, kq)
            t = (edge - p[0]) / (q[0] - p[0])
            cut = p + t * (q - p)
            cut[0] = edge
            current.append(cut.tolist())
            pieces.append(current)
            current = [cut.tolist()]
        current.append(q.tolist())
    pieces.append(current)
    out = []
    for piece in pieces:
        arr = np.asarray(piece, np.float64)
        mid = 0.5 * (arr[:, 0].min() + arr[:, 0].max())
        arr[:, 0] -= 360.0 * np.round(mid / 360.0)  # back into [-180, 180]
        out.append(arr.tolist())
    return out


def _split_area(geom: Any) -> Any:
    polygons = list(geom.geoms) if geom.geom_type == "MultiPolygon" else [geom]
    parts = []
    for poly in polygons:
        ring = np.asarray(poly.exterior.coords, np.float64)
        if not _crosses(ring[:, 0]):
            parts.append(poly)
            continue
        shift = float(ring[0, 0]) - float(unwrap_lon(ring[:, 0])[0])
        unwrapped = shapely.transform(poly, lambda c, s=shift: _unwrapped(c, s))
        for k in (-1, 0, 1):
            window = box(-180.0 + 360.0 * k, -90.0, 180.0 + 360.0 * k, 90.0)
            piece = unwrapped.intersection(window)
            if not piece.is_empty:
                back = shapely.transform(piece, lambda c, k=k: c - np.array([360.0 * k, 0.0]))
                parts.extend(back.geoms if hasattr(back, "geoms") else [back])
    polys = [p for p in parts if p.geom_type == "Polygon" and p.area > 0]
    return polys[0] if len(polys) == 1 else shapely.MultiPolygon(polys)


def _unwrapped(coords: FloatArray, shift: float) -> FloatArray:
    out = np.array(coords, np.float64)
    out[:, 0] = unwrap_lon(out[:, 0]) + shift
    return out


def cut_geometry(geometry: dict[str, Any]) -> dict[str, Any]:
    """A GeoJSON geometry cut at the antimeridian (unchanged when it does not cross)."""
    kind = geometry.get("type")
    if kind == "LineString":
        lines = split_line(geometry["coordinates"])
        if len(lines) == 1:
            return geometry
        return {"type": "MultiLineString", "coordinates": lines}
    if kind == "MultiLineString":
        lines = [part for line in geometry["coordinates"] for part in split_line(line)]
        return {"type": "MultiLineString", "coordinates": lines}
    if kind in ("Polygon", "MultiPolygon"):
        geom = shape(geometry)
        rings = [np.asarray(p.exterior.coords)[:, 0] for p in getattr(geom, "geoms", [geom])]
        if not any(_crosses(r) for r in rings):
            return geometry
        out: dict[str, Any] = mapping(_split_area(geom))
        return _lists(out)
    return geometry


def _lists(g: Any) -> Any:
    if isinstance(g, dict):
        return {k: _lists(v) for k, v in g.items()}
    if isinstance(g, (list, tuple)):
        return [_lists(v) for v in g]
    return g
