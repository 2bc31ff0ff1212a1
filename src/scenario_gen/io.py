"""Scenario directories: written atomically, read back exactly enough to reuse.

Layout: ``scenario.json`` (format version, spec, seed, datum, CRS, LoD, counts, versions),
``terrain.npz``, ``plants.csv``, ``route.csv``, ``field.geojson``, ``route.geojson`` and
``plants.geojson`` (WGS84, one geometry type each) and ``preview.png``.
Everything is first written to a hidden sibling folder which is renamed into place only once
complete, so a failure never leaves a half-written scenario.
"""

from __future__ import annotations

import csv
import json
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from shapely import wkt

from .atomic import output_dir
from .errors import InputError
from .geodesy import GeoFrame
from .geojson import scenario_layers
from .layout import RowFrame
from .model import Plants, Scenario
from .preview import render_preview
from .routes import Route
from .spec import ScenarioSpec
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


def save(
    scn: Scenario, directory: str | Path, overwrite: bool = False, preview: bool = True
) -> Path:
    """Write ``scn`` to ``directory`` (atomically: the folder appears complete or not at all)."""
    with output_dir(directory, overwrite) as tmp:
        _write_all(scn, tmp, preview)
    return Path(directory)


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
    for name, layer in scenario_layers(scn, lat, lon, alt, rlat, rlon).items():
        (d / f"{name}.geojson").write_text(json.dumps(layer))
    (d / "scenario.json").write_text(json.dumps(metadata_dict(scn), indent=2) + "\n")
    if preview:
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


def load(directory: str | Path) -> Scenario:
    """Read a scenario directory written by ``Scenario.save``."""
    d = Path(directory)
    meta_path = d / "scenario.json"
    if not meta_path.is_file():
        raise InputError("scenario", str(d), "is not a scenario directory (no scenario.json)")
    meta = json.loads(meta_path.read_text())
    if meta.get("format") != FORMAT or meta.get("format_version") != FORMAT_VERSION:
        raise InputError(
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
            raise InputError(path.name, head, f"allowed header: {','.join(header)}")
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
