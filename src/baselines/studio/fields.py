"""Drawn fields: the polygons on the map to one lon/lat geometry and back, checked.

leaflet-draw draws simple polygons only, so holes are drawn as polygons inside another: a
polygon that lies inside another drawn polygon cuts a hole in it (even-odd by nesting depth, so
an island inside a hole is planted again). A loaded GeoJSON keeps its own holes. The geometry is
written as GeoJSON text with coordinates rounded to 1e-9° (0.1 mm) and read back from that text,
so the preview, the saved ``field.geojson`` and ``agrinav scenario --field`` see the same bits.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon, mapping, shape
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

from scenario_gen.errors import InputError
from scenario_gen.field import geometries
from scenario_gen.schema import parse_json

DIGITS = 9  # 1e-9° ≈ 0.1 mm: far below any plant or row spacing
MAX_VERTICES = 100_000


def polygons_of(data: Any) -> list[Polygon]:
    """Every polygon in a GeoJSON object (FeatureCollection, Feature, geometry), checked."""
    out: list[Polygon] = []
    for g in geometries(data, "field"):
        kind = g.get("type")
        if kind not in ("Polygon", "MultiPolygon"):
            continue
        try:
            geom = shape(g)
        except Exception as exc:  # shapely raises several types for malformed coordinates
            raise InputError("field", str(g)[:60], f"has malformed coordinates ({exc})") from None
        out += list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    n = sum(len(p.exterior.coords) + sum(len(r.coords) for r in p.interiors) for p in out)
    if n > MAX_VERTICES:
        raise InputError("field", f"{n} vertices", f"allowed: at most {MAX_VERTICES}")
    for p in out:
        if p.is_empty:
            raise InputError("field", "an empty polygon", "allowed: polygons with an area")
        if not p.is_valid:
            raise InputError(
                "field",
                explain_validity(p),
                "the polygon is invalid; allowed: a simple polygon without self-intersections",
            )
        lon0, lat0, lon1, lat1 = p.bounds
        if not (-180 <= lon0 <= lon1 <= 180 and -90 <= lat0 <= lat1 <= 90):
            raise InputError(
                "field",
                f"bounds {p.bounds}",
                "allowed: WGS84 longitude, latitude (RFC 7946); these look projected",
            )
    return out


def field_of(data: Any) -> BaseGeometry | None:
    """The field a GeoJSON object draws (``polygons_of`` then ``combine``)."""
    return combine(polygons_of(data))


def combine(polys: list[Polygon]) -> BaseGeometry | None:
    """One field from drawn polygons: those nested an odd number of times are holes."""
    if not polys:
        return None
    # how many others contain each: pairs from an R-tree (every pair tested was seconds of a
    # frozen page for a few thousand polygons)
    outer, inner = shapely.STRtree(polys).query(polys, predicate="contains")
    other = outer != inner
    depth = np.bincount(inner[other], minlength=len(polys)).tolist()
    geom = shapely.union_all([p for p, d in zip(polys, depth, strict=True) if d == 0])
    for level in range(1, max(depth) + 1):  # holes, then islands in holes, ...
        ring = shapely.union_all([p for p, d in zip(polys, depth, strict=True) if d == level])
        geom = geom.difference(ring) if level % 2 else geom.union(ring)
    if geom.is_empty or not isinstance(geom, (Polygon, MultiPolygon)):
        raise InputError("field", geom.geom_type, "the drawn polygons leave no field")
    return geom


def to_text(geom: BaseGeometry) -> str:
    """The field as a GeoJSON FeatureCollection (one feature), coordinates rounded."""
    g = _round(mapping(geom))
    feature = {"type": "Feature", "properties": {"kind": "field"}, "geometry": g}
    return json.dumps({"type": "FeatureCollection", "features": [feature]}, indent=1) + "\n"


def from_text(text: str) -> BaseGeometry:
    """The geometry a field file holds, read as ``scenario_gen.fieldfile`` reads a GeoJSON."""
    data = parse_json(text, "field", text[:40])
    polys = polygons_of(data)
    if not polys:
        raise InputError("field", text[:40], "holds no Polygon or MultiPolygon geometry")
    geoms = [
        shape(g) for g in geometries(data, "field") if g.get("type") in ("Polygon", "MultiPolygon")
    ]
    return shapely.union_all(geoms) if len(geoms) > 1 else geoms[0]


def normalise(geom: BaseGeometry) -> tuple[BaseGeometry, str]:
    """(geometry, text): the geometry as it reads back from its own rounded GeoJSON text."""
    text = to_text(geom)
    back = from_text(text)
    if not back.is_valid:  # rounding can, rarely, make a sliver polygon touch itself
        raise InputError("field", explain_validity(back), "allowed: a simple polygon")
    return back, text


def _round(g: Any) -> Any:
    if isinstance(g, dict):
        return {k: _round(v) for k, v in g.items()}
    if isinstance(g, (list, tuple)):
        if g and isinstance(g[0], float):
            return [round(v, DIGITS) for v in g]
        return [_round(v) for v in g]
    return g
