"""Scenario directories, written atomically (``reading.load`` reads them back, checked).

Layout: ``scenario.json`` (format version, spec, seed, datum, CRS, LoD, counts, rows and their
planted segments, the reference curve of curved or contour rows since format 3, the user plant
model, versions), ``terrain.npz``, ``plants.csv`` (with each plant's ``row`` since format 2),
``route.csv`` (with each waypoint's ``turn`` and ``direction`` since format 3),
``obstacles.csv`` (since format 4: stones, litter and fallen stalks, ``obstacles.py``),
``field.geojson``, ``route.geojson``, ``plants.geojson`` and, when there are obstacles,
``obstacles.geojson`` (WGS84, one geometry type each),
``preview.png`` and, when the spec names a ``crop.model``, ``models/<its file name>`` (or
``models/<mesh stem>/`` holding the mesh and the files it references in their folders):
byte-identical copies, checked against the recorded SHA-256s. Everything is first written to a
hidden sibling folder which is renamed into place only once complete, so a failure never
leaves a half-written scenario.
"""

from __future__ import annotations

import csv
import json
import shutil
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from .atomic import output_dir
from .errors import InputError
from .geojson import scenario_layers
from .model import Scenario
from .models import sha256_file
from .preview import render_preview
from .vertical import of_scenario

FORMAT = "agrinav-scenario"
FORMAT_VERSION = 4
# version 1: no row column, no segments, no models; version 2: straight rows only, no turn or
# direction columns in route.csv; version 3: no obstacles.csv
READABLE_VERSIONS = (1, 2, 3, 4)
PLANT_HEADER_V1 = [
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
PLANT_HEADER = [*PLANT_HEADER_V1, "row"]
ROUTE_HEADER_V2 = ["index", "x", "y", "z", "lat", "lon", "segment"]
ROUTE_HEADER = [*ROUTE_HEADER_V2, "turn", "direction"]
OBSTACLE_HEADER = [
    "id", "kind", "x", "y", "z", "roll", "pitch", "yaw", "length", "width", "height", "shape",
    "lat", "lon", "alt",
]  # fmt: skip
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
    scn: Scenario,
    directory: str | Path,
    overwrite: bool = False,
    preview: bool = True,
    what: str = "out",
) -> Path:
    """Write ``scn`` to ``directory`` (atomically: the folder appears complete or not at all);
    ``what`` names it in errors (the CLI: ``--out``)."""
    with output_dir(directory, overwrite, what, kind="scenario") as tmp:
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
                row,
            )
            for i, (sp, st, x, y, z, r, pi, ya, h, la, lo, al, row) in enumerate(
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
                    p.row.tolist(),
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
            (i, f"{x:.6f}", f"{y:.6f}", f"{z:.6f}", f"{la:.10f}", f"{lo:.10f}", s, tn, dn)
            for i, ((x, y, z), la, lo, s, tn, dn) in enumerate(
                zip(r.xyz, rlat, rlon, r.segment, r.turn, r.direction.tolist(), strict=True)
            )
        )
    _write_obstacles(scn, d / "obstacles.csv")
    t = scn.terrain
    np.savez_compressed(
        d / "terrain.npz",
        heights=t.heights,
        x0=t.x0,
        y0=t.y0,
        spacing=t.spacing,
        lod=-1 if t.lod is None else t.lod,
    )
    if scn.crop_model is not None:
        _copy_model(scn, d)
    for name, layer in scenario_layers(scn, lat, lon, alt, rlat, rlon).items():
        (d / f"{name}.geojson").write_text(json.dumps(layer))
    (d / "scenario.json").write_text(json.dumps(metadata_dict(scn), indent=2) + "\n")
    if preview:
        render_preview(scn, d / "preview.png")


def _write_obstacles(scn: Scenario, path: Path) -> None:
    o = scn.obstacles
    lat, lon, alt = scn.geo.enu_to_geodetic(o.x, o.y, o.z)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(OBSTACLE_HEADER)
        w.writerows(
            (i, k, *(f"{v:.6f}" for v in (x, y, z)), *(f"{v:.7f}" for v in (r, pi, ya)),
             *(f"{v:.5f}" for v in (ln, wd, ht)), sh, f"{la:.10f}", f"{lo:.10f}", f"{al:.4f}")
            for i, (k, x, y, z, r, pi, ya, ln, wd, ht, sh, la, lo, al) in enumerate(
                zip(o.kind.tolist(), o.x, o.y, o.z, o.roll, o.pitch, o.yaw, o.length, o.width,
                    o.height, o.shape.tolist(), lat, lon, alt, strict=True)
            )
        )  # fmt: skip


def _copy_model(scn: Scenario, d: Path) -> None:
    """models/<name> (a single file), or models/<bundle>/ (a mesh and the files it references,
    in their folders): the user's files, byte for byte, as they were at generation."""
    um = scn.crop_model
    assert um is not None
    target = d / um.file
    pairs = [(um.path, target, um.sha256)]
    pairs += [(um.root / rel, target.parents[len(Path(um.mesh).parts) - 1] / rel, digest)
              for rel, digest in um.files]  # fmt: skip
    for src, dst, digest in pairs:
        dst.parent.mkdir(parents=True, exist_ok=True)
        try:
            shutil.copyfile(src, dst)
        except OSError as exc:
            raise InputError("crop.model", str(src), f"cannot be copied ({exc})") from None
        if sha256_file(dst) != digest:
            raise InputError(
                "crop.model",
                str(src),
                "changed since the scenario was generated (SHA-256 differs); generate it again",
            )


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
            "geodetic": "EPSG:4979 (WGS84 lat, lon, ellipsoidal height); heights: "
            + of_scenario(scn.info).label(),
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
            "obstacles": scn.obstacles.counts(),
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
            "segments": [
                [int(r), float(a), float(b)]
                for r, (a, b) in zip(rows.seg_row, rows.seg_t, strict=True)  # type: ignore[arg-type]
            ],
            "geometry": rows.geometry,
            "curve": None if rows.curve is None else rows.curve.to_dict(),
        },
        "crop_model": None if scn.crop_model is None else scn.crop_model.to_dict(),
        "info": info,
        "versions": versions(),
    }
