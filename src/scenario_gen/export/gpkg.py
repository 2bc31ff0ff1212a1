"""A GeoPackage (OGC 12-128, version 1.2) writer on the standard library's sqlite3.

Only what feature layers need: the three required metadata tables, one table per layer with an
integer primary key, a ``geom`` column of GeoPackage binary geometry (``GP`` header, SRS id,
XY envelope, ISO WKB) and typed attribute columns, and each layer's spatial index (the RTree
extension, ``gpkg_rtree_index``: ``rtree_<table>_geom`` filled from the envelopes, with the
spec's triggers that keep it current when a GIS edits the layer). GDAL, QGIS and any OGC reader
open it; no GDAL is needed to write it.
"""

from __future__ import annotations

import sqlite3
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from pyproj import CRS
from shapely.geometry import shape

APPLICATION_ID = 0x47504B47  # "GPKG"
USER_VERSION = 10200
_SQL_TYPES = {int: "INTEGER", float: "DOUBLE", str: "TEXT"}


@dataclass(frozen=True)
class Layer:
    name: str
    geometry_type: str  # GeoPackage name: POINT, LINESTRING, POLYGON, MULTIPOLYGON, GEOMETRY
    features: list[dict[str, Any]]  # GeoJSON features (full-precision coordinates)
    srs_id: int = 4326
    description: str = ""


def _blobs(geoms: list[Any], srs_id: int) -> list[bytes]:
    """GeoPackage binary geometries: ``GP`` header, SRS id, XY envelope (none for points)."""
    arr = np.array(geoms, dtype=object)
    has_z = bool(shapely.has_z(arr).any()) if len(arr) else False
    wkb = shapely.to_wkb(arr, output_dimension=3 if has_z else 2, byte_order=1, flavor="iso")
    srs = struct.pack("<i", srs_id)
    points = shapely.get_type_id(arr) == 0
    bounds = shapely.bounds(arr)  # minx, miny, maxx, maxy
    out = []
    for w, pt, (x0, y0, x1, y1) in zip(wkb.tolist(), points.tolist(), bounds.tolist(), strict=True):
        if pt:  # a point's envelope is itself: the spec says leave it out
            out.append(b"GP\x00\x01" + srs + w)
        else:  # flags: little endian, envelope [minx, maxx, miny, maxy]
            out.append(b"GP\x00\x03" + srs + struct.pack("<4d", x0, x1, y0, y1) + w)
    return out


def write_gpkg(path: Path, layers: list[Layer], crs: dict[int, CRS]) -> None:
    """Write ``layers`` to a new GeoPackage; ``crs`` maps each SRS id used to its CRS."""
    con = sqlite3.connect(path)
    try:
        _write(con, layers, crs)
        con.commit()
    finally:
        con.close()


def _write(con: sqlite3.Connection, layers: list[Layer], crs: dict[int, CRS]) -> None:
    cur = con.cursor()
    cur.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    cur.execute(f"PRAGMA user_version = {USER_VERSION}")
    cur.executescript(
        """
        CREATE TABLE gpkg_spatial_ref_sys (
          srs_name TEXT NOT NULL, srs_id INTEGER NOT NULL PRIMARY KEY,
          organization TEXT NOT NULL, organization_coordsys_id INTEGER NOT NULL,
          definition TEXT NOT NULL, description TEXT);
        CREATE TABLE gpkg_contents (
          table_name TEXT NOT NULL PRIMARY KEY, data_type TEXT NOT NULL,
          identifier TEXT UNIQUE, description TEXT DEFAULT '',
          last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
          min_x DOUBLE, min_y DOUBLE, max_x DOUBLE, max_y DOUBLE, srs_id INTEGER,
          CONSTRAINT fk_gc_r_srs_id FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id));
        CREATE TABLE gpkg_geometry_columns (
          table_name TEXT NOT NULL, column_name TEXT NOT NULL,
          geometry_type_name TEXT NOT NULL, srs_id INTEGER NOT NULL,
          z TINYINT NOT NULL, m TINYINT NOT NULL,
          CONSTRAINT pk_geom_cols PRIMARY KEY (table_name, column_name),
          CONSTRAINT fk_gc_tn FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name),
          CONSTRAINT fk_gc_srs FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys (srs_id));
        CREATE TABLE gpkg_extensions (
          table_name TEXT, column_name TEXT, extension_name TEXT NOT NULL,
          definition TEXT NOT NULL, scope TEXT NOT NULL,
          CONSTRAINT ge_tce UNIQUE (table_name, column_name, extension_name));
        """
    )
    srs = [
        ("Undefined cartesian SRS", -1, "NONE", -1, "undefined", "undefined cartesian"),
        ("Undefined geographic SRS", 0, "NONE", 0, "undefined", "undefined geographic"),
    ]
    for sid, c in sorted(crs.items()):
        epsg = c.to_epsg()
        srs.append(
            (
                c.name,
                sid,
                "EPSG" if epsg == sid else "NONE",
                sid,
                c.to_wkt("WKT1_GDAL"),
                c.name,
            )
        )
    cur.executemany("INSERT INTO gpkg_spatial_ref_sys VALUES (?, ?, ?, ?, ?, ?)", srs)
    for layer in layers:
        _layer(cur, layer)


def _layer(cur: sqlite3.Cursor, layer: Layer) -> None:
    geoms = _geometries(layer.features)
    props = [f.get("properties", {}) for f in layer.features]
    columns: dict[str, type] = {}
    for p in props:
        for k, v in p.items():
            columns.setdefault(k, type(v) if type(v) in _SQL_TYPES else str)
    cols_sql = "".join(f', "{k}" {_SQL_TYPES[t]}' for k, t in columns.items())
    q = f'"{layer.name}"'
    cur.execute(
        f"CREATE TABLE {q} (fid INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, "
        f"geom {layer.geometry_type}{cols_sql})"
    )
    bounds = shapely.total_bounds(geoms) if geoms else [None] * 4
    cur.execute(
        "INSERT INTO gpkg_contents (table_name, data_type, identifier, description, "
        "min_x, min_y, max_x, max_y, srs_id) VALUES (?, 'features', ?, ?, ?, ?, ?, ?, ?)",
        (layer.name, layer.name, layer.description, *map(_num, bounds), layer.srs_id),
    )
    has_z = int(bool(shapely.has_z(np.array(geoms, dtype=object)).any())) if geoms else 0
    cur.execute(
        "INSERT INTO gpkg_geometry_columns VALUES (?, 'geom', ?, ?, ?, 0)",
        (layer.name, layer.geometry_type, layer.srs_id, has_z),
    )
    names = ", ".join(["geom", *(f'"{k}"' for k in columns)])
    marks = ", ".join("?" * (len(columns) + 1))
    cur.executemany(
        f"INSERT INTO {q} ({names}) VALUES ({marks})",
        (
            (blob, *(p.get(k) for k in columns))
            for blob, p in zip(_blobs(geoms, layer.srs_id), props, strict=True)
        ),
    )
    _rtree(cur, layer.name, geoms)


#: The RTree spatial index triggers of GeoPackage 1.2 (Annex F.3); <t> the table, <c> the
#: geometry column, <i> the primary key. The ST_* functions are the GeoPackage SQL functions
#: GDAL and QGIS register: the triggers run in those tools, never here (the index is filled
#: directly, before the triggers exist).
RTREE_TRIGGERS = """
CREATE TRIGGER "rtree_<t>_<c>_insert" AFTER INSERT ON "<t>"
  WHEN (new."<c>" NOT NULL AND NOT ST_IsEmpty(NEW."<c>"))
BEGIN
  INSERT OR REPLACE INTO "rtree_<t>_<c>" VALUES (NEW."<i>",
    ST_MinX(NEW."<c>"), ST_MaxX(NEW."<c>"), ST_MinY(NEW."<c>"), ST_MaxY(NEW."<c>"));
END;
CREATE TRIGGER "rtree_<t>_<c>_update1" AFTER UPDATE OF "<c>" ON "<t>"
  WHEN OLD."<i>" = NEW."<i>" AND (NEW."<c>" NOTNULL AND NOT ST_IsEmpty(NEW."<c>"))
BEGIN
  INSERT OR REPLACE INTO "rtree_<t>_<c>" VALUES (NEW."<i>",
    ST_MinX(NEW."<c>"), ST_MaxX(NEW."<c>"), ST_MinY(NEW."<c>"), ST_MaxY(NEW."<c>"));
END;
CREATE TRIGGER "rtree_<t>_<c>_update2" AFTER UPDATE OF "<c>" ON "<t>"
  WHEN OLD."<i>" = NEW."<i>" AND (NEW."<c>" ISNULL OR ST_IsEmpty(NEW."<c>"))
BEGIN
  DELETE FROM "rtree_<t>_<c>" WHERE id = OLD."<i>";
END;
CREATE TRIGGER "rtree_<t>_<c>_update3" AFTER UPDATE ON "<t>"
  WHEN OLD."<i>" != NEW."<i>" AND (NEW."<c>" NOTNULL AND NOT ST_IsEmpty(NEW."<c>"))
BEGIN
  DELETE FROM "rtree_<t>_<c>" WHERE id = OLD."<i>";
  INSERT OR REPLACE INTO "rtree_<t>_<c>" VALUES (NEW."<i>",
    ST_MinX(NEW."<c>"), ST_MaxX(NEW."<c>"), ST_MinY(NEW."<c>"), ST_MaxY(NEW."<c>"));
END;
CREATE TRIGGER "rtree_<t>_<c>_update4" AFTER UPDATE ON "<t>"
  WHEN OLD."<i>" != NEW."<i>" AND (NEW."<c>" ISNULL OR ST_IsEmpty(NEW."<c>"))
BEGIN
  DELETE FROM "rtree_<t>_<c>" WHERE id IN (OLD."<i>", NEW."<i>");
END;
CREATE TRIGGER "rtree_<t>_<c>_delete" AFTER DELETE ON "<t>"
  WHEN old."<c>" NOT NULL
BEGIN
  DELETE FROM "rtree_<t>_<c>" WHERE id = OLD."<i>";
END;
"""


def _rtree(cur: sqlite3.Cursor, table: str, geoms: list[Any]) -> None:
    """The layer's spatial index: the RTree of every non-empty geometry's envelope."""
    rtree = f'"rtree_{table}_geom"'
    cur.execute(f"CREATE VIRTUAL TABLE {rtree} USING rtree(id, minx, maxx, miny, maxy)")
    if geoms:
        arr = np.array(geoms, dtype=object)
        keep = ~shapely.is_empty(arr)
        ids = np.flatnonzero(keep) + 1  # fid: AUTOINCREMENT from 1 in insertion order
        b = shapely.bounds(arr[keep])  # minx, miny, maxx, maxy -> the rtree's x, x, y, y order
        rows = np.column_stack([ids, b[:, 0], b[:, 2], b[:, 1], b[:, 3]]).tolist()
        cur.executemany(
            f"INSERT INTO {rtree} VALUES (?, ?, ?, ?, ?)", ((int(r[0]), *r[1:]) for r in rows)
        )
    cur.execute(
        "INSERT INTO gpkg_extensions VALUES (?, 'geom', 'gpkg_rtree_index', "
        "'http://www.geopackage.org/spec120/#extension_rtree', 'write-only')",
        (table,),
    )
    sql = RTREE_TRIGGERS.replace("<t>", table).replace("<c>", "geom").replace("<i>", "fid")
    cur.executescript(sql)


def _geometries(features: list[dict[str, Any]]) -> list[Any]:
    """Shapely geometries of GeoJSON features; points in one vectorized call."""
    kinds = {f["geometry"]["type"] for f in features}
    if kinds == {"Point"}:
        xyz = np.array([f["geometry"]["coordinates"] for f in features], np.float64)
        out: list[Any] = shapely.points(xyz).tolist()
        return out
    return [shape(f["geometry"]) for f in features]


def _num(v: Any) -> float | None:
    return None if v is None else float(v)


def read_geometries(path: Path, layer: str) -> list[Any]:
    """The geometries of one layer of a GeoPackage (what the GIS preview draws, read back)."""
    con = sqlite3.connect(path)
    try:
        rows = con.execute(f'SELECT geom FROM "{layer}" ORDER BY fid').fetchall()
    finally:
        con.close()
    out = []
    for (blob,) in rows:
        envelope = (blob[3] >> 1) & 0b111
        start = 8 + {0: 0, 1: 32, 2: 48, 3: 48, 4: 64}[envelope]
        out.append(shapely.from_wkb(bytes(blob[start:])))
    return out
