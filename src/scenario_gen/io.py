"""Scenario directories: written atomically, read back exactly enough to reuse.

Layout: ``scenario.json`` (format version, spec, seed, datum, CRS, LoD, counts, versions),
``terrain.npz``, ``plants.csv``, ``route.csv``, ``field.geojson`` (WGS84) and ``preview.png``.
Everything is first written to a hidden sibling folder which is renamed into place only once
complete, so a failure never leaves a half-written scenario.
"""

from __future__ import annotations

import csv
import itertools
import json
import os
import shutil
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from shapely import wkt

from .config import ScenarioSpec
from .errors import ScenarioError
from .geodesy import GeoFrame
from .layout import RowFrame
from .routes import Route
from .scenario import Plants, Scenario
from .terrain import Terrain

FORMAT = "agrinav-scenario"
FORMAT_VERSION = 1
PLANT_HEADER = [
    "id",
    "species",
    "stage",
    "x",
    "y",
    "z",
    "roll",
    "pitch",
    "yaw",
    "height",
    "lat",
    "lon",
    "alt",
]
ROUTE_HEADER = ["index", "x", "y", "z", "lat", "lon", "segment"]
_VERSIONED = (
    "agrinav-gym",
    "numpy",
    "scipy",
    "shapely",
    "pyproj",
    "rasterio",
    "trimesh",
    "matplotlib",
)


def versions() -> dict[str, str]:
    out = {}
    for name in _VERSIONED:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    import pyproj

    out["PROJ"] = pyproj.proj_version_str
    return out


def check_output_dir(directory: str | Path, overwrite: bool) -> Path:
    out = Path(directory)
    if out.exists() and not overwrite:
        raise ScenarioError(
            "out",
            str(out),
            "already exists; choose another directory or "
            "allow overwriting (--force / overwrite=True)",
        )
    if out.exists() and not out.is_dir():
        raise ScenarioError("out", str(out), "exists and is not a directory")
    return out


def save(
    scn: Scenario, directory: str | Path, overwrite: bool = False, preview: bool = True
) -> Path:
    out = check_output_dir(directory, overwrite)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        _write_all(scn, tmp, preview)
        if out.exists():
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old)
        else:
            tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _write_all(scn: Scenario, d: Path, preview: bool) -> None:
    p = scn.plants
    lat, lon, alt = scn.geo.enu_to_geodetic(p.x, p.y, p.z)
    with open(d / "plants.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(PLANT_HEADER)
        w.writerows(
            (
                i,
                sp,
                f"{st:.4f}",
                f"{x:.6f}",
                f"{y:.6f}",
                f"{z:.6f}",
                f"{r:.7f}",
                f"{pi:.7f}",
                f"{ya:.7f}",
                f"{h:.4f}",
                f"{la:.10f}",
                f"{lo:.10f}",
                f"{al:.4f}",
            )
            for i, (sp, st, x, y, z, r, pi, ya, h, la, lo, al) in enumerate(
                zip(
                    p.species,
                    p.stage,
                    p.x,
                    p.y,
                    p.z,
                    p.roll,
                    p.pitch,
                    p.yaw,
                    p.height,
                    lat,
                    lon,
                    alt,
                    strict=True,
                )
            )
        )
    r = scn.route
    rlat, rlon, _ = scn.geo.enu_to_geodetic(r.xyz[:, 0], r.xyz[:, 1], r.xyz[:, 2])
    with open(d / "route.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(ROUTE_HEADER)
        w.writerows(
            (i, f"{x:.6f}", f"{y:.6f}", f"{z:.6f}", f"{la:.10f}", f"{lo:.10f}", s)
            for i, ((x, y, z), la, lo, s) in enumerate(
                zip(r.xyz, rlat, rlon, r.segment, strict=True)
            )
        )
    t = scn.terrain
    np.savez_compressed(
        d / "terrain.npz",
        heights=t.heights,
        x0=t.x0,
        y0=t.y0,
        spacing=t.spacing,
        lod=-1 if t.lod is None else t.lod,
    )
    (d / "field.geojson").write_text(json.dumps(geojson(scn, lat, lon, alt, rlat, rlon)))
    (d / "scenario.json").write_text(json.dumps(metadata_dict(scn), indent=2) + "\n")
    if preview:
        from .preview import render_preview

        render_preview(scn, d / "preview.png")


def metadata_dict(scn: Scenario) -> dict[str, Any]:
    rows = scn.rows
    crops_n = int((~scn.plants.is_weed).sum())
    info = {k: v for k, v in scn.info.items() if k != "generate_seconds"}  # keeps files stable
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "name": scn.spec.name,
        "seed": scn.seed,
        "spec": scn.spec.to_dict(),
        "datum": scn.geo.to_dict(),
        "crs": {
            "geodetic": "EPSG:4979 (WGS84 lat, lon, ellipsoidal height)",
            "local": "ENU tangent plane at the datum via geocentric EPSG:4978; x east, y north, "
            "z up, metres",
        },
        "lod": scn.terrain.lod,
        "terrain": {
            "x0": scn.terrain.x0,
            "y0": scn.terrain.y0,
            "spacing": scn.terrain.spacing,
            "shape": list(scn.terrain.shape),
            "relief_m": scn.terrain.relief,
        },
        "counts": {
            "plants": crops_n,
            "weeds": len(scn.plants) - crops_n,
            "rows": len(rows.offsets),
            "lanes": len(scn.lanes),
            "route_waypoints": len(scn.route),
            "terrain_samples": scn.terrain.size,
        },
        "field_enu_wkt": scn.field.wkt,
        "field_area_m2": scn.field.area,
        "rows": {
            "angle_rad": rows.angle,
            "origin": list(rows.origin),
            "spacing": rows.spacing,
            "offsets": rows.offsets.tolist(),
            "starts": rows.starts.tolist(),
            "ends": rows.ends.tolist(),
        },
        "info": info,
        "versions": versions(),
    }


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


def load(directory: str | Path) -> Scenario:
    """Read a scenario directory written by ``Scenario.save``."""
    d = Path(directory)
    meta_path = d / "scenario.json"
    if not meta_path.is_file():
        raise ScenarioError("scenario", str(d), "is not a scenario directory (no scenario.json)")
    meta = json.loads(meta_path.read_text())
    if meta.get("format") != FORMAT or meta.get("format_version") != FORMAT_VERSION:
        raise ScenarioError(
            "scenario.json",
            meta.get("format_version"),
            f"allowed: format {FORMAT!r} version {FORMAT_VERSION}",
        )
    spec = ScenarioSpec.from_dict(meta["spec"])
    geo = GeoFrame(**meta["datum"])
    with np.load(d / "terrain.npz") as z:
        lod = int(z["lod"])
        terrain = Terrain(
            z["heights"],
            float(z["x0"]),
            float(z["y0"]),
            float(z["spacing"]),
            None if lod < 0 else lod,
        )
    r = meta["rows"]
    rows = RowFrame(
        r["angle_rad"],
        tuple(r["origin"]),
        np.asarray(r["offsets"], float),
        np.asarray(r["starts"], float),
        np.asarray(r["ends"], float),
        r["spacing"],
    )
    plants = _read_plants(d / "plants.csv", rows)
    route = _read_route(d / "route.csv", rows)
    return Scenario(
        spec,
        int(meta["seed"]),
        geo,
        terrain,
        wkt.loads(meta["field_enu_wkt"]),
        rows,
        plants,
        route,
        dict(meta.get("info", {})),
    )


def _read_csv(path: Path, header: list[str]) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        reader = csv.reader(f)
        head = next(reader)
        if head != header:
            raise ScenarioError(path.name, head, f"allowed header: {','.join(header)}")
        cols = list(zip(*reader, strict=True)) or [() for _ in header]
    return {h: np.asarray(c) for h, c in zip(header, cols, strict=True)}


def _nearest(values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    if len(grid) == 0:
        return np.full(len(values), -1, np.int64)
    return np.abs(values[:, None] - grid[None, :]).argmin(axis=1).astype(np.int64)


def _read_plants(path: Path, rows: RowFrame) -> Plants:
    c = _read_csv(path, PLANT_HEADER)
    f = {
        k: c[k].astype(np.float64)
        for k in ("x", "y", "z", "roll", "pitch", "yaw", "height", "stage")
    }
    species = c["species"].astype(str)
    # Row indices are not in the CSV's fixed header; jitter is far below half a row spacing,
    # so the nearest row line recovers them exactly.
    row = np.where(species == "weed", -1, _nearest(rows.to_rows(f["x"], f["y"])[1], rows.offsets))
    return Plants(
        f["x"],
        f["y"],
        f["z"],
        f["roll"],
        f["pitch"],
        f["yaw"],
        f["height"],
        species,
        f["stage"],
        row.astype(np.int64),
    )


def _read_route(path: Path, rows: RowFrame) -> Route:
    c = _read_csv(path, ROUTE_HEADER)
    xyz = (
        np.column_stack([c[k].astype(np.float64) for k in ("x", "y", "z")])
        if len(c["x"])
        else np.empty((0, 3))
    )
    segment = c["segment"].astype(str)
    lanes = 0.5 * (rows.offsets[:-1] + rows.offsets[1:])
    lane = _nearest(rows.to_rows(xyz[:, 0], xyz[:, 1])[1], lanes)
    return Route(xyz, segment, np.where(segment == "furrow", lane, -1).astype(np.int64))
