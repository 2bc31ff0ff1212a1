"""GeoJSON layers in WGS84 (RFC 7946): field, route, plants and planted rows.

One geometry type per layer and file (``field.geojson``, ``route.geojson``,
``plants.geojson``; ``obstacles.geojson``, footprint polygons, when there are obstacles): GIS
formats hold one geometry type per layer, so a file mixing polygons, lines and points cannot be
converted to a Shapefile. Every feature carries a unique top-level
``id`` (its index in the file), and plant numbers live in the ``plant_id`` property, so GDAL
never takes a repeated property for its feature id (``ogr2ogr -f GPKG`` refused the old file).
Coordinates are lon, lat, height (the scenario's heights: ``vertical``); ``decimals=None``
keeps full precision (for the GeoPackage writer), 8 decimals are ≈1 mm. Lines and the field
that cross the antimeridian are cut there (``antimeridian``), as RFC 7946 asks: their features
become Multi- geometries.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import shapely

from .antimeridian import cut_geometry
from .model import Scenario

LAYERS = ("field", "route", "plants", "obstacles")


def _coords(lon: Any, lat: Any, z: Any, decimals: int | None) -> list[list[float]]:
    a = np.column_stack([np.atleast_1d(lon), np.atleast_1d(lat), np.atleast_1d(z)])
    a = a.astype(np.float64)
    if decimals is not None:
        a = np.column_stack([np.round(a[:, :2], decimals), np.round(a[:, 2], 3)])
    out: list[list[float]] = a.tolist()
    return out


def _line(lon: Any, lat: Any, z: Any, decimals: int | None) -> dict[str, Any]:
    """A LineString, or a MultiLineString where it crosses the antimeridian."""
    full = {"type": "LineString", "coordinates": _coords(lon, lat, z, None)}
    return _round_geom(cut_geometry(full), decimals)


def _round_geom(g: Any, decimals: int | None) -> Any:
    if decimals is None:
        return g
    if isinstance(g, dict):
        return {k: _round_geom(v, decimals) for k, v in g.items()}
    if isinstance(g, (list, tuple)):
        if g and isinstance(g[0], float):  # a position: lon, lat (≈1 mm), height (1 mm)
            return [round(v, decimals if i < 2 else 3) for i, v in enumerate(g)]
        return [_round_geom(v, decimals) for v in g]
    return g


def collection(name: str, features: list[dict[str, Any]]) -> dict[str, Any]:
    """A FeatureCollection whose features get unique ids 0..n-1."""
    for i, f in enumerate(features):
        f["id"] = i
    return {"type": "FeatureCollection", "name": name, "features": features}


def field_features(scn: Scenario, decimals: int | None = 8) -> list[dict[str, Any]]:
    # RFC 7946 §3.1.6: exterior rings counter-clockwise, holes clockwise (a field file may
    # come either way; tools that go by the ring's direction drew it inside out)
    geom = shapely.orient_polygons(scn.field_lonlat).__geo_interface__
    return [
        {
            "type": "Feature",
            "properties": {"name": scn.spec.name, "area_m2": round(scn.field.area, 2)},
            "geometry": _round_geom(cut_geometry(_plain(geom)), decimals),
        }
    ]


def _plain(g: Any) -> Any:
    if isinstance(g, dict):
        return {k: _plain(v) for k, v in g.items()}
    if isinstance(g, (list, tuple)):
        return [_plain(v) for v in g]
    return g


def route_features(
    scn: Scenario, rlat: np.ndarray, rlon: np.ndarray, decimals: int | None = 8
) -> list[dict[str, Any]]:
    """One LineString per furrow or headland run, a headland turn and each leg of it driven
    in one direction being runs of their own; runs share their junction point."""
    r = scn.route
    seg = r.segment
    change = (seg[1:] != seg[:-1]) | (r.turn[1:] != r.turn[:-1])
    change |= r.direction[1:] != r.direction[:-1]
    cuts = np.flatnonzero(change) + 1
    bounds = np.concatenate([[0], cuts, [len(seg)]]).astype(int)
    ralt = scn.geo.enu_to_geodetic(r.xyz[:, 0], r.xyz[:, 1], r.xyz[:, 2])[2]
    feats = []
    for a, b in itertools.pairwise(bounds.tolist()):
        hi = min(b + 1, len(seg))
        length = float(np.hypot(*np.diff(r.xy[a:hi], axis=0).T).sum())
        feats.append(
            {
                "type": "Feature",
                "properties": {
                    "segment": str(seg[a]),
                    "lane": int(r.lane[a]),
                    "turn": str(r.turn[a]),
                    "direction": int(r.direction[a]),
                    "length_m": round(length, 3),
                },
                "geometry": _line(rlon[a:hi], rlat[a:hi], ralt[a:hi], decimals),
            }
        )
    return feats


def plant_features(
    scn: Scenario,
    lat: np.ndarray,
    lon: np.ndarray,
    alt: np.ndarray,
    decimals: int | None = 8,
) -> list[dict[str, Any]]:
    p = scn.plants
    xyz = _coords(lon, lat, alt, decimals)

    def col(v: np.ndarray, d: int) -> list[float]:
        a = np.asarray(v, np.float64)
        out: list[float] = (np.round(a, d) if decimals is not None else a).tolist()
        return out

    names = ("stage", "height", "roll", "pitch", "yaw", "x_enu", "y_enu", "z_enu")
    cols = zip(
        col(p.stage, 3),
        col(p.height, 3),
        col(p.roll, 6),
        col(p.pitch, 6),
        col(p.yaw, 6),
        col(p.x, 4),
        col(p.y, 4),
        col(p.z, 4),
        strict=True,
    )
    return [
        {
            "type": "Feature",
            "properties": {"plant_id": i, "species": sp, **dict(zip(names, vals, strict=True))},
            "geometry": {"type": "Point", "coordinates": xyz[i]},
        }
        for i, (sp, vals) in enumerate(zip(p.species.tolist(), cols, strict=True))
    ]


def obstacle_features(scn: Scenario, decimals: int | None = 8) -> list[dict[str, Any]]:
    """Each obstacle's footprint rectangle on the ground, with its kind and size."""
    o = scn.obstacles
    feats = []
    for i, ring in enumerate(o.footprints()):
        x, y = ring[:, 0], ring[:, 1]
        lat, lon, alt = scn.geo.enu_to_geodetic(x, y, scn.terrain.height_at(x, y))
        closed = _coords(np.append(lon, lon[0]), np.append(lat, lat[0]), np.append(alt, alt[0]),
                         decimals)  # fmt: skip
        feats.append(
            {
                "type": "Feature",
                "properties": {
                    "obstacle_id": i,
                    "kind": str(o.kind[i]),
                    "length_m": round(float(o.length[i]), 4),
                    "width_m": round(float(o.width[i]), 4),
                    "height_m": round(float(o.height[i]), 4),
                    "yaw": round(float(o.yaw[i]), 6),
                },
                "geometry": {"type": "Polygon", "coordinates": [closed]},
            }
        )
    return feats


def row_features(scn: Scenario, decimals: int | None = 8, step: float = 1.0) -> list[dict]:
    """Each planted row as a line on the terrain, a vertex at most ``step`` metres apart."""
    rows = scn.rows
    feats = []
    for i, (s, t0, t1) in enumerate(zip(rows.offsets, rows.starts, rows.ends, strict=True)):
        n = max(2, int(np.ceil((t1 - t0) * rows.stretch(t0, t1, s) / step)) + 1)
        t = np.linspace(t0, t1, n)
        x, y = rows.to_enu(t, np.full(n, s))
        z = scn.terrain.height_at(x, y)
        lat, lon, alt = scn.geo.enu_to_geodetic(x, y, z)
        feats.append(
            {
                "type": "Feature",
                "properties": {"row": i, "length_m": round(rows.row_length(t0, t1, s), 3)},
                "geometry": _line(lon, lat, alt, decimals),
            }
        )
    return feats


def scenario_layers(
    scn: Scenario,
    lat: np.ndarray,
    lon: np.ndarray,
    alt: np.ndarray,
    rlat: np.ndarray,
    rlon: np.ndarray,
) -> dict[str, dict[str, Any]]:
    """The GeoJSON files of a scenario folder, by layer name (``LAYERS``; obstacles only
    when the field has some)."""
    out = {
        "field": collection("field", field_features(scn)),
        "route": collection("route", route_features(scn, rlat, rlon)),
        "plants": collection("plants", plant_features(scn, lat, lon, alt)),
    }
    if len(scn.obstacles):
        out["obstacles"] = collection("obstacles", obstacle_features(scn))
    return out
