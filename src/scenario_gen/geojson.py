"""field.geojson: the field, the route and every plant in WGS84, for GIS tools."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from .model import Scenario


def geojson(
    scn: Scenario,
    lat: np.ndarray,
    lon: np.ndarray,
    alt: np.ndarray,
    rlat: np.ndarray,
    rlon: np.ndarray,
) -> dict[str, Any]:
    def rnd(v: Any) -> Any:
        return np.round(np.asarray(v, dtype=np.float64), 8).tolist()

    feats: list[dict[str, Any]] = [
        {
            "type": "Feature",
            "properties": {
                "kind": "field",
                "name": scn.spec.name,
                "area_m2": round(scn.field.area, 2),
            },
            "geometry": _round_geom(scn.field_lonlat.__geo_interface__),
        }
    ]
    seg = scn.route.segment
    cuts = np.flatnonzero(seg[1:] != seg[:-1]) + 1
    bounds = np.concatenate([[0], cuts, [len(seg)]])
    z = scn.route.xyz[:, 2] + scn.geo.alt
    for a, b in itertools.pairwise(bounds):
        hi = min(b + 1, len(seg))  # share the junction so the line is continuous
        feats.append(
            {
                "type": "Feature",
                "properties": {
                    "kind": "route",
                    "segment": str(seg[a]),
                    "lane": int(scn.route.lane[a]),
                },
                "geometry": {
                    "type": "LineString",
                    "coordinates": np.column_stack(
                        [rnd(rlon[a:hi]), rnd(rlat[a:hi]), np.round(z[a:hi], 3)]
                    ).tolist(),
                },
            }
        )
    p = scn.plants
    for i in range(len(p)):
        feats.append(
            {
                "type": "Feature",
                "properties": {
                    "kind": "plant",
                    "id": i,
                    "species": str(p.species[i]),
                    "stage": round(float(p.stage[i]), 3),
                    "height": round(float(p.height[i]), 3),
                },
                "geometry": {
                    "type": "Point",
                    "coordinates": [
                        round(float(lon[i]), 8),
                        round(float(lat[i]), 8),
                        round(float(alt[i]), 3),
                    ],
                },
            }
        )
    return {"type": "FeatureCollection", "name": scn.spec.name, "features": feats}


def _round_geom(g: Any) -> Any:
    if isinstance(g, dict):
        return {k: _round_geom(v) for k, v in g.items()}
    if isinstance(g, (list, tuple)):
        if g and isinstance(g[0], float):
            return [round(v, 8) for v in g]
        return [_round_geom(v) for v in g]
    return g
