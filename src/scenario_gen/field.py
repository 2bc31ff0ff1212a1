"""The planting area: a lon/lat polygon (read by ``fieldfile``) or a rectangle at the site."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

from .antimeridian import wrap_lon
from .errors import InputError
from .geodesy import GeoFrame
from .spec import FieldSpec

MIN_FIELD_AREA = 4.0  # m²: below this not even one lane fits
MAX_NESTING = 32  # FeatureCollection > Feature > GeometryCollection ... levels


def rectangle(spec: FieldSpec, centre: tuple[float, float]) -> Polygon:
    if spec.width <= 0 or spec.length <= 0:
        bad = "field.width" if spec.width <= 0 else "field.length"
        raise InputError(bad, getattr(spec, bad.split(".")[1]), "allowed: a size > 0 m")
    a = math.radians(spec.angle_deg)
    u = np.array([math.cos(a), math.sin(a)]) * spec.length / 2
    n = np.array([-math.sin(a), math.cos(a)]) * spec.width / 2
    c = np.asarray(centre)
    return Polygon([c - u - n, c + u - n, c + u + n, c - u + n])


def geometries(data: Any, where: str) -> list[dict[str, Any]]:
    """Geometry objects of a GeoJSON document, walked without recursion, nesting bounded."""
    out: list[dict[str, Any]] = []
    stack: list[tuple[Any, int]] = [(data, 0)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_NESTING:
            raise InputError(
                "field.geojson", where, f"nests collections over {MAX_NESTING} levels deep"
            )
        if not isinstance(node, dict):
            continue
        kind = node.get("type")
        if kind == "FeatureCollection":
            feats = node.get("features") or []
            stack += [(f, depth + 1) for f in reversed(feats if isinstance(feats, list) else [])]
        elif kind == "Feature":
            stack.append((node.get("geometry") or {}, depth + 1))
        elif kind == "GeometryCollection":
            subs = node.get("geometries") or []
            stack += [(g, depth + 1) for g in reversed(subs if isinstance(subs, list) else [])]
        else:
            out.append(node)
    return out


def lonlat_to_enu(
    geom: BaseGeometry, geo: GeoFrame, what: str = "field.geojson vertex"
) -> BaseGeometry:
    def tx(coords: np.ndarray) -> np.ndarray:
        x, y = geo.local_enu(coords[:, 1], coords[:, 0], 0.0, what)
        return np.column_stack([x, y])

    return shapely.transform(geom, tx)


def enu_to_lonlat(geom: BaseGeometry, geo: GeoFrame) -> BaseGeometry:
    def tx(coords: np.ndarray) -> np.ndarray:
        lat, lon, _ = geo.enu_to_geodetic(coords[:, 0], coords[:, 1], 0.0)
        return np.column_stack([lon, lat])

    return shapely.transform(geom, tx)


def centroid_latlon(geom: BaseGeometry) -> tuple[float, float]:
    """Latitude and longitude (in -180..180: a field joined across the antimeridian has
    longitudes past 180) of a lon/lat geometry's centroid."""
    c = geom.centroid
    return float(c.y), float(wrap_lon(float(c.x)))


def check_field(poly: BaseGeometry, where: str) -> Polygon | MultiPolygon:
    if not isinstance(poly, (Polygon, MultiPolygon)) or poly.is_empty:
        raise InputError(where, poly.geom_type, "allowed: a non-empty Polygon/MultiPolygon")
    if not poly.is_valid:
        raise InputError(where, explain_validity(poly), "allowed: a valid simple polygon")
    if poly.area < MIN_FIELD_AREA:
        raise InputError(
            where,
            f"{math.floor(poly.area * 1000) / 1000:g} m²",  # rounded down: 3.997 read "4.00"
            f"is too small; allowed: at least {MIN_FIELD_AREA} m²",
        )
    return poly


def long_axis_deg(poly: BaseGeometry) -> float:
    """Direction of the long side of the minimum rotated rectangle, degrees from east."""
    rect = np.asarray(poly.minimum_rotated_rectangle.exterior.coords)
    e1, e2 = rect[1] - rect[0], rect[2] - rect[1]
    e = e1 if np.hypot(*e1) >= np.hypot(*e2) else e2
    return float(math.degrees(math.atan2(e[1], e[0])))
